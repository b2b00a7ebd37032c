//! The first pass of a frame: the view samples, what the camera sees. One
//! [`GpuViewSample`] per pixel (index `y * width + x`, `y = 0` the top row,
//! as [`Camera::ray_direction`]): the camera-relative point where the
//! pixel-centre ray meets the nearest triangle, that triangle's global id and
//! its unit geometric normal flipped to face the camera, flagged
//! [`VIEW_SAMPLE_VALID`]; all zero where nothing is seen.
//!
//! Two GPU steps:
//!
//! 1. **Raster** (`shaders/view_samples.{vert,frag}`): the triangles, read
//!    straight from the [`GpuTriangle`] buffer bound as a vertex buffer
//!    (16-byte stride: each `vec4` holds one vertex), are drawn non-indexed
//!    with an infinite reversed-Z perspective (`D32_SFLOAT`, test `GREATER`,
//!    so equal depths keep the earlier, smaller id like the oracle), no
//!    culling; the fragment shader writes `id + 1` to an `R32_UINT`
//!    attachment (0 = nothing). The rasteriser samples pixel centres, so a
//!    pixel's id is the triangle its centre ray meets, up to edge rules.
//!    Triangles without alpha tests draw with the shader's `OPAQUE`
//!    variant, which discards nothing, so its depth test runs before the
//!    shader: the same ids, and lavapipe skips the hidden fragments. A
//!    frame with alpha tests draws its triangles in id order by runs
//!    (`raster_runs`): long runs of opaque triangles with that variant,
//!    the rest with the alpha-testing one.
//!
//!    On a CPU device only the triangles whose image may contain a pixel
//!    centre are drawn (`drawn_triangles`, through an index buffer of
//!    their corners, so that `gl_VertexIndex / 3` is still the id): a
//!    triangle covers no sample, and so writes nothing, when every pixel
//!    centre lies outside it with its corners moved by the raster's f32
//!    and fixed-point rounding (`may_cover_pixel_centre`: its widened box
//!    holds no centre, or a small box's few centres each lie outside one
//!    of its edges); one near or behind the eye is always drawn. The ids
//!    are the same. Lavapipe shades vertices and sets up triangles on one
//!    thread, so its raster costs per triangle (ToyCar: 17 ms at 64², 29
//!    at 512²), and a model's small triangles far away or outside the view
//!    are most of its triangles at 256². A GPU draws every triangle (the
//!    test is host work it does not need).
//! 2. **Resolve** (`shaders/view_samples_resolve.comp`): per pixel, the
//!    pixel-centre ray (same formula as [`Camera::ray_direction`], in f32) is
//!    intersected with that triangle's plane — exact rather than an
//!    interpolated depth — and the sample written to a storage buffer.
//!    An image whose samples pass one storage binding
//!    (`maxStorageBufferRange`: lavapipe binds 128 MiB, 2048² samples) is
//!    resolved in bands of rows (`band_rows`), each dispatch binding its
//!    band's ranges of the id and sample buffers; the light passes then
//!    take the samples in batches (`gpu::batches`).
//!
//! The near plane is `1e-6 ×` the distance of the farthest vertex; there is
//! no far plane.

use std::ops::Range;

use glam::DVec3;

use crate::gpu::alpha::AlphaInputs;
use crate::gpu::dispatch::RGBA32UI;
use crate::gpu::shaders;
#[cfg(doc)]
use crate::gpu::shared::VIEW_SAMPLE_VALID;
use crate::gpu::shared::{GpuTriangle, GpuViewSample, TRIANGLE_ALPHA};
use crate::scene::Camera;
use crate::vulkan::Draw;
use crate::vulkan::{
    vertex_input_barrier, vk, Attachment, Barrier, Binding, Buffer, BufferDesc, CommandRecorder,
    ComputePipeline, ComputePipelineDesc, DescriptorKind, DeviceLimits, Framebuffer, GpuContext,
    GraphicsPipeline, GraphicsPipelineDesc, GrowBuffer, Profiler, VertexAttribute,
};
use crate::{Error, Result};

/// Push constants of `view_samples.vert` and `view_samples.frag`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct RasterPush {
    /// xyz: right / (tan(fov/2) · aspect).
    right: [f32; 4],
    /// xyz: −up / tan(fov/2).
    down: [f32; 4],
    /// xyz: forward; w: near.
    forward: [f32; 4],
    /// The pixel rays of the fragment shader's alpha test.
    ray: ViewRay,
}

/// `ViewRay` (`view_ray.glsl`): the camera as the pixel rays need it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct ViewRay {
    /// xyz: right; w: tan(fov/2) · aspect.
    right: [f32; 4],
    /// xyz: up; w: tan(fov/2).
    up: [f32; 4],
    /// xyz: forward.
    forward: [f32; 4],
    /// width, height, triangles, 1 when some triangle is alpha-tested.
    sizes: [u32; 4],
}

