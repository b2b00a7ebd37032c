//! Shadows recorded into a caller's command buffer (issue 18):
//! `Engine::record_frame` records the view samples and two lights into one
//! command buffer that the test, as the renderer, begins, submits and
//! waits for; both lights' targets must equal `Engine::render`'s frame of
//! the same scene on a second engine bit for bit, from a visibility buffer
//! (triangle-id image) and from a buffer of view samples, into buffers and
//! into a storage image. Validation is on: a message fails the test.

use alias_free_shadows::gpu::shared::{GpuViewSample, VIEW_SAMPLE_VALID};
use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::render::{
    Engine, Frame, FrameOptions, RecordOptions, RecordReport, ViewSampleSource, VisibilityTarget,
};
use alias_free_shadows::scene::file::{self, SceneDescription, SoftMode};
use alias_free_shadows::vulkan::{
    barrier, vk, Buffer, BufferDesc, ContextOptions, Device, GpuContext, ImageDesc,
};
use glam::{DVec3, Vec3};
use std::sync::Arc;

/// `builtin:demo` at 48×40 with a point light and a sphere light (exact
/// mode, 64 samples).
fn scene() -> SceneDescription {
    scene_of("builtin:demo")
}

/// Scene `name` at 48×40 under the same two lights.
fn scene_of(name: &str) -> SceneDescription {
    let mut desc = file::load(name).unwrap();
    desc.camera.width = 48;
    desc.camera.height = 40;
    desc.shadows.mode = SoftMode::Exact;
    let base = desc.lights[0].clone();
    let p = base.center().unwrap();
    desc.lights = vec![
        Light {
            shape: LightShape::Point { position: p },
            ..base.clone()
        },
        Light {
            shape: LightShape::Sphere {
                position: p + DVec3::new(-1.5, 0.0, 1.0),
                radius: 0.4,
            },
            samples: 64,
            ..base
        },
    ];
    desc
}

/// A one-time command buffer of `ctx`'s queue family, begun: what a
/// renderer records its frame into.
struct CallerCommands {
    device: Arc<Device>,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
}

impl CallerCommands {
    fn begin(device: &Arc<Device>) -> Self {
        let d = device.raw();
        unsafe {
            let pool = d
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default().queue_family_index(device.queue_family()),
                    None,
                )
                .unwrap();
            let cmd = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
                .unwrap()[0];
            d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
                .unwrap();
            CallerCommands {
                device: Arc::clone(device),
                pool,
                cmd,
            }
        }
    }

    /// Ends, submits and waits; the renderer's barrier to the host first.
    fn submit_and_wait(&self) {
        let d = self.device.raw();
        unsafe {
            let barrier = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::TRANSFER_READ | vk::AccessFlags::HOST_READ);
            d.cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
            d.end_command_buffer(self.cmd).unwrap();
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .unwrap();
            let cmds = [self.cmd];
            let submit = vk::SubmitInfo::default().command_buffers(&cmds);
            d.queue_submit(*self.device.queue(), &[submit], fence)
                .unwrap();
            d.wait_for_fences(&[fence], true, 300_000_000_000).unwrap();
            d.destroy_fence(fence, None);
        }
    }
}

impl Drop for CallerCommands {
    fn drop(&mut self) {
        unsafe { self.device.raw().destroy_command_pool(self.pool, None) };
    }
}

/// Moves `image` from `GENERAL` (where the crate's images live) to
/// `TRANSFER_SRC_OPTIMAL`, its writes visible after.
fn to_transfer_src(device: &Device, cmd: vk::CommandBuffer, image: vk::Image) {
    barrier::image_layout(
        device.raw(),
        cmd,
        image,
        vk::ImageLayout::GENERAL,
        vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
        vk::PipelineStageFlags::TRANSFER,
    );
}

/// The renderer's buffers: `frame`'s view samples, and two visibility
/// targets.
fn renderer_buffers(ctx: &GpuContext, frame: &Frame) -> (Buffer, Vec<Buffer>) {
    let n = frame.view.samples.len() as u64;
    let samples = ctx
        .create_buffer_with_data(
            BufferDesc::storage("samples", 32 * n),
            &gpu_view_samples(frame),
        )
        .unwrap();
    let targets = (0..2)
        .map(|k| {
            ctx.create_buffer(BufferDesc::storage(format!("target {k}"), 4 * n))
                .unwrap()
        })
        .collect();
    (samples, targets)
}

fn differing(a: &[f32], b: &[f32]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count()
}

/// The view samples of `frame` as the GPU holds them (camera-relative
/// `f32`, as its dump writes them).
fn gpu_view_samples(frame: &Frame) -> Vec<GpuViewSample> {
    (0..frame.view.samples.len())
        .map(|i| match &frame.view.samples[i] {
            Some(s) => GpuViewSample::new(
                Vec3::from_slice(&frame.dump.position[i][..3]),
                s.triangle,
                Vec3::from_slice(&frame.dump.normal[i][..3]),
                VIEW_SAMPLE_VALID,
            ),
            None => GpuViewSample::default(),
        })
        .collect()
}

