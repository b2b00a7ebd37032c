//! Shadows recorded into a renderer's own command buffer
//! ([`Engine::record_frame`]): the view samples come from the renderer's
//! G-buffer on the GPU (a visibility buffer of triangle ids, or a buffer of
//! [`GpuViewSample`]s), each light's visibility goes to the renderer's
//! storage buffer or image, and nothing is submitted or read back in
//! between. The same passes as [`Engine::render`], in the same order, with
//! the same results (tests/record.rs compares them bit for bit).
//!
//! ```text
//! let mut frame = engine.record_frame(&desc, &RecordOptions::default())?; // uploads, sizes
//! unsafe {
//!     frame.record_view_samples(cmd, ViewSampleSource::TriangleIds(ids_image))?;
//!     frame.record_light(cmd, 0, VisibilityTarget::Image(view0))?;
//!     frame.record_light(cmd, 1, VisibilityTarget::Image(view1))?;
//! }
//! // end, submit and wait for `cmd` (the renderer's queue), then:
//! let report = frame.finish()?;
//! ```
//!
//! **Synchronisation.** Before the first recorded command, the renderer
//! makes its writes to the inputs available: the triangle-id image in
//! `TRANSFER_SRC_OPTIMAL` with its writes made visible to
//! `TRANSFER`/`TRANSFER_READ`, or the view-sample buffer's writes visible to
//! `COMPUTE_SHADER`/`SHADER_READ`. A target buffer or image (`GENERAL`
//! layout) is written by `COMPUTE_SHADER` with `SHADER_WRITE`; a barrier
//! from there to the renderer's use is the renderer's. The engine's own
//! buffers are synchronised by the recorded commands themselves.
//!
//! **Limits.** Lights with extent run in exact mode
//! ([`crate::gpu::soft_light::SoftMode::Exact`]): the look-up modes size their work on the
//! host. The list of binned (caster, tile) pairs has a fixed capacity
//! ([`RecordOptions::binned_pairs`]); a light that needs more runs no
//! occlusion test and [`RecordedFrame::finish`] says so, with the count it
//! needed. Counters and pass timings are not read back.

use super::inputs::frame_light;
use super::Engine;
use crate::cpu::light_view::LightView;
use crate::gpu::gpu_inputs;
use crate::gpu::shared::{GpuViewSample, LightPush};
use crate::gpu::soft_light::{SoftLight, SoftMode};
use crate::gpu::visibility_out::OutTarget;
use crate::scene::file::SceneDescription;
use crate::vulkan::{vk, Barrier, Buffer, BufferDesc, CommandRecorder, MemoryLocation};
use crate::{Error, Result};

use super::inputs::gpu_triangles;

/// Where a recorded frame's view samples come from (the camera's
/// `width × height` pixels, index `y · width + x`, `y = 0` the top row).
#[derive(Clone, Copy, Debug)]
pub enum ViewSampleSource {
    /// A visibility buffer: an `R32_UINT` image of the camera's size with
    /// `TRANSFER_SRC` usage, in `TRANSFER_SRC_OPTIMAL`, holding per pixel
    /// the index + 1 of the scene triangle (in [`gpu_triangles`] order) that
    /// the pixel-centre ray meets, 0 where none. The engine intersects each
    /// pixel's ray with that triangle's plane, as its own raster step does.
    TriangleIds(vk::Image),
    /// A storage buffer of `width × height` [`GpuViewSample`]s (32 bytes
    /// each, positions relative to the camera's eye) starting at `offset`.
    Buffer {
        /// The buffer (`STORAGE_BUFFER` usage).
        buffer: vk::Buffer,
        /// Byte offset of the first sample: 0 (the passes bind the buffer
        /// whole; another offset is refused).
        offset: u64,
    },
}

/// Where a recorded light's visibility goes: per view sample, the visible
/// fraction (hard shadows: 1 lit, 0 shadowed), 0 where no sample was
/// evaluated, exactly as [`crate::render::Frame`]'s dump holds it.
#[derive(Clone, Copy, Debug)]
pub enum VisibilityTarget {
    /// `width × height` `f32`s at `offset` in a storage buffer.
    Buffer {
        /// The buffer (`STORAGE_BUFFER` usage).
        buffer: vk::Buffer,
        /// Byte offset (a multiple of `minStorageBufferOffsetAlignment`).
        offset: u64,
    },
    /// An `R32_SFLOAT` storage image of the camera's size, in `GENERAL`
    /// layout: view sample `y · width + x` at texel `(x, y)`.
    Image(vk::ImageView),
}