/// Push constants of `view_samples_resolve.comp`: the pixel rays and the
/// band of rows one dispatch resolves.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct ResolvePush {
    ray: ViewRay,
    /// The band's first row, its rows, 0, 0.
    band: [u32; 4],
}

// The shader's block: a ViewRay (64 bytes) and a uvec4, within the 128
// bytes of push constants every device has.
const _: () = assert!(std::mem::size_of::<ResolvePush>() == 80);

/// Bands of rows start at multiples of this: their byte offsets into the
/// id (4 B per pixel) and sample (32 B) buffers are then multiples of 256,
/// the largest binding-offset alignment Vulkan allows.
const BAND_ROW_MULTIPLE: u32 = 64;

/// The rows of one resolve dispatch for a `width × height` image: all of
/// them when one binding holds the image's samples and ids, else as many
/// as it holds, a multiple of [`BAND_ROW_MULTIPLE`]; at most `limit` (a
/// test's forced bands, rounded down to that multiple as well).
fn band_rows(limits: &DeviceLimits, [width, height]: [u32; 2], limit: Option<u32>) -> Result<u32> {
    let sample_bytes = std::mem::size_of::<GpuViewSample>() as u64;
    let width = width.max(1) as u64;
    let fit = (limits.max_storage_buffer_range as u64 / (width * sample_bytes))
        .min(limits.max_texel_buffer_elements as u64 / width)
        .min(limit.map_or(u64::MAX, |l| l as u64));
    if fit >= height as u64 {
        return Ok(height);
    }
    let rows = fit / BAND_ROW_MULTIPLE as u64 * BAND_ROW_MULTIPLE as u64;
    if rows == 0 {
        return Err(Error::InvalidInput(match limit {
            Some(l) if (l as u64) < BAND_ROW_MULTIPLE as u64 => {
                format!("a band limit of {l} rows: bands are multiples of {BAND_ROW_MULTIPLE} rows")
            }
            _ => format!(
                "{BAND_ROW_MULTIPLE} rows of {width} view samples pass the device's \
                 maxStorageBufferRange ({} bytes) or maxTexelBufferElements ({})",
                limits.max_storage_buffer_range, limits.max_texel_buffer_elements
            ),
        }));
    }
    Ok(rows as u32)
}

/// Render targets of one image size. Field order: the framebuffer is
/// destroyed before its attachments.
struct Targets {
    framebuffer: Framebuffer,
    ids: Attachment,
    _depth: Attachment,
    extent: [u32; 2],
}

/// The view-sample pass: pipelines made once, render targets kept per image
/// size, buffers kept across frames. See the [module documentation](self).
pub struct ViewSamplePass {
    /// With the alpha tests (a fragment may be discarded).
    raster: GraphicsPipeline,
    /// Without them, for frames with no alpha-tested triangle: the depth
    /// test runs before the fragment shader, which on lavapipe halves the
    /// raster of a model with much depth complexity.
    raster_opaque: GraphicsPipeline,
    resolve: ComputePipeline,
    targets: Option<Targets>,
    /// The triangles, also the vertex buffer.
    triangles: GrowBuffer,
    /// The corners of the triangles drawn (`drawn_triangles`): the index
    /// buffer.
    indices: GrowBuffer,
    /// Whether the raster draws only the triangles that may cover a pixel
    /// centre (module docs): on a CPU device by default.
    cull: bool,
    /// Triangles the last [`ViewSamplePass::render`] drew.
    drawn: usize,
    /// The raster's triangle ids, copied out of the attachment.
    ids: GrowBuffer,
    /// The view samples.
    samples: GrowBuffer,
    /// Bound in place of the alpha tables when there are none.
    none: GrowBuffer,
    profiler: Profiler,
    /// The resolve's push constants of [`ViewSamplePass::prepare_for_caller`].
    caller_push: Option<ViewRay>,
    /// At most this many rows per dispatch (tests force bands with it).
    band_limit: Option<u32>,
}

const ID_FORMAT: vk::Format = vk::Format::R32_UINT;

/// Runs of triangles without alpha tests shorter than this draw with the
/// alpha-testing variant (which passes them as it would any opaque
/// triangle), so that a scene of many small primitives makes few draws.
const MIN_OPAQUE_RUN: u32 = 1024;