fn buffer_source(b: &Buffer) -> ViewSampleSource {
    ViewSampleSource::Buffer {
        buffer: b.raw(),
        offset: 0,
    }
}

fn buffer_target(b: &Buffer) -> VisibilityTarget {
    VisibilityTarget::Buffer {
        buffer: b.raw(),
        offset: 0,
    }
}

/// As a renderer: one command buffer with `before`'s commands, the view
/// samples from `source`, and `lights` (light, target) in that order; one
/// submission, waited for; then `finish`.
fn record_one_submission(
    engine: &mut Engine,
    desc: &SceneDescription,
    options: &RecordOptions,
    (before, source): (impl FnOnce(&Device, vk::CommandBuffer), ViewSampleSource),
    lights: &[(usize, VisibilityTarget)],
) -> alias_free_shadows::Result<RecordReport> {
    let device = Arc::clone(engine.context().device());
    let mut recorded = engine.record_frame(desc, options)?;
    let cmds = CallerCommands::begin(&device);
    before(&device, cmds.cmd);
    // SAFETY: the command buffer is the engine device's, in the recording
    // state; the sources and targets live until after the wait below, and
    // so does `recorded`.
    unsafe {
        recorded.record_view_samples(cmds.cmd, source)?;
        for &(k, target) in lights {
            recorded.record_light(cmds.cmd, k, target)?;
        }
    }
    cmds.submit_and_wait();
    drop(cmds);
    recorded.finish()
}

#[test]
fn two_lights_recorded_into_one_submission_equal_the_engines_frame() {
    let desc = scene();
    let n = (desc.camera.width * desc.camera.height) as usize;
    let mut own = Engine::new(&ContextOptions::validated()).unwrap();
    let frame = own.render(&desc, FrameOptions::default()).unwrap();
    let expected: Vec<Vec<f32>> = frame
        .dump
        .visibility
        .iter()
        .map(|l| l.iter().map(|v| v[0]).collect())
        .collect();
    own.context().check_validation().unwrap();
    // The lights cast shadows and light something: a test that can fail.
    for (k, v) in expected.iter().enumerate() {
        let lit = v.iter().filter(|&&x| x > 0.0).count();
        let dark = v.iter().filter(|&&x| x < 1.0).count();
        assert!(
            lit > n / 10 && dark > n / 20,
            "light {k}: {lit} lit, {dark} not"
        );
    }

    // The renderer's resources, on the engine's device.
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let ctx = engine.context();
    let (w, h) = (desc.camera.width, desc.camera.height);
    // Its visibility buffer: per pixel, the triangle + 1.
    let ids: Vec<u32> = frame
        .view
        .samples
        .iter()
        .map(|s| s.as_ref().map_or(0, |s| s.triangle + 1))
        .collect();
    let ids_image = ctx
        .create_image(&ImageDesc::d2("ids", w, h, vk::Format::R32_UINT))
        .unwrap();
    ctx.upload_image(&ids_image, bytemuck::cast_slice(&ids))
        .unwrap();
    let (samples, targets) = renderer_buffers(ctx, &frame);
    let image_target = ctx
        .create_image(&ImageDesc::d2("target image", w, h, vk::Format::R32_SFLOAT))
        .unwrap();

    // 1. The visibility buffer; both lights into buffers, one submission.
    let ids_raw = ids_image.raw();
    let to_src = |d: &Device, cmd| to_transfer_src(d, cmd, ids_raw);
    let lights = [
        (0, buffer_target(&targets[0])),
        (1, buffer_target(&targets[1])),
    ];
    let source = (to_src, ViewSampleSource::TriangleIds(ids_raw));
    let options = RecordOptions::default();
    let report = record_one_submission(&mut engine, &desc, &options, source, &lights).unwrap();
    assert_eq!(report.lights.len(), 2);
    assert!(report
        .lights
        .iter()
        .all(|l| l.binned_pairs > 0 && l.units > 0));
    for (k, t) in targets.iter().enumerate() {
        let got: Vec<f32> = engine.context().read_buffer_staged(t, 0, n).unwrap();
        let d = differing(&got, &expected[k]);
        assert_eq!(
            d, 0,
            "visibility buffer, light {k}: {d} of {n} pixels differ"
        );
    }

    // 2. The view samples as a buffer; light 1 into an image, then light 0
    // into a buffer (cleared first).
    engine
        .context()
        .upload_staged(&targets[0], 0, &vec![0u32; n])
        .unwrap();
    let lights = [
        (1, VisibilityTarget::Image(image_target.view())),
        (0, buffer_target(&targets[0])),
    ];
    let source = (|_: &Device, _| {}, buffer_source(&samples));
    let before = engine.context().allocations();
    record_one_submission(&mut engine, &desc, &options, source, &lights).unwrap();
    let ctx = engine.context();
    // A second recorded frame of the same size makes no buffer or image.
    assert_eq!(
        ctx.allocations(),
        before,
        "the second recorded frame allocated"
    );
    let got: Vec<f32> = ctx.read_buffer_staged(&targets[0], 0, n).unwrap();
    assert_eq!(differing(&got, &expected[0]), 0, "sample buffer, light 0");
    let bytes = ctx.read_image(&image_target, 4).unwrap();
    let got: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
    let d = differing(&got, &expected[1]);
    assert_eq!(d, 0, "sample buffer, light 1 (image)");
    ctx.check_validation().unwrap();
}

