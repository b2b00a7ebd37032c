//! The engine's public API: [`Engine`] holds the Vulkan context and every
//! pass, made once and reused frame after frame. [`Engine::render`] (in
//! [`super::gpu_frame`]) renders a scene; [`Engine::hard_shadows`] and
//! [`Engine::soft_shadows`] compute the visibility of the caller's own view
//! samples.

use glam::DVec3;

use super::inputs::{light_view, soft_light, user_gpu_inputs};
use super::validate::{validate_gpu_inputs, validate_shadow_inputs};
use crate::cpu::alpha::{AlphaTables, AlphaTablesCache};
use crate::cpu::light_view::LightView;
use crate::gpu::alpha::mark_alpha_triangles;
use crate::gpu::shared::{GpuTriangle, GpuViewSample};
use crate::gpu::view_samples::ViewSamplePass;
use crate::gpu::visibility_out::VisibilityOutPass;
use crate::gpu::ShadowPipeline;
use crate::light::Light;
use crate::oracle::ViewSample;
use crate::scene::file::{LightTexels, ShadowSettings};
use crate::scene::Scene;
use crate::shade::ShadingCache;
use crate::stats::ShadowStats;
use crate::vulkan::{ContextOptions, ExternalDevice, GpuContext};
use crate::{Error, Result};

/// The engine: a Vulkan context and the compiled passes, reused frame after
/// frame, with the buffers they keep across frames.
pub struct Engine {
    pub(super) ctx: GpuContext,
    pub(super) view: ViewSamplePass,
    pub(super) shadows: ShadowPipeline,
    /// The shading normals of the last frame's scene.
    pub(super) shading: ShadingCache,
    /// The alpha tables of the last scene the shadow passes were given.
    pub(super) alpha: AlphaTablesCache,
    /// Counts the frames whose view samples and triangles the GPU buffers
    /// hold ([`super::FrameReuse`] reuses them only while it is its own).
    pub(super) frame_id: u64,
    /// A recorded frame's visibility into the caller's targets.
    pub(super) visibility_out: VisibilityOutPass,
    /// A recorded frame's status words, four per light (host-visible).
    pub(super) record_status: Option<crate::vulkan::Buffer>,
}

/// Hard-shadow visibility of a set of view samples for one light.
#[derive(Clone, Debug)]
pub struct HardShadowResult {
    /// Per view sample: `None` when it faces away from the light (unlit
    /// without a shadow test), else whether it is lit.
    pub lit: Vec<Option<bool>>,
    /// Statistics (counters and milliseconds per pass).
    pub stats: ShadowStats,
}

/// Soft-shadow visibility of a set of view samples for one light with extent.
#[derive(Clone, Debug)]
pub struct SoftShadowResult {
    /// Per view sample: the visible fraction of the light samples, `None`
    /// where not evaluated (no sample, or facing away from the whole light).
    pub visibility: Vec<Option<f32>>,
    /// Per view sample, its visible light samples: `mask_words` words, bit
    /// `j % 32` of word `j / 32` for light sample `j` of
    /// [`Light::light_samples`].
    pub visible: Vec<u32>,
    /// Words per view sample in `visible`.
    pub mask_words: usize,
    /// For a light with an emission texture, per view sample: the visible
    /// share of its red, green and blue emission
    /// ([`crate::light::channel_visibility`]); `None` for other lights.
    pub visibility_rgb: Option<Vec<[f32; 3]>>,
    /// Statistics (counters and milliseconds per pass).
    pub stats: ShadowStats,
}

impl Engine {
    /// Creates the Vulkan context (device from `options`, `AFS_DEVICE`, or
    /// the default choice) and sets up the passes; each pipeline is
    /// compiled at its first dispatch (all at once with
    /// [`ContextOptions::eager_pipelines`]).
    pub fn new(options: &ContextOptions) -> Result<Self> {
        Self::with_context(GpuContext::new(options)?)
    }

    /// An engine on a renderer's own Vulkan device: create the device with
    /// [`DeviceRequirements`](crate::vulkan::DeviceRequirements) merged in,
    /// then hand it over. Of `options` only the timeout applies. The engine
    /// destroys only what it made; drop it before the device.
    pub fn from_external(external: ExternalDevice, options: &ContextOptions) -> Result<Self> {
        Self::with_context(GpuContext::from_external(external, options)?)
    }

    fn with_context(ctx: GpuContext) -> Result<Self> {
        let shadows = ShadowPipeline::new(&ctx)?;
        let view = ViewSamplePass::new(&ctx)?;
        let visibility_out = VisibilityOutPass::new(&ctx)?;
        Ok(Engine {
            ctx,
            view,
            shadows,
            shading: ShadingCache::default(),
            alpha: AlphaTablesCache::default(),
            frame_id: 0,
            visibility_out,
            record_status: None,
        })
    }