/// The raster's draws over `triangles` (a frame with alpha tests), in id
/// order: each run of at least [`MIN_OPAQUE_RUN`] triangles without
/// [`TRIANGLE_ALPHA`] with the `OPAQUE` variant (false), whose depth test
/// runs before its fragment shader, the rest with the alpha-testing one
/// (true), which must shade every fragment it covers before its depth
/// test (on lavapipe). The ids are drawn in order, so equal depths keep
/// the smaller id as with one draw.
///
/// `drawn` lists the ids drawn, in increasing order; the runs are ranges
/// of positions in it.
fn raster_runs(triangles: &[GpuTriangle], drawn: &[u32]) -> Vec<(bool, Range<u32>)> {
    let mut runs: Vec<(bool, Range<u32>)> = Vec::new();
    let mut push = |alpha: bool, ids: Range<u32>| match runs.last_mut() {
        Some((a, last)) if *a == alpha && last.end == ids.start => last.end = ids.end,
        _ => runs.push((alpha, ids)),
    };
    let is_alpha = |k: usize| triangles[drawn[k] as usize].flags & TRIANGLE_ALPHA != 0;
    let mut start = 0usize;
    while start < drawn.len() {
        let alpha = is_alpha(start);
        let len = (start..drawn.len())
            .take_while(|&k| is_alpha(k) == alpha)
            .count();
        let end = start + len;
        let as_alpha = alpha || (len as u32) < MIN_OPAQUE_RUN;
        push(as_alpha, start as u32..end as u32);
        start = end;
    }
    if runs.is_empty() {
        runs.push((false, 0..0));
    }
    runs
}
const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// Relative rounding allowed for the raster's f32 transform of a vertex
/// (its dot products and divide, a few ulps: this is over a hundred).
const CULL_ROUNDING: f64 = 1e-5;
/// Pixels allowed per axis for the viewport transform's rounding and the
/// rasteriser's fixed-point vertex snapping: twice the most that Vulkan
/// allows (4 sub-pixel bits, 1/32 pixel; lavapipe has 8). With none, the
/// cull changes view samples (`tests/view_samples.rs`); 0.002 sufficed
/// there.
const CULL_SNAP: f64 = 0.0625;

/// Pixel centres a triangle's box may hold for [`may_cover_pixel_centre`]
/// to test each against its edges; a larger one is drawn.
const CULL_CENTRES: f64 = 16.0;

/// Whether triangle `t`'s image under `push` (the raster's transform) may
/// contain the centre of one of the `size` pixels: false only when each
/// corner moved by up to the raster's rounding (`margin` pixels per axis)
/// leaves every centre outside it: none in the widened bounding box, or,
/// for a box of at most [`CULL_CENTRES`] centres, each centre farther than
/// √2 `margin` outside one of its edges. Always true for a triangle with a
/// corner near or behind the eye (the raster clips it at the near plane),
/// one without area, or a coordinate that is not finite.
fn may_cover_pixel_centre(push: &RasterPush, size: [u32; 2], t: &GpuTriangle) -> bool {
    let v3 = |a: [f32; 4]| DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64);
    let axes = [v3(push.right), v3(push.down)];
    let forward = v3(push.forward);
    let (axes_abs, forward_abs) = (axes.map(|a| a.abs()), forward.abs());
    let half = size.map(|s| 0.5 * s as f64);
    let near = push.forward[3] as f64;
    let mut corners = [[0.0f64; 2]; 3];
    let mut margin = 0.0f64;
    for (c, v) in corners.iter_mut().zip([t.v0, t.v1, t.v2]) {
        let p = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        let z = p.dot(forward);
        if !(z > 2.0 * near && z.is_finite()) {
            return true;
        }
        // What the f32 dot products can be off by, before the divide.
        let (pa, inv_z) = (p.abs(), 1.0 / z);
        let z_err = pa.dot(forward_abs);
        for k in 0..2 {
            let ndc = p.dot(axes[k]) * inv_z;
            let err = CULL_ROUNDING * (pa.dot(axes_abs[k]) + ndc.abs() * z_err) * inv_z;
            c[k] = (ndc + 1.0) * half[k];
            margin = margin.max(err * half[k] + CULL_SNAP);
        }
    }
    if !(corners.iter().flatten().all(|x| x.is_finite()) && margin.is_finite()) {
        return true;
    }
    // The pixel centres i + 0.5 (0 <= i < size) inside the widened box.
    let range = |k: usize| {
        let lo = corners.iter().map(|c| c[k]).fold(f64::INFINITY, f64::min) - margin;
        let hi = corners
            .iter()
            .map(|c| c[k])
            .fold(f64::NEG_INFINITY, f64::max)
            + margin;
        let first = (lo - 0.5).ceil().max(0.0);
        let last = (hi - 0.5).floor().min(size[k] as f64 - 1.0);
        (first, last)
    };
    let ((x0, x1), (y0, y1)) = (range(0), range(1));
    if !(x0 <= x1 && y0 <= y1) {
        return false;
    }
    if (x1 - x0 + 1.0) * (y1 - y0 + 1.0) > CULL_CENTRES {
        return true;
    }
    let [a, b, c] = corners;
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if area.is_nan() || area.abs() <= 1e-9 {
        return true;
    }
    // A corner moved by up to `margin` on each axis moves by up to √2
    // `margin`, and so does every point of the triangle. Per edge (e0, e1):
    // a centre p lies farther than that outside it when (e1 - e0) x
    // (p - e0), signed by the winding, is below -√2 margin |e1 - e0|.
    let edges = [(a, b), (b, c), (c, a)].map(|(e0, e1)| {
        let (dx, dy) = (e1[0] - e0[0], e1[1] - e0[1]);
        let limit = -std::f64::consts::SQRT_2 * margin * (dx * dx + dy * dy).sqrt();
        (e0, dx * area.signum(), dy * area.signum(), limit)
    });
    let mut y = y0;
    while y <= y1 {
        let mut x = x0;
        while x <= x1 {
            let (px, py) = (x + 0.5, y + 0.5);
            let outside = edges
                .iter()
                .any(|&(e0, dx, dy, limit)| dx * (py - e0[1]) - dy * (px - e0[0]) < limit);
            if !outside {
                return true;
            }
            x += 1.0;
        }
        y += 1.0;
    }
    false
}