/// Options of [`Engine::record_frame`].
#[derive(Clone, Copy, Debug)]
pub struct RecordOptions {
    /// Capacity of the list of binned (caster, light tile) pairs, in
    /// entries of 4 bytes, shared by the frame's lights one after another.
    /// A light that needs more is reported by [`RecordedFrame::finish`].
    pub binned_pairs: u32,
}

impl Default for RecordOptions {
    /// 4 Mi entries (16 MiB).
    fn default() -> Self {
        RecordOptions {
            binned_pairs: 1 << 22,
        }
    }
}

/// What the GPU reported for one recorded light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecordedLight {
    /// The light's index in the scene description.
    pub light: usize,
    /// Binned (caster, light tile) pairs it needed.
    pub binned_pairs: u32,
    /// Occlusion work units it ran.
    pub units: u32,
}

/// What [`RecordedFrame::finish`] returns: per recorded light, in the order
/// recorded.
#[derive(Clone, Debug, Default)]
pub struct RecordReport {
    /// The recorded lights.
    pub lights: Vec<RecordedLight>,
}

/// One light as the passes take it.
struct FrameLight {
    view: LightView,
    texels: u32,
    soft: Option<SoftLight>,
}

/// A frame being recorded into a renderer's command buffers
/// ([`Engine::record_frame`]). It holds the engine, and the descriptor sets
/// of what it recorded: keep it until every submission of those commands
/// has completed, then call [`RecordedFrame::finish`].
pub struct RecordedFrame<'e> {
    engine: &'e mut Engine,
    lights: Vec<FrameLight>,
    /// View samples (pixels) and triangles.
    n: u32,
    nt: u32,
    /// The caller's view-sample buffer (else the engine's view samples).
    samples: Option<Buffer>,
    /// Bytes between two lights' status slots.
    stride: u64,
    /// The lights recorded, in order.
    recorded: Vec<usize>,
    recorders: Vec<CommandRecorder>,
    view_recorded: bool,
}

impl Engine {
    /// Starts a frame of `desc` (its scene, camera, lights and shadow
    /// settings) whose passes a renderer records into its own command
    /// buffers ([`RecordedFrame`]; the module documentation, [`self`], says
    /// how). This call uploads the scene's triangles and sizes every buffer
    /// for all of `desc`'s lights, waiting on the engine's queue; the
    /// recordings then allocate and submit nothing.
    ///
    /// Errors: an invalid description, a light with extent in a look-up
    /// mode (recordings run exact mode), a zero `binned_pairs`, or an
    /// image whose view samples pass one storage binding (a recording has
    /// no batches; lavapipe binds 2048² samples).
    pub fn record_frame(
        &mut self,
        desc: &SceneDescription,
        options: &RecordOptions,
    ) -> Result<RecordedFrame<'_>> {
        desc.validate()?;
        let limits = &self.ctx.info().limits;
        let most = (limits.max_storage_buffer_range as u64 / 4)
            .min(limits.max_texel_buffer_elements as u64);
        if options.binned_pairs == 0 || options.binned_pairs as u64 > most {
            return Err(Error::InvalidInput(format!(
                "RecordOptions::binned_pairs is {}; this device binds 1 to {most}",
                options.binned_pairs
            )));
        }
        // A recording runs each light's passes once over every view
        // sample: no batches (Engine::render runs an image this large).
        let samples_bytes = desc.camera.width as u64
            * desc.camera.height as u64
            * std::mem::size_of::<crate::gpu::shared::GpuViewSample>() as u64;
        if samples_bytes > limits.max_storage_buffer_range as u64 {
            return Err(Error::InvalidInput(format!(
                "record_frame: {}x{} view samples need {samples_bytes} bytes, more than one \
                 binding of this device holds (maxStorageBufferRange {} bytes); a recorded \
                 frame runs its passes without batches (Engine::render takes this image in \
                 batches)",
                desc.camera.width, desc.camera.height, limits.max_storage_buffer_range
            )));
        }
        self.shadows.set_clusters(desc.shadows.clusters);
        self.shadows.set_wedge_rule(desc.shadows.wedge_rule);
        let eye = desc.camera.eye;
        let lights = frame_lights(desc)?;
        let (_, mut tris) = gpu_inputs(&[], &gpu_triangles(&desc.scene, eye));
        self.set_scene_alpha(&desc.scene, &mut tris)?;
        let any_alpha = self.shadows.alpha().1;
        self.view
            .prepare_for_caller(&self.ctx, &desc.camera, &tris, any_alpha)?;
        // The GPU buffers no longer hold a frame that render_reusing knows.
        self.frame_id += 1;
        let n = desc.camera.width * desc.camera.height;
        let nt = u32::try_from(tris.len())
            .map_err(|_| Error::InvalidInput("too many triangles".into()))?;
        for l in &lights {
            let light = (&l.view, l.texels, l.soft.as_ref());
            self.shadows.prepare_for_caller(
                &self.ctx,
                (self.view.samples(), n),
                (self.view.triangles(), nt),
                light,
                options.binned_pairs,
            )?;
        }
        // Host-visible, kept across frames (the frame holds the engine, so
        // no other frame uses it meanwhile).
        // One slot per light, each at a storage-binding offset.
        let stride = limits_stride(self.ctx.info().limits.min_storage_buffer_offset_alignment);
        let bytes = stride * lights.len().max(1) as u64;
        if self.record_status.as_ref().is_none_or(|b| b.size() < bytes) {
            self.record_status = None;
            self.record_status = Some(self.ctx.create_buffer(BufferDesc {
                name: "record_status".into(),
                size: bytes,
                usage: vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
                location: MemoryLocation::GpuToCpu,
            })?);
        }
        let status = self.record_status.as_ref().expect("made above");
        status.write_mapped(0, &vec![0u32; (bytes / 4) as usize])?;
        Ok(RecordedFrame {
            engine: self,
            lights,
            n,
            nt,
            samples: None,
            stride,
            recorded: Vec::new(),
            recorders: Vec::new(),
            view_recorded: false,
        })
    }
}

