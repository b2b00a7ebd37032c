//! Alias-free hard shadows on Vulkan compute (paper §3), for point lights
//! (six cube faces, empty ones skipped) and directional lights (one
//! orthographic face). The passes, in order:
//!
//! 1. `light_fit` + `light_fit_finalize`: each face's window fitted to the
//!    view samples that face the light, far plane at the farthest one;
//! 2. `texel_count`, scan, `texel_scatter`: per-light-texel lists of view samples;
//! 3. `caster_setup`: casting triangles, their planes and conservative
//!    per-face rectangles and edges; `caster_clip` (indirect) for the few
//!    projections that must be clipped to a face's window pyramid;
//! 4. `tile_bin` (count), scan, `tile_bin` (scatter): (caster, face) pairs per tile;
//!    `tile_units`, scan: per tile, its occlusion work units (chunks of pairs
//!    times chunks of its longest list, so that no invocation loops past
//!    lavapipe's limit of 65535 loop iterations per invocation);
//! 5. `occlusion`: every listed sample of every touched texel against its tile's casters;
//! 6. `resolve`: per view sample lit / evaluated.
//!
//! Each pass has a CPU twin in [`crate::cpu`]; the whole chain's twin is
//! [`crate::cpu::hard_shadows::hard_shadows`].

use crate::cpu::light_view::LightView;
use crate::gpu::scan::ScanPass;
use crate::gpu::shaders;
use crate::gpu::shared::{
    counter, GpuTriangle, GpuViewSample, HardPush, LIGHT_KIND_DIRECTIONAL, LIGHT_KIND_POINT,
};
use crate::vulkan::{
    vk, Barrier, Binding, Buffer, BufferDesc, CommandRecorder, ComputePipeline,
    ComputePipelineDesc, DescriptorKind, GpuContext, PassTiming, Profiler,
};
use crate::{Error, Result};

/// Texel format the hot gathers read (floats travel as bits).
const RGBA32UI: vk::Format = vk::Format::R32G32B32A32_UINT;

/// Workgroup size of the 1D passes.
const WG: u32 = 64;
/// Tile side in texels (`TILE` in hard_common.glsl).
pub const TILE: u32 = 8;

/// What one hard-shadow run returns.
#[derive(Clone, Debug)]
pub struct HardShadowOutput {
    /// Per view sample: `None` when not evaluated (invalid, or facing away
    /// from the light), else whether it is lit.
    pub lit: Vec<Option<bool>>,
    /// The pass counters (indices in [`counter`]).
    pub counters: [u32; counter::COUNT],
    /// Per light texel, tile-major (`texel_index` in hard_common.glsl):
    /// list length. Split runs keep the batch with the longest list.
    pub list_lengths: Vec<u32>,
    /// GPU milliseconds per pass.
    pub timings: Vec<PassTiming>,
    /// Bytes of GPU buffers this run allocated.
    pub buffer_bytes: u64,
    /// Soft shadows only: per view sample, visibility in [0, 1] (`None`
    /// where not evaluated), and its visible light samples, `mask_words`
    /// words per sample (bit `j % 32` of word `j / 32` for light sample `j`).
    pub soft: Option<SoftOutput>,
}

/// What a soft-shadow run returns besides the common output.
#[derive(Clone, Debug)]
pub struct SoftOutput {
    /// Per view sample: visible fraction of the light samples, `None`
    /// where not evaluated (invalid, or facing away from the whole light).
    pub visibility: Vec<Option<f32>>,
    /// Visible light samples per view sample, `mask_words` words each.
    pub visible: Vec<u32>,
    /// Words per view sample in `visible` (4 per 128-sample block).
    pub mask_words: usize,
    /// Whether this run built the plane look-up texture (`lut_build` in the
    /// timings); false in exact mode and when the last one was reused.
    pub lut_built: bool,
}

/// A light with extent as the soft-shadow passes see it (paper §4): its
/// samples, camera-relative, and how the planes are evaluated.
#[derive(Clone, Debug)]
pub struct SoftLight {
    /// 1 to 1024 light samples, camera-relative.
    pub samples: Vec<glam::Vec3>,
    /// Test every light sample against the planes instead of looking the
    /// planes up (`mode = "exact"`).
    pub exact: bool,
    /// Plane look-up texture resolution (`lut_resolution`³ texels per block).
    pub lut_resolution: u32,
    /// Corners of the polygon that bounds the light's silhouette in the
    /// influence regions (6: a hexagon).
    pub polygon_degree: u32,
}

impl SoftLight {
    /// The centre and bounding radius of the samples (their bounding box's
    /// centre and the largest distance to it, rounded up).
    pub fn bounds(&self) -> (glam::Vec3, f32) {
        let lo = self
            .samples
            .iter()
            .fold(glam::Vec3::splat(f32::INFINITY), |a, &b| a.min(b));
        let hi = self
            .samples
            .iter()
            .fold(glam::Vec3::splat(f32::NEG_INFINITY), |a, &b| a.max(b));
        let c = (lo + hi) * 0.5;
        let r = self
            .samples
            .iter()
            .map(|s| s.distance(c))
            .fold(0.0f32, f32::max);
        // Rounded up, and never 0 (one sample): every |y| stays <= 1.
        let scale = c.abs().max_element().max(hi.abs().max_element()).max(1e-30);
        (c, (r * (1.0 + 1e-5)).max(scale * 1e-6))
    }
}

/// Maximum number of light samples (`MAX_LIGHT_SAMPLES` in soft_common.glsl).
pub const MAX_SOFT_SAMPLES: usize = 1024;