/// The ids of the triangles the raster draws, in increasing order: with
/// `cull`, those that [`may_cover_pixel_centre`]; without, all.
fn drawn_triangles(
    push: &RasterPush,
    size: [u32; 2],
    triangles: &[GpuTriangle],
    cull: bool,
) -> Vec<u32> {
    use rayon::prelude::*;
    if !cull {
        return (0..triangles.len() as u32).collect();
    }
    // Rayon's collect keeps the order.
    triangles
        .par_iter()
        .enumerate()
        .filter(|(_, t)| may_cover_pixel_centre(push, size, t))
        .map(|(i, _)| i as u32)
        .collect()
}

impl ViewSamplePass {
    /// Builds both pipelines; fails when the device's queue cannot do graphics.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let raster_with = |name, fragment| {
            ctx.create_graphics_pipeline(&GraphicsPipelineDesc {
                name,
                vertex: shaders::VIEW_SAMPLES_VERT,
                fragment,
                vertex_stride: 16,
                attributes: &[VertexAttribute {
                    location: 0,
                    format: vk::Format::R32G32B32_SFLOAT,
                    offset: 0,
                }],
                color_formats: &[ID_FORMAT],
                depth: Some((DEPTH_FORMAT, vk::CompareOp::GREATER)),
                cull_mode: vk::CullModeFlags::NONE,
                push_constant_bytes: std::mem::size_of::<RasterPush>() as u32,
                bindings: &[DescriptorKind::UniformTexelBuffer; 4],
            })
        };
        let raster = raster_with("view_samples_raster", shaders::VIEW_SAMPLES_FRAG)?;
        let raster_opaque = raster_with(
            "view_samples_raster_opaque",
            shaders::VIEW_SAMPLES_OPAQUE_FRAG,
        )?;
        let resolve = ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
            name: "view_samples_resolve",
            spirv: shaders::VIEW_SAMPLES_RESOLVE,
            bindings: &[
                DescriptorKind::UniformTexelBuffer,
                DescriptorKind::UniformTexelBuffer,
                DescriptorKind::StorageBuffer,
            ],
            push_constant_bytes: std::mem::size_of::<ResolvePush>() as u32,
            specialization: &[],
        })?;
        let mut triangles = BufferDesc::storage("view_triangles", 0);
        triangles.usage |= vk::BufferUsageFlags::VERTEX_BUFFER;
        let mut indices = BufferDesc::storage("view_triangle_corners", 0);
        indices.usage |= vk::BufferUsageFlags::INDEX_BUFFER;
        Ok(ViewSamplePass {
            raster,
            raster_opaque,
            resolve,
            targets: None,
            triangles: GrowBuffer::new(triangles),
            indices: GrowBuffer::new(indices),
            // The raster's per-triangle work is the host's on a CPU device
            // (lavapipe); a GPU's raster has no use for a host-side cull.
            cull: ctx.info().is_cpu(),
            drawn: 0,
            ids: GrowBuffer::storage("view_sample_ids"),
            samples: GrowBuffer::storage("view_samples"),
            none: GrowBuffer::storage("view_alpha_none"),
            profiler: Profiler::new(ctx, 1)?,
            caller_push: None,
            band_limit: None,
        })
    }

    /// Makes the render targets for `extent` (again) when the size changed.
    fn ensure_targets(&mut self, ctx: &GpuContext, extent: [u32; 2]) -> Result<()> {
        if self.targets.as_ref().is_none_or(|t| t.extent != extent) {
            self.targets = None;
            let ids = ctx.create_attachment("view_sample_ids", extent, ID_FORMAT, false)?;
            let depth = ctx.create_attachment("view_sample_depth", extent, DEPTH_FORMAT, true)?;
            let framebuffer = self.raster.framebuffer(&[&ids], Some(&depth))?;
            self.targets = Some(Targets {
                framebuffer,
                ids,
                _depth: depth,
                extent,
            });
        }
        Ok(())
    }

    /// Renders `triangles` (camera-relative [`GpuTriangle`]s, e.g. from
    /// [`crate::gpu::gpu_inputs`]; ids are indices into this slice) seen by
    /// `camera` (its eye is the origin of the triangles) into the pass's
    /// buffer of `width × height` [`GpuViewSample`]s (kept until the next
    /// call), and returns it with the GPU milliseconds of the raster and
    /// resolve steps (NaN when the device has no timestamps). Uploading the
    /// triangles is not timed.
    /// With `alpha`, the triangles marked
    /// [`crate::gpu::shared::TRIANGLE_ALPHA`] are seen only where its tests
    /// find them opaque; without, every triangle is opaque.
    pub fn render(
        &mut self,
        ctx: &GpuContext,
        camera: &Camera,
        triangles: &[GpuTriangle],
        alpha: Option<AlphaInputs>,
    ) -> Result<(&Buffer, f64)> {
        let any_alpha = alpha.is_some();
        let (raster_push, resolve_push, nt) = pushes(ctx, camera, triangles, any_alpha)?;
        let (width, height) = (camera.width, camera.height);
        let pixels = width as u64 * height as u64;
        let out_bytes = pixels * std::mem::size_of::<GpuViewSample>() as u64;
        self.ensure_targets(ctx, [width, height])?;
        let tri_buf = self.triangles.get(ctx, 48 * nt.max(1) as u64)?;
        if nt > 0 {
            ctx.upload(tri_buf, 0, triangles)?;
        }
        let drawn = drawn_triangles(&raster_push, [width, height], triangles, self.cull);
        self.drawn = drawn.len();
        // An index buffer only when some triangle is left out: with every
        // one drawn (a GPU, or nothing culled), a run's positions in
        // `drawn` are its ids, and the draws are the plain ones.
        let indexed = drawn.len() < nt as usize;
        if indexed {
            let corners: Vec<u32> = drawn
                .iter()
                .flat_map(|&t| [3 * t, 3 * t + 1, 3 * t + 2])
                .collect();
            let index_buf = self.indices.get(ctx, 4 * corners.len().max(1) as u64)?;
            if !corners.is_empty() {
                ctx.upload(index_buf, 0, &corners)?;
            }
        }
        self.ids.get(ctx, 4 * pixels)?;
        self.samples.get(ctx, out_bytes)?;
        let (tri_buf, ids_buf) = (self.triangles.buffer(), self.ids.buffer());
        let index_buf = indexed.then(|| self.indices.buffer());
        let targets = self.targets.as_ref().expect("made above");
        self.profiler.clear();
        let mut rec = ctx.begin()?;
        vertex_input_barrier(&mut rec);
        let scope = self.profiler.begin(&mut rec, "view_samples")?;
        let clear = [
            vk::ClearValue {
                color: vk::ClearColorValue { uint32: [0; 4] },
            },
            vk::ClearValue {
                depth_stencil: vk::ClearDepthStencilValue {
                    depth: 0.0,
                    stencil: 0,
                },
            },
        ];
        let tri_bits = tri_buf.slice(0, 48 * nt.max(1) as u64)?;
        self.none.get(ctx, 16)?;
        let placeholder = AlphaInputs::placeholder(self.none.slice());
        let [records, textures, alphas] = alpha.unwrap_or(placeholder).bindings();
        let raster_bindings = [
            Binding::uniform_texel(tri_bits, RGBA32UI),
            records,
            textures,
            alphas,
        ];
        let runs = match any_alpha {
            true => raster_runs(&triangles[..nt as usize], &drawn),
            false => vec![(false, 0..drawn.len() as u32)],
        };
        let draws: Vec<Draw> = runs
            .iter()
            .map(|(alpha, ids)| Draw {
                pipeline: if *alpha {
                    &self.raster
                } else {
                    &self.raster_opaque
                },
                first_vertex: 3 * ids.start,
                vertex_count: 3 * (ids.end - ids.start),
            })
            .collect();
        rec.draw_pass_ranges(
            &draws,
            &targets.framebuffer,
            &clear,
            (Some(tri_buf), index_buf),
            (bytemuck::bytes_of(&raster_push), &raster_bindings),
        )?;
        rec.copy_attachment_to_buffer(&targets.ids, 4, ids_buf)?;
        rec.barrier(Barrier::TransferToCompute);
        self.record_resolve(&mut rec, &resolve_push, nt)?;
        self.profiler.end(&mut rec, scope);
        ctx.submit_and_wait(rec)?;
        let ms = self.profiler.pass_ms("view_samples")?.unwrap_or(f64::NAN);
        Ok((self.samples.buffer(), ms))
    }
}