    /// The Vulkan context.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The shadow passes (their buffers hold the last run's intermediate
    /// results, for tests against the CPU twins).
    pub fn shadow_pipeline(&self) -> &ShadowPipeline {
        &self.shadows
    }

    /// Hard-shadow visibility of user-supplied view samples (world-space
    /// positions and unit geometric normals; `triangle` = the scene triangle
    /// each lies on, or [`crate::oracle::NO_TRIANGLE`]) for a point or
    /// directional `light`. Positions are made relative to `eye` (the
    /// camera) before they go to the GPU in `f32`. `light_texels`: texels
    /// per side of each light face, a number or [`LightTexels::Auto`]
    /// (only speed depends on it; the result says which it used).
    pub fn hard_shadows(
        &mut self,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        light: &Light,
        light_texels: impl Into<LightTexels>,
    ) -> Result<HardShadowResult> {
        validate_shadow_inputs(scene, eye, samples, light)?;
        let lv = light_view(light, eye).ok_or_else(|| {
            Error::InvalidInput("hard shadows need a point or directional light".into())
        })?;
        let (vs, ts) = self.user_inputs(scene, eye, samples)?;
        let texels = light_texels.into().resolve(vs.len(), ts.len(), false);
        self.run_hard(&vs, &ts, &lv, texels)
    }

    /// User view samples and the scene's triangles in GPU form, the
    /// alpha-tested ones marked and their tables handed to the shadow
    /// passes.
    fn user_inputs(
        &mut self,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
    ) -> Result<(Vec<GpuViewSample>, Vec<GpuTriangle>)> {
        let (vs, mut ts) = user_gpu_inputs(scene, eye, samples);
        self.set_scene_alpha(scene, &mut ts)?;
        Ok((vs, ts))
    }

    /// Marks `scene`'s alpha-tested `triangles` (its triangles in GPU form)
    /// and hands their tables, kept across frames, to the shadow passes.
    pub(super) fn set_scene_alpha(
        &mut self,
        scene: &Scene,
        triangles: &mut [GpuTriangle],
    ) -> Result<()> {
        let (tables, _) = self.alpha.get(scene);
        mark_alpha_triangles(triangles, tables);
        self.shadows.set_alpha(&self.ctx, tables)
    }

    /// Soft-shadow visibility (paper §4) of user-supplied view samples (as in
    /// [`Engine::hard_shadows`]) for a `light` with extent, with the
    /// `settings`' mode, look-up resolution and light-texel resolution.
    pub fn soft_shadows(
        &mut self,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        light: &Light,
        settings: &ShadowSettings,
    ) -> Result<SoftShadowResult> {
        validate_shadow_inputs(scene, eye, samples, light)?;
        settings.validate()?;
        let (sl, lv) = soft_light(light, eye, settings)
            .ok_or_else(|| Error::InvalidInput("soft shadows need a light with extent".into()))?;
        let (vs, ts) = self.user_inputs(scene, eye, samples)?;
        let texels = settings.soft_light_texels.resolve(vs.len(), ts.len(), true);
        self.shadows.set_clusters(settings.clusters);
        self.shadows.set_wedge_rule(settings.wedge_rule);
        self.shadows.set_read_masks(true);
        let out = self
            .shadows
            .run(&self.ctx, &vs, &ts, &lv, texels, Some(&sl))?;
        let stats = ShadowStats::new(&out, texels, lv.face_count(), Some(&sl));
        let so = out.soft.expect("a soft run returns soft output");
        let visibility_rgb = light.sample_colors().map(|colors| {
            crate::light::mask_channel_visibility(
                &colors,
                &so.visible,
                so.mask_words,
                &so.visibility,
            )
        });
        Ok(SoftShadowResult {
            visibility: so.visibility,
            visible: so.visible,
            mask_words: so.mask_words,
            visibility_rgb,
            stats,
        })
    }

    /// [`Engine::hard_shadows`] on inputs already in GPU form (every
    /// triangle opaque).
    pub fn hard_shadows_gpu(
        &mut self,
        view_samples: &[GpuViewSample],
        triangles: &[GpuTriangle],
        light: &LightView,
        light_texels: impl Into<LightTexels>,
    ) -> Result<HardShadowResult> {
        self.shadows.set_alpha(&self.ctx, &AlphaTables::default())?;
        let texels = light_texels
            .into()
            .resolve(view_samples.len(), triangles.len(), false);
        self.run_hard(view_samples, triangles, light, texels)
    }

