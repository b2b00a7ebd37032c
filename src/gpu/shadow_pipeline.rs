//! The shadow passes of a frame after the view samples, for one light at a
//! time, hard (paper §3) or soft (§4): [`ShadowPipeline`] checks its inputs,
//! splits runs too large for one binding into [`batches`](crate::gpu::batches)
//! and runs [`LightPasses::run`], the passes in order.

use crate::cpu::alpha::AlphaTables;
use crate::cpu::light_view::LightView;
use crate::gpu::alpha::{AlphaBuffers, AlphaInputs};
use crate::gpu::batches::{Batches, RunOf};
use crate::gpu::light_frame::LightInputs;
use crate::gpu::light_passes::{LightPasses, ShadowOutput};
use crate::gpu::shared::{GpuTriangle, GpuViewSample};
use crate::gpu::soft_light::SoftLight;
use crate::vulkan::{Buffer, BufferSlice, CommandRecorder, GpuContext, GrowBuffer};
use crate::{Error, Result};

/// The shadow passes of every light: pipelines made once, buffers kept and
/// grown across frames (a second frame of the same size allocates nothing).
pub struct ShadowPipeline {
    passes: LightPasses,
    batches: Batches,
    /// View samples and triangles uploaded by [`ShadowPipeline::run`].
    uploaded_samples: GrowBuffer,
    uploaded_triangles: GrowBuffer,
    /// The alpha-tested casters' tables ([`ShadowPipeline::set_alpha`]).
    alpha: AlphaBuffers,
}