impl ViewSamplePass {
    /// Readies a caller's recording of the view samples of `camera` over
    /// `triangles` (as [`ViewSamplePass::render`] takes them): uploads the
    /// triangles and sizes the buffers; [`ViewSamplePass::record_from_ids`]
    /// records the rest.
    pub fn prepare_for_caller(
        &mut self,
        ctx: &GpuContext,
        camera: &Camera,
        triangles: &[GpuTriangle],
        any_alpha: bool,
    ) -> Result<()> {
        let (_, resolve_push, nt) = pushes(ctx, camera, triangles, any_alpha)?;
        let pixels = camera.width as u64 * camera.height as u64;
        let tri_buf = self.triangles.get(ctx, 48 * nt.max(1) as u64)?;
        if nt > 0 {
            ctx.upload(tri_buf, 0, triangles)?;
        }
        self.ids.get(ctx, 4 * pixels)?;
        self.samples
            .get(ctx, pixels * std::mem::size_of::<GpuViewSample>() as u64)?;
        self.caller_push = Some(resolve_push);
        Ok(())
    }

    /// Records, into a caller's recording, the view samples of a
    /// visibility buffer: `ids` (`R32_UINT`, the camera's size, in
    /// `TRANSFER_SRC_OPTIMAL`) holds per pixel the id + 1 of the triangle
    /// its centre ray meets (0: nothing), as the raster step writes it;
    /// the resolve step then makes the samples as [`ViewSamplePass::render`]
    /// does. After [`ViewSamplePass::prepare_for_caller`].
    pub fn record_from_ids(&self, rec: &mut CommandRecorder, ids: vk::Image) -> Result<()> {
        let push = self.caller_push.ok_or_else(|| {
            Error::InvalidInput("record_from_ids before prepare_for_caller".into())
        })?;
        let [width, height, nt, _] = push.sizes;
        let region = vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: vk::ImageAspectFlags::COLOR,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(vk::Extent3D {
                width,
                height,
                depth: 1,
            });
        // What the last frame's passes read, the copy rewrites.
        rec.barrier(Barrier::ComputeToTransfer);
        unsafe {
            rec.device().raw().cmd_copy_image_to_buffer(
                rec.raw(),
                ids,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                self.ids.buffer().raw(),
                &[region],
            )
        };
        rec.barrier(Barrier::TransferToCompute);
        self.record_resolve(rec, &push, nt)
    }