/// The lights of `desc` as the passes take them; lights with extent must
/// be in exact mode.
fn frame_lights(desc: &SceneDescription) -> Result<Vec<FrameLight>> {
    let n = desc.camera.width as usize * desc.camera.height as usize;
    (0..desc.lights.len())
        .map(|k| {
            let (view, soft, texels) = frame_light(desc, k, n)?;
            if let Some(sl) = soft.as_ref().filter(|sl| sl.mode != SoftMode::Exact) {
                return Err(Error::InvalidInput(format!(
                    "light {k}: a recorded frame computes soft shadows in exact mode only \
                     (set the shadow settings' mode to exact; {:?} mode sizes its work on \
                     the host)",
                    sl.mode
                )));
            }
            Ok(FrameLight { view, texels, soft })
        })
        .collect()
}

impl RecordedFrame<'_> {
    /// The engine's Vulkan context (its device is the one to record for).
    pub fn context(&self) -> &crate::vulkan::GpuContext {
        &self.engine.ctx
    }

    /// Records the view samples from `source` into `cmd`.
    ///
    /// # Safety
    /// `cmd` is a primary command buffer of the engine's device in the
    /// recording state, from a pool of the engine's queue family, and is
    /// submitted to a queue of that family; the images and buffers `source`
    /// names are the engine device's, of the sizes and usages
    /// [`ViewSampleSource`] says, and live until the submission completed;
    /// `self` is kept until then too. `cmd` is outside a render pass; the
    /// command buffers holding a frame's recordings run in the order
    /// recorded, on one queue, never at the same time as each other or as
    /// another use of the engine (its buffers are shared by all lights).
    /// The recording replaces the command buffer's bound compute
    /// pipeline, descriptor sets and push constants.
    pub unsafe fn record_view_samples(
        &mut self,
        cmd: vk::CommandBuffer,
        source: ViewSampleSource,
    ) -> Result<()> {
        let ctx = &self.engine.ctx;
        let mut rec = CommandRecorder::for_caller(ctx.device(), cmd);
        match source {
            ViewSampleSource::TriangleIds(image) => {
                self.samples = None;
                self.engine.view.record_from_ids(&mut rec, image)?;
            }
            ViewSampleSource::Buffer { buffer, offset } => {
                let bytes = self.n as u64 * std::mem::size_of::<GpuViewSample>() as u64;
                let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
                // SAFETY: the caller's promise above.
                let whole = unsafe {
                    Buffer::borrowed(ctx.device(), buffer, offset + bytes, usage, "samples")
                };
                whole.slice(offset, bytes)?;
                if offset != 0 {
                    return Err(Error::InvalidInput(
                        "a view-sample buffer must start at offset 0 (the passes bind it whole)"
                            .into(),
                    ));
                }
                self.samples = Some(whole);
            }
        }
        self.recorders.push(rec);
        self.view_recorded = true;
        Ok(())
    }

    /// Records light `k`'s passes into `cmd`, after the view samples (in
    /// this command buffer or one submitted before it), its visibility
    /// into `target`.
    ///
    /// On an error, what this frame recorded into `cmd` so far must not
    /// be submitted.
    ///
    /// # Safety
    /// As [`RecordedFrame::record_view_samples`], for `cmd` and `target`;
    /// the caller's earlier reads of `target` have finished (a barrier)
    /// before these commands write it.
    pub unsafe fn record_light(
        &mut self,
        cmd: vk::CommandBuffer,
        k: usize,
        target: VisibilityTarget,
    ) -> Result<()> {
        if !self.view_recorded {
            return Err(Error::InvalidInput(
                "record the view samples before the lights".into(),
            ));
        }
        let light = self.lights.get(k).ok_or_else(|| {
            Error::InvalidInput(format!(
                "light {k} is not in the frame ({} lights)",
                self.lights.len()
            ))
        })?;
        let engine = &mut *self.engine;
        let ctx = &engine.ctx;
        let samples = match &self.samples {
            Some(b) => b,
            None => engine.view.samples(),
        };
        let status = engine
            .record_status
            .as_ref()
            .expect("made by record_frame")
            .slice(self.stride * k as u64, 16)?;
        let rec = CommandRecorder::for_caller(ctx.device(), cmd);
        let light_in = (&light.view, light.texels, light.soft.as_ref());
        let mut rec = engine.shadows.record_for_caller(
            ctx,
            (rec, status),
            (samples, self.n),
            (engine.view.triangles(), self.nt),
            light_in,
        )?;
        let bytes = 4 * self.n as u64;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let borrowed;
        let out = match target {
            VisibilityTarget::Buffer { buffer, offset } => {
                // SAFETY: the caller's promise above.
                borrowed = unsafe {
                    Buffer::borrowed(ctx.device(), buffer, offset + bytes, storage, "target")
                };
                OutTarget::Buffer(borrowed.slice(offset, bytes)?)
            }
            VisibilityTarget::Image(view) => OutTarget::Image(view),
        };
        // The conversion reads sizes.x, the view samples.
        let mut push: LightPush = bytemuck::Zeroable::zeroed();
        push.sizes[0] = self.n;
        let result = engine.shadows.passes().resolve.result.slice();
        engine
            .visibility_out
            .record(&mut rec, result, light.soft.is_some(), out, &push)?;
        // The light ran to its end: word 3 of its slot, for finish().
        let status = engine.record_status.as_ref().expect("made by record_frame");
        rec.barrier(Barrier::ComputeToTransfer);
        rec.fill_buffer(status.slice(self.stride * k as u64 + 12, 4)?, 1)?;
        rec.barrier(Barrier::AllToHost);
        self.recorders.push(rec);
        self.recorded.push(k);
        Ok(())
    }

    /// After every submission of the recorded commands completed: what
    /// each recorded light reported, or an error naming a light whose
    /// binned pairs passed [`RecordOptions::binned_pairs`] (its target then
    /// holds no shadow: record the frame again with at least the count the
    /// error gives) or that did not run.
    ///
    /// A recorded light that has not finished (the caller did not wait, or
    /// did not submit) is waited for with `vkDeviceWaitIdle` before this
    /// frame's descriptor sets go, then reported as an error.
    pub fn finish(self) -> Result<RecordReport> {
        let status = self
            .engine
            .record_status
            .as_ref()
            .expect("made by record_frame");
        let slot = (self.stride / 4) as usize;
        let mut words: Vec<u32> = status.read_mapped(0, slot * self.lights.len().max(1))?;
        if self.recorded.iter().any(|&k| words[slot * k + 3] != 1) {
            // Maybe still running: nothing may go before it ends.
            unsafe { self.engine.ctx.raw().device_wait_idle() }?;
            words = status.read_mapped(0, slot * self.lights.len().max(1))?;
        }
        let mut report = RecordReport::default();
        for &k in &self.recorded {
            let w = &words[slot * k..slot * k + 4];
            if w[3] != 1 {
                return Err(Error::Vulkan(format!(
                    "light {k} was recorded but did not run to its end: submit the recorded \
                     commands and wait for them before finish()"
                )));
            }
            if w[2] != 0 {
                return Err(Error::InvalidInput(format!(
                    "light {k} needed {} binned pairs, more than RecordOptions::binned_pairs; \
                     its target holds no shadows",
                    w[0]
                )));
            }
            report.lights.push(RecordedLight {
                light: k,
                binned_pairs: w[0],
                units: w[1],
            });
        }
        self.engine.ctx.check_validation()?;
        Ok(report)
    }
}

/// Bytes per light's status slot: 16, or the device's storage-binding
/// offset alignment when larger.
fn limits_stride(alignment: u64) -> u64 {
    alignment.max(16).next_multiple_of(16)
}