/// The compiled pipelines of the hard-shadow passes; create once, run per frame.
pub struct HardShadowPass {
    light_fit: ComputePipeline,
    light_fit_finalize: ComputePipeline,
    texel_count: ComputePipeline,
    texel_scatter: ComputePipeline,
    caster_setup: ComputePipeline,
    caster_clip_args: ComputePipeline,
    caster_clip: ComputePipeline,
    tile_count: ComputePipeline,
    tile_scatter: ComputePipeline,
    tile_units: ComputePipeline,
    occlusion: ComputePipeline,
    resolve: ComputePipeline,
    /// Soft passes' work units: one lane per listed sample of a tile.
    tile_units_soft: ComputePipeline,
    lut_build: ComputePipeline,
    /// LUT-mode occlusion, one pipeline per number of 128-sample blocks (1 to 8).
    occlusion_lut: Vec<ComputePipeline>,
    occlusion_exact: ComputePipeline,
    soft_resolve: ComputePipeline,
    scan: ScanPass,
    /// The last plane look-up texture built, kept across frames: it depends
    /// only on the light's normalized samples and the resolution.
    plane_lut: Option<PlaneLut>,
    /// At most this many view samples per run; more are split into batches
    /// (None: as many as the device's binding limits allow).
    batch_limit: Option<usize>,
    /// At most this many triangles per run (None: as many as the device's
    /// binding limits allow for the caster pairs and planes).
    triangle_batch_limit: Option<usize>,
    /// The global id of triangle 0 of the current run (triangle batches):
    /// view samples name their own triangle by global id.
    triangle_base: u32,
}

/// A plane look-up texture on the device and what it was built from.
struct PlaneLut {
    /// Bits of the normalized samples, then the resolution.
    key: Vec<u32>,
    buffer: Buffer,
}

/// Pairs per soft occlusion work unit (spec constant 2, OCC_PAIR_CHUNK):
/// each lane has one sample, and in exact mode each test loops over 128
/// light samples, so 256 · 129 stays below lavapipe's 65535 loop
/// iterations per invocation.
const SOFT_PAIR_CHUNK: (u32, u32) = (2, 256);

fn groups(n: u32) -> [u32; 3] {
    let g = n.div_ceil(WG);
    if g <= 65535 {
        [g, 1, 1]
    } else {
        [65535, g.div_ceil(65535), 1]
    }
}

fn groups_2d(g: u32) -> [u32; 3] {
    if g <= 65535 {
        [g, 1, 1]
    } else {
        [65535, g.div_ceil(65535), 1]
    }
}