impl ShadowPipeline {
    /// Builds every pipeline.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        // No alpha-tested triangles until set_alpha says otherwise.
        let mut alpha = AlphaBuffers::new();
        alpha.upload(ctx, &AlphaTables::default())?;
        Ok(ShadowPipeline {
            passes: LightPasses::new(ctx)?,
            batches: Batches::new(),
            uploaded_samples: GrowBuffer::storage("view_samples"),
            uploaded_triangles: GrowBuffer::storage("triangles"),
            alpha,
        })
    }

    /// The alpha tests of the triangles the next runs take (their
    /// [`GpuTriangle`]s marked by [`crate::gpu::alpha::mark_alpha_triangles`]
    /// with the same tables); empty tables (as before the first call):
    /// every caster is opaque.
    pub fn set_alpha(&mut self, ctx: &GpuContext, tables: &AlphaTables) -> Result<()> {
        self.alpha.upload(ctx, tables)
    }

    /// The tables of the last [`ShadowPipeline::set_alpha`] (a placeholder
    /// without alpha-tested triangles) and whether there are any.
    pub fn alpha(&self) -> (AlphaInputs<'_>, bool) {
        (self.alpha.inputs(), self.alpha.present())
    }

    /// Shadows of `view_samples` (camera-relative) from `light` with the
    /// scene's `triangles` over `resolution`² light texels per face: uploads
    /// both, then [`ShadowPipeline::run_on`].
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        view_samples: &[GpuViewSample],
        triangles: &[GpuTriangle],
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Result<ShadowOutput> {
        let samples = self
            .uploaded_samples
            .get(ctx, 32 * view_samples.len() as u64)?;
        ctx.upload_staged(samples, 0, view_samples)?;
        let tris = self
            .uploaded_triangles
            .get(ctx, 48 * triangles.len() as u64)?;
        ctx.upload_staged(tris, 0, triangles)?;
        let inputs = LightInputs {
            samples: self.uploaded_samples.slice(),
            n: count(view_samples.len(), "view samples")?,
            triangles: self.uploaded_triangles.slice(),
            nt: count(triangles.len(), "triangles")?,
            triangle_base: 0,
            alpha: self.alpha.inputs(),
            alpha_casters: self.alpha.present(),
        };
        run_checked(
            &mut self.passes,
            &mut self.batches,
            ctx,
            &inputs,
            light,
            resolution,
            soft,
        )
    }

    /// [`ShadowPipeline::run`] on view samples and triangles already on the
    /// GPU (e.g. the view-sample pass's output): `n` samples, `nt` triangles.
    /// With `soft`, the same passes compute soft shadows of that light, seen
    /// from `light` (a point light at the samples' centre; see
    /// [`SoftLight::bounds`]).
    #[allow(clippy::too_many_arguments)]
    pub fn run_on(
        &mut self,
        ctx: &GpuContext,
        samples: &Buffer,
        n: usize,
        triangles: &Buffer,
        nt: usize,
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Result<ShadowOutput> {
        let (n, nt) = (count(n, "view samples")?, count(nt, "triangles")?);
        let inputs = whole_inputs(&self.alpha, (samples, n), (triangles, nt));
        run_checked(
            &mut self.passes,
            &mut self.batches,
            ctx,
            &inputs,
            light,
            resolution,
            soft,
        )
    }

    /// [`LightPasses::prepare_for_caller`] on `n` view samples in
    /// `samples` and `nt` triangles in `triangles` (with the alpha tables
    /// of [`ShadowPipeline::set_alpha`]).
    pub fn prepare_for_caller(
        &mut self,
        ctx: &GpuContext,
        (samples, n): (&Buffer, u32),
        (triangles, nt): (&Buffer, u32),
        light: (&LightView, u32, Option<&SoftLight>),
        pair_capacity: u32,
    ) -> Result<()> {
        let inputs = whole_inputs(&self.alpha, (samples, n), (triangles, nt));
        let frame = crate::gpu::light_frame::LightFrame::new(&inputs, light.0, light.1, light.2);
        self.passes.texel_lists.check(&frame)?;
        self.passes
            .prepare_for_caller(ctx, &inputs, light, pair_capacity)
    }

    /// [`LightPasses::record_for_caller`] on the inputs of
    /// [`ShadowPipeline::prepare_for_caller`]; the light's result stays in
    /// the resolve pass's buffer.
    pub fn record_for_caller(
        &mut self,
        ctx: &GpuContext,
        (cmd, status): (CommandRecorder, BufferSlice),
        (samples, n): (&Buffer, u32),
        (triangles, nt): (&Buffer, u32),
        light: (&LightView, u32, Option<&SoftLight>),
    ) -> Result<CommandRecorder> {
        let inputs = whole_inputs(&self.alpha, (samples, n), (triangles, nt));
        self.passes
            .record_for_caller(ctx, (cmd, status), &inputs, light)
    }

    /// The plane look-up texture of `light` as the GPU builds it (for the
    /// CPU twin's test; [`crate::cpu::plane_lut::build_lut`]).
    pub fn plane_lut_bits(&mut self, ctx: &GpuContext, light: &SoftLight) -> Result<Vec<[u32; 4]>> {
        let passes = &mut self.passes;
        passes.plane_lut.bits(ctx, &mut passes.clock, light)
    }

    /// Keeps look-up mode's tables in `dir` across runs (None: never; see
    /// [`crate::gpu::plane_lut::table_cache`]).
    pub fn set_table_cache(&mut self, dir: Option<std::path::PathBuf>) {
        self.passes.plane_lut.set_cache_dir(dir);
    }

    /// Whether tables read from the cache are mapped into device memory
    /// where the device allows it (see [`crate::gpu::plane_lut::PlaneLutPass::set_cache_mapping`]).
    pub fn set_table_mapping(&mut self, on: bool) {
        self.passes.plane_lut.set_cache_mapping(on);
    }

    /// The folder of [`ShadowPipeline::set_table_cache`], taken out.
    pub fn take_table_cache(&mut self) -> Option<std::path::PathBuf> {
        self.passes.plane_lut.take_cache_dir()
    }

    /// Limits the entries of look-up mode's unsure list per range of work
    /// units (tests: forces many ranges, and ranges that overflow and run
    /// again); `None` lifts it.
    pub fn set_unsure_list_limit(&mut self, limit: Option<u64>) {
        self.passes.soft_occlusion.list_limit = limit;
    }

    /// Turns the view-sample clusters on or off (on by default; the results
    /// are the same, off only to measure what they save).
    pub fn set_clusters(&mut self, on: bool) {
        self.passes.clusters.enabled = on;
    }

    /// Turns soft occlusion's wedge rule on or off (on by default; the
    /// results are the same, off only to measure what it saves).
    pub fn set_wedge_rule(&mut self, on: bool) {
        self.passes.soft_occlusion.set_wedge_rule(on);
    }

    /// Whether soft runs read the visible light-sample masks back
    /// ([`LightPasses::read_masks`]; on by default). Off, their
    /// `SoftOutput::visible` is empty and a frame skips the read-back.
    pub fn set_read_masks(&mut self, on: bool) {
        self.passes.read_masks = on;
    }

    /// Who is told of each batch of view samples when a run takes several
    /// (a frame's progress bar); `None`: nobody.
    pub fn set_batch_progress(&mut self, progress: Option<crate::gpu::batches::BatchProgress>) {
        self.batches.progress = progress;
    }

    /// Limits the view samples per run (tests: forces the batched path that
    /// large runs take); `None` lifts the limit.
    pub fn set_batch_limit(&mut self, limit: Option<usize>) {
        self.batches.view_sample_limit = limit;
    }

    /// Limits the triangles per run (tests: forces the batched path that
    /// scenes of millions of triangles take); `None` lifts the limit.
    pub fn set_triangle_batch_limit(&mut self, limit: Option<usize>) {
        self.batches.triangle_limit = limit;
    }

    /// The passes and the buffers they kept from the last run (for the
    /// tests that compare a pass's buffers with its CPU twin).
    pub fn passes(&self) -> &LightPasses {
        &self.passes
    }
}