#[test]
fn an_overflowing_pair_list_is_reported_and_lookup_mode_refused() {
    let desc = scene();
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let n = (desc.camera.width * desc.camera.height) as u64;
    let ctx = engine.context();
    let target = ctx
        .create_buffer(BufferDesc::storage("target", 4 * n))
        .unwrap();
    let samples = ctx
        .create_buffer(BufferDesc::storage("samples", 32 * n))
        .unwrap();
    let options = RecordOptions { binned_pairs: 1 };
    let none = |_: &Device, _| {};

    // All-zero samples: none is valid, so nothing is binned or overflows.
    let lights = [(0, buffer_target(&target))];
    let source = (none, buffer_source(&samples));
    let report = record_one_submission(&mut engine, &desc, &options, source, &lights).unwrap();
    assert_eq!(report.lights[0].binned_pairs, 0);
    // A light the frame does not have.
    let lights = [(2, buffer_target(&target))];
    let source = (none, buffer_source(&samples));
    let err = record_one_submission(&mut engine, &desc, &options, source, &lights);
    assert!(err.is_err(), "light 2 of 2");

    // With the real view samples, one entry is too few.
    let mut own = Engine::new(&ContextOptions::validated()).unwrap();
    let frame = own.render(&desc, FrameOptions::default()).unwrap();
    let ctx = engine.context();
    ctx.upload_staged(&samples, 0, &gpu_view_samples(&frame))
        .unwrap();
    let lights = [(1, buffer_target(&target))];
    let source = (none, buffer_source(&samples));
    let err = record_one_submission(&mut engine, &desc, &options, source, &lights)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("light 1 needed") && err.contains("binned_pairs"),
        "{err}"
    );

    // Look-up mode sizes its work on the host: refused up front.
    let mut lut = desc.clone();
    lut.shadows.mode = SoftMode::Lut;
    let err = engine
        .record_frame(&lut, &RecordOptions::default())
        .err()
        .expect("look-up mode is refused")
        .to_string();
    assert!(err.contains("exact mode"), "{err}");

    // An image whose view samples pass one binding: a recording has no
    // batches, so it is refused up front with what to do instead.
    let range = engine.context().info().limits.max_storage_buffer_range as u64;
    let mut large = desc.clone();
    large.camera.width = 2048;
    large.camera.height = (range / (32 * 2048)) as u32 + 8;
    let err = engine
        .record_frame(&large, &RecordOptions::default())
        .err()
        .expect("an image past one binding is refused")
        .to_string();
    assert!(
        err.contains("maxStorageBufferRange") && err.contains("Engine::render"),
        "{err}"
    );
    engine.context().check_validation().unwrap();
}

/// An alpha-tested scene: the opaque casters and the alpha-tested ones run
/// in two rounds inside one recording, and both lights still equal
/// `Engine::render`'s frame bit for bit.
#[test]
fn an_alpha_tested_scene_records_both_caster_rounds() {
    let desc = scene_of("builtin:fence");
    let n = (desc.camera.width * desc.camera.height) as usize;
    let mut own = Engine::new(&ContextOptions::validated()).unwrap();
    let frame = own.render(&desc, FrameOptions::default()).unwrap();
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let ctx = engine.context();
    let (samples, targets) = renderer_buffers(ctx, &frame);
    let lights = [
        (0, buffer_target(&targets[0])),
        (1, buffer_target(&targets[1])),
    ];
    let source = (|_: &Device, _| {}, buffer_source(&samples));
    let options = RecordOptions::default();
    record_one_submission(&mut engine, &desc, &options, source, &lights).unwrap();
    for (k, t) in targets.iter().enumerate() {
        let expected: Vec<f32> = frame.dump.visibility[k].iter().map(|v| v[0]).collect();
        let dark = expected.iter().filter(|&&v| v < 1.0).count();
        assert!(
            dark > n / 20,
            "light {k}: the fence casts shadows ({dark} pixels)"
        );
        let got: Vec<f32> = engine.context().read_buffer_staged(t, 0, n).unwrap();
        let d = differing(&got, &expected);
        assert_eq!(d, 0, "fence, light {k}: {d} of {n} pixels differ");
    }
    // Too small a list in either round is reported, never hidden by the
    // other round.
    let lights = [(0, buffer_target(&targets[0]))];
    let source = (|_: &Device, _| {}, buffer_source(&samples));
    let tiny = RecordOptions { binned_pairs: 1 };
    let err = record_one_submission(&mut engine, &desc, &tiny, source, &lights).unwrap_err();
    assert!(err.to_string().contains("light 0 needed"), "{err}");
    engine.context().check_validation().unwrap();
}