impl HardShadowPass {
    /// Builds every pipeline.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let sb = DescriptorKind::StorageBuffer;
        let tb = DescriptorKind::UniformTexelBuffer;
        let ub = DescriptorKind::UniformBuffer;
        let push = std::mem::size_of::<HardPush>() as u32;
        let make = |name: &str, spirv: &[u32], bindings: &[DescriptorKind], spec: &[(u32, u32)]| {
            ctx.create_compute_pipeline(&ComputePipelineDesc {
                name,
                spirv,
                bindings,
                push_constant_bytes: push,
                specialization: spec,
            })
        };
        Ok(HardShadowPass {
            light_fit: make("light_fit", shaders::LIGHT_FIT, &[sb; 2], &[])?,
            light_fit_finalize: make(
                "light_fit_finalize",
                shaders::LIGHT_FIT_FINALIZE,
                &[sb; 2],
                &[],
            )?,
            texel_count: make(
                "texel_count",
                shaders::TEXEL_COUNT,
                &[sb, ub, sb, sb, sb, sb],
                &[],
            )?,
            texel_scatter: make("texel_scatter", shaders::TEXEL_SCATTER, &[sb; 5], &[])?,
            caster_setup: make(
                "caster_setup",
                shaders::CASTER_SETUP,
                &[tb, ub, sb, sb, sb, sb],
                &[],
            )?,
            caster_clip_args: make("caster_clip_args", shaders::CASTER_CLIP_ARGS, &[sb; 2], &[])?,
            caster_clip: make(
                "caster_clip",
                shaders::CASTER_CLIP,
                &[tb, ub, sb, sb, sb, sb],
                &[],
            )?,
            tile_count: make("tile_bin_count", shaders::TILE_BIN, &[sb; 6], &[(1, 0)])?,
            tile_scatter: make("tile_bin_scatter", shaders::TILE_BIN, &[sb; 6], &[(1, 1)])?,
            tile_units: make("tile_units", shaders::TILE_UNITS, &[sb; 3], &[])?,
            occlusion: make(
                "occlusion",
                shaders::OCCLUSION,
                &[tb, tb, sb, tb, sb, sb, tb, sb, sb, sb],
                &[],
            )?,
            resolve: make("resolve", shaders::RESOLVE, &[sb; 4], &[])?,
            tile_units_soft: make(
                "tile_units_soft",
                shaders::TILE_UNITS_SAMPLE_LANES,
                &[sb; 3],
                &[SOFT_PAIR_CHUNK],
            )?,
            lut_build: make(
                "lut_build",
                shaders::LUT_BUILD,
                &[DescriptorKind::StorageTexelBuffer, ub],
                &[],
            )?,
            occlusion_lut: [
                shaders::OCCLUSION_SOFT_LUT1,
                shaders::OCCLUSION_SOFT_LUT2,
                shaders::OCCLUSION_SOFT_LUT3,
                shaders::OCCLUSION_SOFT_LUT4,
                shaders::OCCLUSION_SOFT_LUT5,
                shaders::OCCLUSION_SOFT_LUT6,
                shaders::OCCLUSION_SOFT_LUT7,
                shaders::OCCLUSION_SOFT_LUT8,
            ]
            .iter()
            .enumerate()
            .map(|(b, spirv)| {
                make(
                    &format!("occlusion_soft_lut{}", b + 1),
                    spirv,
                    &[tb, tb, sb, tb, sb, sb, tb, sb, sb, sb, ub, tb],
                    &[SOFT_PAIR_CHUNK],
                )
            })
            .collect::<Result<_>>()?,
            occlusion_exact: make(
                "occlusion_soft_exact",
                shaders::OCCLUSION_SOFT_EXACT,
                &[tb, tb, sb, tb, sb, sb, tb, sb, sb, sb, ub, tb],
                &[SOFT_PAIR_CHUNK],
            )?,
            soft_resolve: make(
                "soft_resolve",
                shaders::SOFT_RESOLVE,
                &[sb, sb, sb, sb, sb, sb, ub],
                &[],
            )?,
            scan: ScanPass::new(ctx)?,
            plane_lut: None,
            batch_limit: None,
            triangle_batch_limit: None,
            triangle_base: 0,
        })
    }

    /// Makes the plane look-up texture of `light` current: builds it unless
    /// the last one was built from the same normalized samples and
    /// resolution. Returns whether it was built and the build's timing.
    fn ensure_plane_lut(
        &mut self,
        ctx: &GpuContext,
        light: &SoftLight,
    ) -> Result<(bool, Vec<PassTiming>)> {
        let (centre, radius) = light.bounds();
        let ys = crate::cpu::soft::normalized_samples(&light.samples, centre, radius);
        let mut key: Vec<u32> = ys
            .iter()
            .flat_map(|y| y.to_array().map(f32::to_bits))
            .collect();
        key.push(light.lut_resolution);
        if self.plane_lut.as_ref().is_some_and(|l| l.key == key) {
            return Ok((false, Vec::new()));
        }
        let res = light.lut_resolution as u64;
        let texels = res.pow(3) * light.samples.len().div_ceil(128) as u64;
        let max_texels = ctx.info().limits.max_texel_buffer_elements as u64;
        if texels > max_texels {
            return Err(Error::InvalidInput(format!(
                "a {res}³ look-up texture for {} light samples has {texels} texels; this device binds at most {max_texels} (lower lut_resolution or the samples)",
                light.samples.len()
            )));
        }
        self.plane_lut = None; // the old table is freed before the new one is made
        let buffer = ctx.create_buffer(BufferDesc::storage("plane_lut", 16 * texels))?;
        let mut d = BufferDesc::storage("normalized_light_samples", 16 * MAX_SOFT_SAMPLES as u64);
        d.usage |= vk::BufferUsageFlags::UNIFORM_BUFFER;
        let ys_ubo = ctx.create_buffer(d)?;
        let v: Vec<[f32; 4]> = ys.iter().map(|y| [y.x, y.y, y.z, 0.0]).collect();
        ctx.upload_staged(&ys_ubo, 0, &v)?;
        let push = HardPush {
            soft: [0, light.samples.len() as u32, light.lut_resolution, 0],
            ..Default::default()
        };
        let mut prof = Profiler::new(ctx, 2)?;
        let mut walls = walls_wanted(ctx).then(Vec::new);
        let mut rec = ctx.begin()?;
        timed(ctx, &mut prof, &mut rec, &mut walls, "lut_build", |rec| {
            rec.dispatch(
                &self.lut_build,
                &[
                    Binding::storage_texel(&buffer, RGBA32UI),
                    Binding::uniform(&ys_ubo),
                ],
                bytemuck::bytes_of(&push),
                groups(res.pow(3) as u32),
            )?;
            rec.barrier(Barrier::ComputeToHost);
            Ok(())
        })?;
        ctx.submit_and_wait(rec)?;
        ctx.check_validation()?;
        let timings = match walls {
            Some(w) => w,
            None => prof.results()?,
        };
        self.plane_lut = Some(PlaneLut { key, buffer });
        Ok((true, timings))
    }

    /// The plane look-up texture of `light` as the GPU builds it (for the
    /// CPU twin's test): per texel, then per 128-sample block, the bits of
    /// the samples behind the texel's plane ([`crate::cpu::soft::build_lut`]).
    pub fn plane_lut_bits(&mut self, ctx: &GpuContext, light: &SoftLight) -> Result<Vec<[u32; 4]>> {
        self.ensure_plane_lut(ctx, light)?;
        let lut = self
            .plane_lut
            .as_ref()
            .expect("ensure_plane_lut keeps a table");
        let words: Vec<u32> =
            ctx.read_buffer_staged(&lut.buffer, 0, (lut.buffer.size() / 4) as usize)?;
        Ok(words
            .chunks_exact(4)
            .map(|w| [w[0], w[1], w[2], w[3]])
            .collect())
    }

    /// Limits the view samples per run (tests: forces the batched path that
    /// large runs take); `None` lifts the limit.
    pub fn set_batch_limit(&mut self, limit: Option<usize>) {
        self.batch_limit = limit;
    }

    /// Limits the triangles per run (tests: forces the batched path that
    /// scenes of millions of triangles take); `None` lifts the limit.
    pub fn set_triangle_batch_limit(&mut self, limit: Option<usize>) {
        self.triangle_batch_limit = limit;
    }

    /// [`HardShadowPass::run_on`] over the `nt` triangles in batches of at
    /// most `batch`: each batch a complete run over every view sample, its
    /// triangles named by global id; a light sample is visible when no
    /// batch blocks it (the AND of the batches' results).
    #[allow(clippy::too_many_arguments)]
    fn run_triangle_batched(
        &mut self,
        ctx: &GpuContext,
        samples_buf: &Buffer,
        n: usize,
        triangles_buf: &Buffer,
        nt: usize,
        batch: usize,
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Result<HardShadowOutput> {
        let mut out: Option<HardShadowOutput> = None;
        // Nested batches (a batch whose binned pairs still pass the limit)
        // count from their parent's first triangle.
        let base = self.triangle_base;
        for start in (0..nt).step_by(batch) {
            let len = batch.min(nt - start);
            let part = copy_range(ctx, triangles_buf, "triangle_batch", 48, start, len)?;
            self.triangle_base = base + start as u32;
            let o = self.run_on(ctx, samples_buf, n, &part, len, light, resolution, soft);
            self.triangle_base = base;
            let o = o?;
            out = Some(match out {
                None => o,
                Some(mut acc) => {
                    for (a, b) in acc.lit.iter_mut().zip(&o.lit) {
                        *a = match (*a, *b) {
                            (Some(x), Some(y)) => Some(x && y),
                            _ => None,
                        };
                    }
                    for (a, b) in acc.counters.iter_mut().zip(o.counters) {
                        *a = a.saturating_add(b);
                    }
                    acc.timings.extend(o.timings);
                    acc.buffer_bytes = acc.buffer_bytes.max(o.buffer_bytes);
                    if let (Some(a), Some(b), Some(sl)) = (acc.soft.as_mut(), o.soft, soft) {
                        let words = a.mask_words;
                        for (x, y) in a.visible.iter_mut().zip(&b.visible) {
                            *x &= *y;
                        }
                        // Visibility = visible light samples / light samples
                        // (soft_resolve.comp), of the combined masks.
                        let count = sl.samples.len() as f32;
                        for (i, v) in a.visibility.iter_mut().enumerate() {
                            if v.is_some() {
                                let mask = &a.visible[i * words..(i + 1) * words];
                                let bits: u32 = mask.iter().map(|w| w.count_ones()).sum();
                                *v = Some(bits as f32 / count);
                            }
                        }
                        a.lut_built |= b.lut_built;
                    }
                    acc
                }
            });
        }
        out.ok_or_else(|| Error::InvalidInput("no triangles".into()))
    }

    /// [`HardShadowPass::run_on`] over `n` view samples in batches of at
    /// most `batch`, each copied into its own buffer; the outputs are
    /// concatenated (counters summed, list lengths of the longest batch).
    #[allow(clippy::too_many_arguments)]
    fn run_batched(
        &mut self,
        ctx: &GpuContext,
        samples_buf: &Buffer,
        n: usize,
        batch: usize,
        triangles_buf: &Buffer,
        nt: usize,
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Result<HardShadowOutput> {
        let mut out: Option<HardShadowOutput> = None;
        for start in (0..n).step_by(batch) {
            let len = batch.min(n - start);
            let part = copy_range(ctx, samples_buf, "view_sample_batch", 32, start, len)?;
            let o = self.run_on(ctx, &part, len, triangles_buf, nt, light, resolution, soft)?;
            out = Some(match out {
                None => {
                    let mut first = o;
                    reserve_results(&mut first, n)?;
                    first
                }
                Some(mut acc) => {
                    acc.lit.extend(o.lit);
                    for (a, b) in acc.counters.iter_mut().zip(o.counters) {
                        *a = a.saturating_add(b);
                    }
                    let longest = |l: &[u32]| l.iter().copied().max().unwrap_or(0);
                    if longest(&o.list_lengths) > longest(&acc.list_lengths) {
                        acc.list_lengths = o.list_lengths;
                    }
                    acc.timings.extend(o.timings);
                    acc.buffer_bytes = acc.buffer_bytes.max(o.buffer_bytes);
                    if let (Some(a), Some(b)) = (acc.soft.as_mut(), o.soft) {
                        a.visibility.extend(b.visibility);
                        a.visible.extend(b.visible);
                        a.lut_built |= b.lut_built;
                    }
                    acc
                }
            });
        }
        out.ok_or_else(|| Error::InvalidInput("no view samples".into()))
    }
}

/// A new buffer holding elements `start..start + len` (of `stride` bytes)
/// of `buf`: one batch's inputs.
fn copy_range(
    ctx: &GpuContext,
    buf: &Buffer,
    name: &str,
    stride: u64,
    start: usize,
    len: usize,
) -> Result<Buffer> {
    let part = ctx.create_buffer(BufferDesc::storage(name, stride * len as u64))?;
    let mut rec = ctx.begin()?;
    rec.copy_buffer(
        buf.slice(stride * start as u64, stride * len as u64)?,
        &part,
        0,
    )?;
    rec.barrier(Barrier::TransferToCompute);
    ctx.submit_and_wait(rec)?;
    Ok(part)
}

/// Reserves the host memory for the results of `n` view samples in `out`
/// (the first batch's), so that a request too large for this machine is a
/// clear error before the work, not an abort after it.
fn reserve_results(out: &mut HardShadowOutput, n: usize) -> Result<()> {
    let more = n.saturating_sub(out.lit.len());
    let too_large = |what: &str, bytes: u128| {
        Error::InvalidInput(format!(
            "the results of {n} view samples ({what}, {:.1} GiB) do not fit in host memory; \
             pass fewer view samples per call",
            bytes as f64 / (1u64 << 30) as f64
        ))
    };
    out.lit
        .try_reserve_exact(more)
        .map_err(|_| too_large("lit flags", 2 * n as u128))?;
    if let Some(so) = out.soft.as_mut() {
        so.visibility
            .try_reserve_exact(more)
            .map_err(|_| too_large("visibility", 8 * n as u128))?;
        let words = so.mask_words * more;
        so.visible
            .try_reserve_exact(words)
            .map_err(|_| too_large("light-sample masks", 4 * (so.mask_words * n) as u128))?;
    }
    Ok(())
}

impl HardShadowPass {
    /// Computes hard-shadow visibility of `view_samples` (camera-relative)
    /// from `light` with the scene's `triangles` over `resolution`² light
    /// texels per face (uploads both, then [`HardShadowPass::run_on`]).
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        view_samples: &[GpuViewSample],
        triangles: &[GpuTriangle],
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Result<HardShadowOutput> {
        let samples_buf = ctx.create_buffer(BufferDesc::storage(
            "view_samples",
            (32 * view_samples.len() as u64).max(16),
        ))?;
        let triangles_buf = ctx.create_buffer(BufferDesc::storage(
            "triangles",
            (48 * triangles.len() as u64).max(16),
        ))?;
        if !view_samples.is_empty() {
            ctx.upload_staged(&samples_buf, 0, view_samples)?;
        }
        if !triangles.is_empty() {
            ctx.upload_staged(&triangles_buf, 0, triangles)?;
        }
        self.run_on(
            ctx,
            &samples_buf,
            view_samples.len(),
            &triangles_buf,
            triangles.len(),
            light,
            resolution,
            soft,
        )
    }

    /// [`HardShadowPass::run`] on view samples and triangles already on the
    /// GPU (e.g. the view-sample pass's output): `n` samples, `nt` triangles.
    /// With `soft`, the same passes compute soft shadows (paper §4) of that
    /// light, seen from `light` (a point light at the samples' centre; see
    /// [`SoftLight::bounds`]): influence regions instead of projections,
    /// light-sample bitmasks instead of one bit.
    #[allow(clippy::too_many_arguments)]
    pub fn run_on(
        &mut self,
        ctx: &GpuContext,
        samples_buf: &Buffer,
        n: usize,
        triangles_buf: &Buffer,
        nt: usize,
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Result<HardShadowOutput> {
        let faces = light.face_count() as u32;
        if let Some(sl) = soft {
            if sl.samples.is_empty() || sl.samples.len() > MAX_SOFT_SAMPLES {
                return Err(Error::InvalidInput(format!(
                    "soft shadows take 1 to {MAX_SOFT_SAMPLES} light samples, got {}",
                    sl.samples.len()
                )));
            }
            if !sl.samples.iter().all(|s| s.is_finite()) {
                return Err(Error::InvalidInput("a light sample is not finite".into()));
            }
            if !(3..=64).contains(&sl.polygon_degree) {
                return Err(Error::InvalidInput(format!(
                    "the influence polygon needs 3 to 64 corners, got {}",
                    sl.polygon_degree
                )));
            }
            if !sl.exact && !(2..=512).contains(&sl.lut_resolution) {
                return Err(Error::InvalidInput(format!(
                    "lut_resolution must be in 2..=512, got {}",
                    sl.lut_resolution
                )));
            }
            if !matches!(light, LightView::Point { .. }) {
                return Err(Error::InvalidInput(
                    "soft shadows are seen from a point (the light's centre)".into(),
                ));
            }
        }
        if resolution == 0 || resolution > 16384 {
            return Err(Error::InvalidInput(format!(
                "light_texels must be in 1..=16384, got {resolution}"
            )));
        }
        // Texel lists in tile-major order (texel_index in hard_common.glsl):
        // every tile has 64 counters, partial edge tiles too.
        let tiles_per_row = resolution.div_ceil(TILE);
        let texels = faces as u64 * (tiles_per_row as u64 * TILE as u64).pow(2);
        if texels + 1 > self.scan.max_len() as u64 {
            return Err(Error::InvalidInput(format!(
                "{faces} light face(s) of {resolution}² texels need {texels} list counters; this device scans at most {} (lower light_texels)",
                self.scan.max_len()
            )));
        }
        let n =
            u32::try_from(n).map_err(|_| Error::InvalidInput("too many view samples".into()))?;
        let nt = u32::try_from(nt).map_err(|_| Error::InvalidInput("too many triangles".into()))?;
        if samples_buf.size() < 32 * n as u64 || triangles_buf.size() < 48 * nt as u64 {
            return Err(Error::InvalidInput(
                "view-sample or triangle buffer smaller than its count".into(),
            ));
        }
        // View samples whose buffers (the samples, 32 B; the masks, 16 B per
        // block) would pass the device's binding limit run in batches: each
        // batch is a complete run (lists, regions, occlusion) over all
        // triangles, so the results are the same as in one run.
        let max_range = ctx.info().limits.max_storage_buffer_range as u64;
        let words = soft.map_or(0, |sl| sl.samples.len().div_ceil(128) * 4) as u64;
        let per_sample = 32.max(4 * words);
        let batch = batch_len(max_range, per_sample, self.batch_limit);
        if n as usize > batch {
            return self.run_batched(
                ctx,
                samples_buf,
                n as usize,
                batch,
                triangles_buf,
                nt as usize,
                light,
                resolution,
                soft,
            );
        }
        // Triangles whose caster pairs (64 B per face) or planes (80 B)
        // would pass the binding limit run in batches too.
        let per_triangle = (64 * faces as u64).max(80);
        let triangle_batch = batch_len(max_range, per_triangle, self.triangle_batch_limit);
        if nt as usize > triangle_batch {
            return self.run_triangle_batched(
                ctx,
                samples_buf,
                n as usize,
                triangles_buf,
                nt as usize,
                triangle_batch,
                light,
                resolution,
                soft,
            );
        }
        let tiles_per_face = tiles_per_row * tiles_per_row;
        let tiles = faces * tiles_per_face;
        let pair_capacity = nt.saturating_mul(faces);
        let (origin, kind, direction, (r, u)) = match light {
            LightView::Point { position } => (
                *position,
                LIGHT_KIND_POINT,
                glam::Vec3::ZERO,
                (glam::Vec3::ZERO, glam::Vec3::ZERO),
            ),
            LightView::Directional { direction } => {
                let (r, u, _) = light.basis(0);
                (glam::Vec3::ZERO, LIGHT_KIND_DIRECTIONAL, *direction, (r, u))
            }
        };
        let push = HardPush {
            origin: [origin.x, origin.y, origin.z, f32::from_bits(kind)],
            direction: [direction.x, direction.y, direction.z, 0.0],
            sizes: [n, nt, resolution, faces],
            more: [pair_capacity, tiles_per_row, tiles_per_face, 0],
            dir_right: [r.x, r.y, r.z, 0.0],
            dir_up: [u.x, u.y, u.z, 0.0],
            soft: match soft {
                Some(sl) => [
                    0,
                    sl.samples.len() as u32,
                    sl.lut_resolution,
                    if sl.exact { 1 } else { 0 },
                ],
                None => [0; 4],
            },
            soft_light: match soft {
                Some(sl) => [
                    sl.bounds().1,
                    sl.polygon_degree as f32,
                    f32::from_bits(self.triangle_base),
                    0.0,
                ],
                None => [0.0, 0.0, f32::from_bits(self.triangle_base), 0.0],
            },
        };
        let pc = bytemuck::bytes_of(&push);

        let mut bytes = samples_buf.size() + triangles_buf.size();
        let mut buffer = |name: &str, size: u64| -> Result<Buffer> {
            let size = size.max(16);
            bytes += size;
            ctx.create_buffer(BufferDesc::storage(name, size))
        };
        let fit = buffer("light_fit_keys", 4 * 8 * 6)?;
        // Read alike by every invocation: bound as a uniform buffer where read.
        let mut faces_desc = BufferDesc::storage("light_faces", 128 * 6);
        faces_desc.usage |= vk::BufferUsageFlags::UNIFORM_BUFFER;
        let faces_buf = ctx.create_buffer(faces_desc)?;
        let counts = buffer("texel_counts", 4 * texels)?;
        let offsets = buffer("texel_offsets", 4 * (texels + 1))?;
        let sample_texel = buffer("sample_texel", 4 * n as u64)?;
        let sample_slot = buffer("sample_slot", 4 * n as u64)?;
        let list_samples = buffer("light_texel_lists", 16 * n as u64)?;
        let planes = buffer("caster_planes", 80 * nt as u64)?;
        let pairs = buffer("caster_faces", 64 * pair_capacity as u64)?;
        let counters = buffer("counters", 4 * counter::COUNT as u64)?;
        let clip_items = buffer("caster_clip_items", 8 * nt as u64)?;
        let mut args_desc = BufferDesc::storage("caster_clip_args", 16);
        args_desc.usage |= vk::BufferUsageFlags::INDIRECT_BUFFER;
        let clip_args = ctx.create_buffer(args_desc)?;
        let tile_counts = buffer("tile_counts", 4 * tiles as u64)?;
        let tile_offsets = buffer("tile_offsets", 4 * (tiles as u64 + 1))?;
        let tile_max_len = buffer("tile_max_len", 4 * tiles as u64)?;
        let tile_units = buffer("tile_units", 4 * tiles as u64)?;
        let unit_offsets = buffer("unit_offsets", 4 * (tiles as u64 + 1))?;
        let shadowed = buffer("shadowed", 4 * n as u64)?;
        let result = buffer("result", 4 * n as u64)?;
        // Soft shadows: blocked bits per list slot, visible bits per view
        // sample (4 words per 128-sample block), the light samples, the LUT.
        let words = soft.map_or(0, |sl| sl.samples.len().div_ceil(128) * 4) as u64;
        let masks = buffer("blocked_masks", 4 * words * n as u64)?;
        let visible = buffer("visible_masks", 4 * words * n as u64)?;
        let light_ubo = {
            let mut d = BufferDesc::storage("light_samples", 16 * MAX_SOFT_SAMPLES as u64);
            d.usage |= vk::BufferUsageFlags::UNIFORM_BUFFER;
            let b = ctx.create_buffer(d)?;
            if let Some(sl) = soft {
                let v: Vec<[f32; 4]> = sl.samples.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect();
                ctx.upload_staged(&b, 0, &v)?;
            }
            b
        };
        // LUT mode: the plane look-up texture of every block, cached across
        // frames (it depends only on the normalized samples and resolution).
        let lut_mode = soft.filter(|sl| !sl.exact);
        let (lut_built, lut_timings) = match lut_mode {
            Some(sl) => self.ensure_plane_lut(ctx, sl)?,
            None => (false, Vec::new()),
        };
        let dummy_lut = buffer("plane_lut_unused", 16)?;
        let lut = match (lut_mode, &self.plane_lut) {
            (Some(_), Some(l)) => &l.buffer,
            _ => &dummy_lut,
        };
        let lut_bytes = lut_mode
            .and(self.plane_lut.as_ref())
            .map_or(0, |l| l.buffer.size());

        let mut fit_init = [0u32; 48];
        for f in 0..6 {
            fit_init[f * 8] = u32::MAX;
            fit_init[f * 8 + 1] = u32::MAX;
        }
        ctx.upload_staged(&fit, 0, &fit_init)?;

        // ---- Submission 1: lists and caster setup, tile counts.
        let mut walls = walls_wanted(ctx).then(Vec::new);
        let mut prof1 = Profiler::new(ctx, 16)?;
        let mut rec = ctx.begin()?;
        rec.fill_buffer(counts.whole(), 0)?;
        rec.fill_buffer(counters.whole(), 0)?;
        rec.fill_buffer(tile_counts.whole(), 0)?;
        rec.fill_buffer(tile_max_len.whole(), 0)?;
        rec.barrier(Barrier::TransferToCompute);
        timed(ctx, &mut prof1, &mut rec, &mut walls, "light_fit", |rec| {
            rec.dispatch(&self.light_fit, &[s(samples_buf), s(&fit)], pc, groups(n))?;
            rec.barrier(Barrier::ComputeToCompute);
            rec.dispatch(
                &self.light_fit_finalize,
                &[s(&fit), s(&faces_buf)],
                pc,
                [1, 1, 1],
            )?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })?;
        timed(
            ctx,
            &mut prof1,
            &mut rec,
            &mut walls,
            "texel_count",
            |rec| {
                rec.dispatch(
                    &self.texel_count,
                    &[
                        s(samples_buf),
                        Binding::uniform(&faces_buf),
                        s(&counts),
                        s(&sample_texel),
                        s(&sample_slot),
                        s(&tile_max_len),
                    ],
                    pc,
                    groups(n),
                )
            },
        )?;
        let scan = &mut self.scan;
        timed(ctx, &mut prof1, &mut rec, &mut walls, "texel_scan", |rec| {
            scan.record(rec, counts.whole(), offsets.whole(), texels as u32)?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })?;
        timed(
            ctx,
            &mut prof1,
            &mut rec,
            &mut walls,
            "texel_scatter",
            |rec| {
                rec.dispatch(
                    &self.texel_scatter,
                    &[
                        s(samples_buf),
                        s(&offsets),
                        s(&sample_texel),
                        s(&sample_slot),
                        s(&list_samples),
                    ],
                    pc,
                    groups(n),
                )
            },
        )?;
        timed(
            ctx,
            &mut prof1,
            &mut rec,
            &mut walls,
            "caster_setup",
            |rec| {
                let casters = [
                    Binding::uniform_texel(triangles_buf, RGBA32UI),
                    Binding::uniform(&faces_buf),
                    s(&planes),
                    s(&pairs),
                    s(&counters),
                    s(&clip_items),
                ];
                rec.dispatch(&self.caster_setup, &casters, pc, groups(nt))?;
                rec.barrier(Barrier::ComputeToCompute);
                // The few projections that cross a face's window pyramid:
                // clipped by one invocation each (indirect dispatch).
                rec.dispatch(
                    &self.caster_clip_args,
                    &[s(&counters), s(&clip_args)],
                    pc,
                    [1, 1, 1],
                )?;
                rec.barrier(Barrier::ComputeToIndirect);
                rec.dispatch_indirect(&self.caster_clip, &casters, pc, &clip_args)?;
                rec.barrier(Barrier::ComputeToCompute);
                Ok(())
            },
        )?;
        timed(
            ctx,
            &mut prof1,
            &mut rec,
            &mut walls,
            "tile_bin_count",
            |rec| {
                rec.dispatch(
                    &self.tile_count,
                    &[
                        s(&pairs),
                        s(&counters),
                        s(&tile_counts),
                        s(&tile_offsets),
                        s(&tile_offsets),
                        s(&tile_max_len),
                    ],
                    pc,
                    groups(pair_capacity),
                )?;
                rec.barrier(Barrier::ComputeToCompute);
                let (units_pipeline, per_tile) = match soft {
                    Some(_) => (&self.tile_units_soft, &offsets),
                    None => (&self.tile_units, &tile_max_len),
                };
                rec.dispatch(
                    units_pipeline,
                    &[s(&tile_counts), s(per_tile), s(&tile_units)],
                    pc,
                    groups(tiles),
                )
            },
        )?;
        timed(ctx, &mut prof1, &mut rec, &mut walls, "tile_scan", |rec| {
            scan.record(rec, tile_counts.whole(), tile_offsets.whole(), tiles)?;
            scan.record(rec, tile_units.whole(), unit_offsets.whole(), tiles)?;
            rec.barrier(Barrier::ComputeToHost);
            Ok(())
        })?;
        ctx.submit_and_wait(rec)?;
        let pairs_total: Vec<u32> = ctx.read_buffer_staged(&tile_offsets, 4 * tiles as u64, 1)?;
        let pairs_total = pairs_total[0];
        let units: Vec<u32> = ctx.read_buffer_staged(&unit_offsets, 4 * tiles as u64, 1)?;
        let units = units[0];
        // The binned pairs (4 B per (pair, tile)) are known only now: past
        // the binding limit, the triangles run again in batches small
        // enough (regions of lights with extent cover many tiles).
        let binned_bytes = 4 * pairs_total as u64;
        if binned_bytes > max_range && nt > 1 {
            let batch = (nt as u64 * max_range / binned_bytes / 2).max(1) as usize;
            return self.run_triangle_batched(
                ctx,
                samples_buf,
                n as usize,
                triangles_buf,
                nt as usize,
                batch,
                light,
                resolution,
                soft,
            );
        }
        let push2 = HardPush {
            more: [pair_capacity, tiles_per_row, tiles_per_face, units],
            ..push
        };
        let pc2 = bytemuck::bytes_of(&push2);

        // ---- Submission 2: tile lists, occlusion, resolve. The pair total
        // is read back first so that the tile-pair array is sized exactly.
        let tile_pairs = buffer("tile_pairs", 4 * pairs_total as u64)?;
        let mut prof2 = Profiler::new(ctx, 4 + 8 * MAX_SOFT_SAMPLES.div_ceil(128) as u32)?;
        let mut rec = ctx.begin()?;
        rec.fill_buffer(tile_counts.whole(), 0)?;
        rec.fill_buffer(shadowed.whole(), 0)?;
        rec.barrier(Barrier::TransferToCompute);
        timed(
            ctx,
            &mut prof2,
            &mut rec,
            &mut walls,
            "tile_bin_scatter",
            |rec| {
                rec.dispatch(
                    &self.tile_scatter,
                    &[
                        s(&pairs),
                        s(&counters),
                        s(&tile_counts),
                        s(&tile_offsets),
                        s(&tile_pairs),
                        s(&tile_max_len),
                    ],
                    pc,
                    groups(pair_capacity),
                )?;
                rec.barrier(Barrier::ComputeToCompute);
                Ok(())
            },
        )?;
        if let Some(sl) = soft {
            rec.fill_buffer(masks.whole(), 0)?;
            rec.barrier(Barrier::TransferToCompute);
            let blocks = sl.samples.len().div_ceil(128) as u32;
            let occlusion = if sl.exact {
                &self.occlusion_exact
            } else {
                &self.occlusion_lut[blocks as usize - 1]
            };
            // LUT mode: one pass for every block (one look-up index serves
            // all); exact mode: one pass per 128-sample block.
            let passes = if sl.exact { blocks } else { 1 };
            for block in 0..passes {
                let push_b = HardPush {
                    soft: [block, push.soft[1], push.soft[2], push.soft[3]],
                    ..push2
                };
                let pcb = bytemuck::bytes_of(&push_b);
                timed(ctx, &mut prof2, &mut rec, &mut walls, "occlusion", |rec| {
                    rec.dispatch(
                        occlusion,
                        &[
                            Binding::uniform_texel(&pairs, RGBA32UI),
                            Binding::uniform_texel(triangles_buf, RGBA32UI),
                            s(&tile_offsets),
                            Binding::uniform_texel(&tile_pairs, vk::Format::R32_UINT),
                            s(&counts),
                            s(&offsets),
                            Binding::uniform_texel(&list_samples, RGBA32UI),
                            s(&masks),
                            s(&counters),
                            s(&unit_offsets),
                            Binding::uniform(&light_ubo),
                            Binding::uniform_texel(lut, RGBA32UI),
                        ],
                        pcb,
                        groups_2d(units.max(1)),
                    )?;
                    rec.barrier(Barrier::ComputeToCompute);
                    Ok(())
                })?;
            }
            timed(
                ctx,
                &mut prof2,
                &mut rec,
                &mut walls,
                "soft_resolve",
                |rec| {
                    rec.dispatch(
                        &self.soft_resolve,
                        &[
                            s(samples_buf),
                            s(&sample_texel),
                            s(&sample_slot),
                            s(&masks),
                            s(&visible),
                            s(&result),
                            Binding::uniform(&light_ubo),
                        ],
                        pc,
                        groups(n),
                    )?;
                    rec.barrier(Barrier::ComputeToHost);
                    Ok(())
                },
            )?;
        } else {
            timed(ctx, &mut prof2, &mut rec, &mut walls, "occlusion", |rec| {
                rec.dispatch(
                    &self.occlusion,
                    &[
                        Binding::uniform_texel(&pairs, RGBA32UI),
                        Binding::uniform_texel(&planes, RGBA32UI),
                        s(&tile_offsets),
                        Binding::uniform_texel(&tile_pairs, vk::Format::R32_UINT),
                        s(&counts),
                        s(&offsets),
                        Binding::uniform_texel(&list_samples, RGBA32UI),
                        s(&shadowed),
                        s(&counters),
                        s(&unit_offsets),
                    ],
                    pc2,
                    groups_2d(units.max(1)),
                )?;
                rec.barrier(Barrier::ComputeToCompute);
                Ok(())
            })?;
            timed(ctx, &mut prof2, &mut rec, &mut walls, "resolve", |rec| {
                rec.dispatch(
                    &self.resolve,
                    &[s(&sample_texel), s(&sample_slot), s(&shadowed), s(&result)],
                    pc,
                    groups(n),
                )?;
                rec.barrier(Barrier::ComputeToHost);
                Ok(())
            })?;
        }
        ctx.submit_and_wait(rec)?;
        ctx.check_validation()?;

        let result: Vec<u32> = ctx.read_buffer_staged(&result, 0, n as usize)?;
        let soft_out = match soft {
            Some(_) => {
                let vis: Vec<u32> = if words > 0 && n > 0 {
                    ctx.read_buffer_staged(&visible, 0, (words * n as u64) as usize)?
                } else {
                    Vec::new()
                };
                Some(SoftOutput {
                    visibility: result
                        .iter()
                        .map(|&r| {
                            let v = f32::from_bits(r);
                            (v >= 0.0).then_some(v)
                        })
                        .collect(),
                    visible: vis,
                    mask_words: words as usize,
                    lut_built,
                })
            }
            None => None,
        };
        let c: Vec<u32> = ctx.read_buffer_staged(&counters, 0, counter::COUNT)?;
        let list_lengths: Vec<u32> = ctx.read_buffer_staged(&counts, 0, texels as usize)?;
        let mut timings = lut_timings;
        match walls {
            Some(w) => timings.extend(w),
            None => {
                timings.extend(prof1.results()?);
                timings.extend(prof2.results()?);
            }
        }
        let mut counters_out = [0u32; counter::COUNT];
        counters_out.copy_from_slice(&c);
        Ok(HardShadowOutput {
            lit: result
                .iter()
                .map(|&r| (r & 2 != 0).then_some(r & 1 != 0))
                .collect(),
            counters: counters_out,
            list_lengths,
            timings,
            buffer_bytes: bytes + lut_bytes,
            soft: soft_out,
        })
    }
}

fn s(b: &Buffer) -> Binding<'_> {
    Binding::storage(b)
}

/// Whether passes are timed on the host, each as its own submission:
/// lavapipe's timestamps do not bracket the passes of one command buffer
/// (measured: 11 ms reported for a 1.4 s run). AFS_PROFILE_WALL=1 / 0 forces
/// either way.
fn walls_wanted(ctx: &GpuContext) -> bool {
    match std::env::var("AFS_PROFILE_WALL").as_deref() {
        Ok("1") => true,
        Ok("0") => false,
        _ => ctx.info().is_cpu(),
    }
}

/// Records `f` between the profiler's timestamps for `name`.
fn timed(
    ctx: &GpuContext,
    prof: &mut Profiler,
    rec: &mut CommandRecorder,
    walls: &mut Option<Vec<PassTiming>>,
    name: &str,
    f: impl FnOnce(&mut CommandRecorder) -> Result<()>,
) -> Result<()> {
    match walls {
        // Wall-clock profiling (AFS_PROFILE_WALL=1): every pass is its own
        // submission, timed on the host. Slower overall, but it does not
        // depend on the device's timestamps.
        Some(list) => {
            let t = std::time::Instant::now();
            f(rec)?;
            let done = std::mem::replace(rec, ctx.begin()?);
            ctx.submit_and_wait(done)?;
            list.push(PassTiming {
                name: name.to_string(),
                ms: Some(t.elapsed().as_secs_f64() * 1e3),
            });
            Ok(())
        }
        None => {
            let scope = prof.begin(rec, name)?;
            f(rec)?;
            prof.end(rec, scope);
            Ok(())
        }
    }
}

/// Camera-relative GPU view samples and triangles from CPU data.
pub fn gpu_inputs(
    samples: &[Option<(glam::Vec3, glam::Vec3, u32)>],
    triangles: &[([glam::Vec3; 3], bool)],
) -> (Vec<GpuViewSample>, Vec<GpuTriangle>) {
    use crate::gpu::shared::{TRIANGLE_CLOSED, VIEW_SAMPLE_VALID};
    let vs = samples
        .iter()
        .map(|s| match s {
            Some((p, n, t)) => GpuViewSample::new(*p, *t, *n, VIEW_SAMPLE_VALID),
            None => GpuViewSample::default(),
        })
        .collect();
    let ts = triangles
        .iter()
        .map(|(v, closed)| GpuTriangle::new(*v, if *closed { TRIANGLE_CLOSED } else { 0 }, 0))
        .collect();
    (vs, ts)
}

/// Items per batch: as many as fit in `max_range` bytes at `per_item`
/// bytes each, at most `limit` (tests force small batches), at least one.
fn batch_len(max_range: u64, per_item: u64, limit: Option<usize>) -> usize {
    ((max_range / per_item) as usize)
        .min(limit.unwrap_or(usize::MAX))
        .max(1)
}