/// The inputs of a run over the whole of `samples` (`n` view samples) and
/// `triangles` (`nt`), with `alpha`'s tables.
fn whole_inputs<'a>(
    alpha: &'a AlphaBuffers,
    (samples, n): (&'a Buffer, u32),
    (triangles, nt): (&'a Buffer, u32),
) -> LightInputs<'a> {
    LightInputs {
        samples: prefix(samples, 32 * n as u64),
        n,
        triangles: prefix(triangles, 48 * nt as u64),
        nt,
        triangle_base: 0,
        alpha: alpha.inputs(),
        alpha_casters: alpha.present(),
    }
}

/// The first `bytes` of `buffer` (at least 16, at most all of it): what
/// this frame's passes bind. A buffer kept from a larger frame (one whose
/// view samples ran in batches) may pass one binding's range as a whole.
fn prefix(buffer: &Buffer, bytes: u64) -> BufferSlice<'_> {
    let size = buffer.size();
    BufferSlice {
        buffer,
        offset: 0,
        size: bytes.max(16).min(size),
    }
}

fn count(n: usize, what: &str) -> Result<u32> {
    u32::try_from(n).map_err(|_| Error::InvalidInput(format!("too many {what}")))
}

/// Checks the run's inputs, then runs it in batches as needed.
fn run_checked(
    passes: &mut LightPasses,
    batches: &mut Batches,
    ctx: &GpuContext,
    inputs: &LightInputs,
    light: &LightView,
    resolution: u32,
    soft: Option<&SoftLight>,
) -> Result<ShadowOutput> {
    if let Some(sl) = soft {
        sl.validate()?;
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
    let frame = crate::gpu::light_frame::LightFrame::new(inputs, light, resolution, soft);
    passes.texel_lists.check(&frame)?;
    if inputs.samples.size < 32 * inputs.n as u64 || inputs.triangles.size < 48 * inputs.nt as u64 {
        return Err(Error::InvalidInput(
            "view-sample or triangle buffer smaller than its count".into(),
        ));
    }
    let of = RunOf {
        light,
        resolution,
        soft,
    };
    batches.run(passes, ctx, inputs, of)
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