    /// The resolve step: per pixel, the ray-plane point on the triangle
    /// of the ids buffer, into the samples buffer.
    fn record_resolve(&self, rec: &mut CommandRecorder, push: &ViewRay, nt: u32) -> Result<()> {
        let [width, height, _, _] = push.sizes;
        // A texel view may not be empty: with no triangles the one-triangle
        // buffer is bound (and never read: every id is 0).
        let tri_buf = self.triangles.buffer();
        let tri_binding = Binding::uniform_texel(
            tri_buf.slice(0, 48 * nt.max(1) as u64)?,
            vk::Format::R32G32B32A32_SFLOAT,
        );
        let (ids, samples) = (self.ids.buffer(), self.samples.buffer());
        let sample_bytes = std::mem::size_of::<GpuViewSample>() as u64;
        let band = band_rows(rec.device().limits(), [width, height], self.band_limit)?;
        for first in (0..height).step_by(band.max(1) as usize) {
            let rows = band.min(height - first);
            let (start, len) = (first as u64 * width as u64, rows as u64 * width as u64);
            let resolve_push = ResolvePush {
                ray: *push,
                band: [first, rows, 0, 0],
            };
            rec.dispatch(
                &self.resolve,
                &[
                    Binding::uniform_texel(ids.slice(4 * start, 4 * len)?, vk::Format::R32_UINT),
                    tri_binding,
                    Binding::storage(samples.slice(sample_bytes * start, sample_bytes * len)?),
                ],
                bytemuck::bytes_of(&resolve_push),
                [width.div_ceil(8), rows.div_ceil(8), 1],
            )?;
        }
        rec.barrier(Barrier::ComputeToCompute);
        Ok(())
    }

    /// The triangles of the last [`ViewSamplePass::render`] or
    /// [`ViewSamplePass::prepare_for_caller`], as uploaded: the shadow
    /// passes read them from here (one upload per frame).
    ///
    /// # Panics
    /// Before the first render.
    pub fn triangles(&self) -> &Buffer {
        self.triangles.buffer()
    }

    /// Whether [`ViewSamplePass::render`] draws only the triangles whose
    /// image may contain a pixel centre (the default on a CPU device) or
    /// all of them (the default on a GPU); the view samples are the same
    /// (module docs).
    pub fn set_cull(&mut self, on: bool) {
        self.cull = on;
    }