    /// The hard-shadow passes on inputs in GPU form, with the alpha tables
    /// set last.
    fn run_hard(
        &mut self,
        view_samples: &[GpuViewSample],
        triangles: &[GpuTriangle],
        light: &LightView,
        light_texels: u32,
    ) -> Result<HardShadowResult> {
        validate_gpu_inputs(view_samples, triangles, light)?;
        let out = self.shadows.run(
            &self.ctx,
            view_samples,
            triangles,
            light,
            light_texels,
            None,
        )?;
        let stats = ShadowStats::new(&out, light_texels, light.face_count(), None);
        Ok(HardShadowResult {
            lit: out.lit,
            stats,
        })
    }

    /// Keeps the look-up tables of lights with extent in `dir` across runs,
    /// so that a later run with the same light samples reads its table
    /// instead of building it (`None`, the default: never). The CLI uses
    /// [`crate::gpu::plane_lut::table_cache::default_dir`].
    pub fn set_table_cache(&mut self, dir: Option<std::path::PathBuf>) {
        self.shadows.set_table_cache(dir);
    }

    /// Turns the view-sample clusters ([`crate::gpu::clusters`]) on or off
    /// for [`Engine::hard_shadows`] and [`Engine::hard_shadows_gpu`] (on by
    /// default; the results are the same, off only to measure what they
    /// save). Frames and [`Engine::soft_shadows`] take it from their
    /// [`ShadowSettings::clusters`].
    pub fn set_clusters(&mut self, on: bool) {
        self.shadows.set_clusters(on);
    }

    /// Whether the view samples' raster draws only the triangles whose
    /// image may contain a pixel centre (by default on a CPU device, where
    /// the raster's per-triangle work runs on the host's threads; the view
    /// samples are the same either way): for tests and for measuring what
    /// the cull saves.
    pub fn set_view_cull(&mut self, on: bool) {
        self.view.set_cull(on);
    }

    /// Maps look-up tables read from the cache into device memory where the
    /// device allows it (a CPU device with `VK_EXT_external_memory_host`:
    /// no copy); on by default. Off reads them into fresh memory, as on a
    /// GPU: for tests of that path and for measuring.
    pub fn set_table_mapping(&mut self, on: bool) {
        self.shadows.set_table_mapping(on);
    }

    /// Limits the entries of look-up mode's unsure list per range of work
    /// units: more ranges (and runs again of ranges that overflow), the same
    /// masks. For tests of that path; `None` lifts it.
    pub fn set_unsure_list_limit(&mut self, limit: Option<u64>) {
        self.shadows.set_unsure_list_limit(limit);
    }

    /// Limits the view samples per shadow run: larger sets are split into
    /// batches, as they are anyway when their buffers would pass the
    /// device's binding limits. For tests of that path; `None` lifts it.
    pub fn set_view_sample_batch_limit(&mut self, limit: Option<usize>) {
        self.shadows.set_batch_limit(limit);
    }

    /// Limits the rows the view samples' resolve writes per dispatch
    /// (rounded down to a multiple of 64): an image is resolved in bands
    /// of rows, as it is anyway when its view samples would pass one
    /// storage binding (lavapipe binds 128 MiB: 2048² samples). For tests
    /// of that path; `None` lifts it.
    pub fn set_view_sample_band_limit(&mut self, rows: Option<u32>) {
        self.view.set_band_limit(rows);
    }

    /// Limits the triangles per shadow run: more are split into batches
    /// whose results are combined, as they are anyway when the caster
    /// buffers would pass the device's binding limits (scenes of millions
    /// of triangles). For tests of that path; `None` lifts it.
    pub fn set_triangle_batch_limit(&mut self, limit: Option<usize>) {
        self.shadows.set_triangle_batch_limit(limit);
    }

    /// The plane look-up texture of `light` (a light with extent) with
    /// `settings`' resolution and mode, as the device holds it: in
    /// approximate mode, per texel, then per 128-sample block, the bits of
    /// the samples behind the texel's plane (built on the GPU; for tests
    /// against [`crate::cpu::plane_lut::build_lut`]); in look-up mode the
    /// table of [`crate::cpu::plane_lut::build_sure_lut`].
    pub fn plane_lut_bits(
        &mut self,
        light: &Light,
        eye: DVec3,
        settings: &ShadowSettings,
    ) -> Result<Vec<[u32; 4]>> {
        light.validate()?;
        let (sl, _) = soft_light(light, eye, settings).ok_or_else(|| {
            Error::InvalidInput("a look-up texture needs a light with extent".into())
        })?;
        self.shadows.plane_lut_bits(&self.ctx, &sl)
    }
}