    /// Resolves at most `rows` rows per dispatch (rounded down to a
    /// multiple of 64; `None`: as many as one binding holds). The samples
    /// are the same; tests force bands with it.
    pub fn set_band_limit(&mut self, rows: Option<u32>) {
        self.band_limit = rows;
    }

    /// How many triangles the last [`ViewSamplePass::render`] drew.
    pub fn drawn_triangles(&self) -> usize {
        self.drawn
    }

    /// The view samples of the last [`ViewSamplePass::render`].
    ///
    /// # Panics
    /// Before the first render.
    pub fn samples(&self) -> &Buffer {
        self.samples.buffer()
    }
}

/// Reads the first `n` [`GpuViewSample`]s of `buf` (e.g. the buffer
/// [`ViewSamplePass::render`] returned) back to the CPU.
pub fn read_view_samples(ctx: &GpuContext, buf: &Buffer, n: usize) -> Result<Vec<GpuViewSample>> {
    ctx.read_buffer(buf, 0, n)
}

/// The raster's and the resolve's push constants for `camera` over
/// `triangles` (checked against the device's limits), and the triangle
/// count.
fn pushes(
    ctx: &GpuContext,
    camera: &Camera,
    triangles: &[GpuTriangle],
    any_alpha: bool,
) -> Result<(RasterPush, ViewRay, u32)> {
    camera.validate()?;
    let (width, height) = (camera.width, camera.height);
    let pixels = width as u64 * height as u64;
    let out_bytes = pixels * std::mem::size_of::<GpuViewSample>() as u64;
    let limits = ctx.device().limits().clone();
    // Past one binding the resolve runs in bands and the light passes in
    // batches; past 4 GiB (11585² pixels) a frame's samples are more than
    // its passes index.
    if out_bytes > u32::MAX as u64 {
        return Err(Error::InvalidInput(format!(
            "{width}x{height} view samples need {out_bytes} bytes, more than the 4 GiB \
             of view samples one frame holds"
        )));
    }
    let nt = u32::try_from(triangles.len())
        .ok()
        .filter(|&n| (n as u64) * 3 <= limits.max_texel_buffer_elements as u64)
        .ok_or_else(|| {
            Error::InvalidInput(format!(
                "{} triangles are more than the view-sample pass can draw on this device",
                triangles.len()
            ))
        })?;

    // Camera basis and frustum in f32 (the eye is the origin).
    let (r, u, f) = camera.basis();
    let tan_half = (camera.fov_y_deg.to_radians() * 0.5).tan();
    let aspect = width as f64 / height as f64;
    let v4 = |v: DVec3, w: f64| [v.x as f32, v.y as f32, v.z as f32, w as f32];
    let far = triangles
        .iter()
        .flat_map(|t| [t.v0, t.v1, t.v2])
        .map(|v| glam::Vec3::from_array(v).length())
        .filter(|l| l.is_finite())
        .fold(0.0f32, f32::max);
    let near = if far > 0.0 { far * 1e-6 } else { 1e-6 };
    let resolve_push = ViewRay {
        right: v4(r, tan_half * aspect),
        up: v4(u, tan_half),
        forward: v4(f, 0.0),
        sizes: [width, height, nt, any_alpha as u32],
    };
    let raster_push = RasterPush {
        right: v4(r / (tan_half * aspect), 0.0),
        down: v4(-u / tan_half, 0.0),
        forward: [f.x as f32, f.y as f32, f.z as f32, near],
        ray: resolve_push,
    };
    Ok((raster_push, resolve_push, nt))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangles(alpha: &[(bool, usize)]) -> Vec<GpuTriangle> {
        alpha
            .iter()
            .flat_map(|&(a, n)| {
                std::iter::repeat_n(
                    GpuTriangle {
                        flags: if a { TRIANGLE_ALPHA } else { 0 },
                        ..Default::default()
                    },
                    n,
                )
            })
            .collect()
    }

    /// The cull's rule on hand-made cases: a 10x10 image seen along -z
    /// with a 90° field of view (pixel (px, py) at depth 1 is x = px / 5 -
    /// 1, y = 1 - py / 5).
    #[test]
    fn pixel_centre_rule_cases() {
        let push = RasterPush {
            right: [1.0, 0.0, 0.0, 0.0],
            down: [0.0, -1.0, 0.0, 0.0],
            forward: [0.0, 0.0, -1.0, 1e-6],
            ray: ViewRay::default(),
        };
        let at = |px: f32, py: f32, z: f32| {
            glam::Vec3::new((px / 5.0 - 1.0) * z, (1.0 - py / 5.0) * z, -z)
        };
        let tri = |v: [glam::Vec3; 3]| GpuTriangle::new(v, 0, 0);
        let size = [10, 10];
        let covers = |t: GpuTriangle| may_cover_pixel_centre(&push, size, &t);
        // Around the centre (3.5, 4.5), and a small one between centres.
        assert!(covers(tri([
            at(3.0, 4.0, 2.0),
            at(4.2, 4.0, 2.0),
            at(3.0, 5.2, 2.0)
        ])));
        assert!(!covers(tri([
            at(3.6, 4.6, 2.0),
            at(4.2, 4.6, 2.0),
            at(3.6, 5.2, 2.0)
        ])));
        // Legs from (2.6, 3.6) of length l: the box holds one centre,
        // (3.5, 4.5), which lies (1.8 - l) / √2 outside the hypotenuse:
        // 0.2 pixel, left out; 0.05 pixel (within the margin), drawn.
        let legs = |l: f32| {
            tri([
                at(2.6, 3.6, 2.0),
                at(2.6 + l, 3.6, 2.0),
                at(2.6, 3.6 + l, 2.0),
            ])
        };
        assert!(!covers(legs(1.8 - 0.2 * std::f32::consts::SQRT_2)));
        assert!(covers(legs(1.8 - 0.05 * std::f32::consts::SQRT_2)));
        assert!(covers(legs(1.9)));
        // Off the image, beyond its last centre by 0.3 pixel.
        assert!(!covers(tri([
            at(9.8, 2.0, 3.0),
            at(12.0, 2.0, 3.0),
            at(12.0, 6.0, 3.0)
        ])));
        assert!(!covers(tri([
            at(-3.0, -3.0, 3.0),
            at(-1.0, -3.0, 3.0),
            at(-1.0, 20.0, 3.0)
        ])));
        // A corner at or behind the eye, or not finite: always drawn.
        assert!(covers(tri([
            glam::Vec3::new(50.0, 50.0, 1.0),
            at(20.0, 20.0, 3.0),
            at(21.0, 20.0, 3.0)
        ])));
        assert!(covers(tri([
            glam::Vec3::ZERO,
            at(20.0, 20.0, 3.0),
            at(21.0, 20.0, 3.0)
        ])));
        assert!(covers(tri([
            glam::Vec3::splat(f32::NAN),
            at(20.0, 20.0, 3.0),
            at(21.0, 20.0, 3.0)
        ])));
        // No area (one point three times), its box holding a centre:
        // drawn (no winding to test against).
        assert!(covers(tri([at(3.45, 4.45, 2.0); 3])));
        // The cull off draws every id; on, the same order.
        let tris = [
            tri([at(3.0, 4.0, 2.0), at(4.2, 4.0, 2.0), at(3.0, 5.2, 2.0)]),
            tri([at(3.6, 4.6, 2.0), at(4.2, 4.6, 2.0), at(3.6, 5.2, 2.0)]),
            tri([at(0.0, 0.0, 2.0), at(10.0, 0.0, 2.0), at(0.0, 10.0, 2.0)]),
        ];
        assert_eq!(drawn_triangles(&push, size, &tris, false), [0, 1, 2]);
        assert_eq!(drawn_triangles(&push, size, &tris, true), [0, 2]);
    }

    #[test]
    fn raster_runs_cover_every_id_in_order() {
        let m = MIN_OPAQUE_RUN as usize;
        let cases: [&[(bool, usize)]; 5] = [
            &[],
            &[(true, 5)],
            &[(false, m), (true, 3), (false, m + 1)],
            // A short opaque run joins the alpha runs around it.
            &[(true, 2), (false, m - 1), (true, 4), (false, 2 * m)],
            &[(false, 7)],
        ];
        let expected: [&[(bool, u32)]; 5] = [
            &[(false, 0)],
            &[(true, 5)],
            &[(false, m as u32), (true, 3), (false, m as u32 + 1)],
            &[(true, m as u32 + 5), (false, 2 * m as u32)],
            &[(true, 7)],
        ];
        for (case, want) in cases.iter().zip(expected) {
            let t = triangles(case);
            let all: Vec<u32> = (0..t.len() as u32).collect();
            let runs = raster_runs(&t, &all);
            let mut next = 0;
            for (alpha, ids) in &runs {
                assert_eq!(ids.start, next, "runs in id order, none left out: {case:?}");
                next = ids.end;
                // An alpha-tested triangle is never drawn without its test.
                assert!(
                    *alpha
                        || t[ids.start as usize..ids.end as usize]
                            .iter()
                            .all(|t| t.flags & TRIANGLE_ALPHA == 0)
                );
            }
            assert_eq!(next as usize, t.len());
            let got: Vec<(bool, u32)> = runs.iter().map(|(a, r)| (*a, r.end - r.start)).collect();
            assert_eq!(got, want, "{case:?}");
        }
    }
}
