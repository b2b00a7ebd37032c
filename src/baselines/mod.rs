//! Baselines to measure the alias-free shadows against, on the same Vulkan
//! device (not part of the main pipeline; `afs bench` runs them):
//!
//! - [`Baselines::pcf`]: a standard shadow map (light-space depth from the
//!   light's centre, 2048² to 8192²) with percentage-closer filtering and
//!   the usual bias settings ([`Bias`]: constant, slope-scaled, normal
//!   offset, receiver plane);
//! - [`Baselines::pcss`]: percentage-closer soft shadows for lights with
//!   extent (blocker search, penumbra estimate, variable PCF);
//! - [`Baselines::per_sample_maps`]: one shadow map per light sample of
//!   [`Light::light_samples`] (the same samples as the engine), averaged:
//!   the brute-force sample-based method;
//! - [`oracle`]: the CPU ray-casting oracle, wrapped to be timed the same way;
//! - `embree` (cargo feature `embree`): Embree's occlusion rays, the CPU ray
//!   tracer a user would pick instead, with the same samples.
//!
//! Every method takes what [`Engine::soft_shadows`](crate::render::Engine::soft_shadows)
//! takes (scene, eye, view samples, light) and returns a visibility per view
//! sample, so that run time and error compare like for like. Maps are fitted
//! to the view samples (a perspective frustum from a point, an orthographic
//! box for a directional light); a sample facing away from the light (or
//! light sample) is unlit, as in the oracle.

#[cfg(feature = "embree")]
pub mod embree;
mod shadow_map;

use std::time::Instant;

use glam::{DVec3, Vec3};

pub use shadow_map::{FilterParams, LightFrame, ShadowMapPass};

use crate::light::{Light, LightSamples};
use crate::oracle::{Oracle, ViewSample, ViewSamples};
use crate::render::validate_shadow_inputs;
use crate::scene::Scene;
use crate::vulkan::{vk, BufferDesc, GpuContext};
use crate::{Error, Result};

/// Shadow-map bias settings, in units of the receiver's texel footprint
/// (the world size of one map texel at the receiver's depth), so that one
/// setting suits every map resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bias {
    /// Constant depth bias.
    pub constant: f32,
    /// Slope-scaled depth bias: times tan(angle between normal and light).
    pub slope: f32,
    /// The receiver is moved this far along its normal before the look-up.
    pub normal_offset: f32,
    /// Each tap compares with the receiver's plane along the tap's texel
    /// ray rather than the receiver's own depth (receiver-plane depth bias:
    /// no self-shadowing of planar receivers under wide kernels).
    pub receiver_plane: bool,
}

impl Default for Bias {
    /// Settings that keep `builtin:demo` free of acne at 64²–512² (see
    /// `tests/baselines.rs`).
    fn default() -> Self {
        Bias {
            constant: 0.5,
            slope: 1.0,
            normal_offset: 0.5,
            receiver_plane: true,
        }
    }
}

/// A standard shadow map with PCF ([`Baselines::pcf`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PcfSettings {
    /// Map side in texels.
    pub resolution: u32,
    /// Kernel radius k: (2k+1)² taps one texel apart (0: one tap).
    pub kernel: u32,
    /// Depth bias and normal offset of the map look-ups.
    pub bias: Bias,
}

/// Percentage-closer soft shadows ([`Baselines::pcss`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PcssSettings {
    /// Map side in texels.
    pub resolution: u32,
    /// Kernel radius k (at least 1): (2k+1)² taps for the blocker search
    /// and again for the filter, spread over their widths.
    pub kernel: u32,
    /// The widest search or filter radius, in texels.
    pub max_radius_texels: f32,
    /// Depth bias and normal offset of the map look-ups.
    pub bias: Bias,
}

/// One shadow map per light sample, averaged ([`Baselines::per_sample_maps`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerSampleSettings {
    /// Map side in texels.
    pub resolution: u32,
    /// PCF kernel radius per map (0: one tap, the plain sample-based method).
    pub kernel: u32,
    /// Depth bias and normal offset of the map look-ups.
    pub bias: Bias,
}

/// A baseline's visibility of each view sample.
#[derive(Clone, Debug)]
pub struct BaselineResult {
    /// Per view sample: the lit share, `None` where there is no view sample.
    pub visibility: Vec<Option<f32>>,
    /// What was done: maps, resolution, wall milliseconds.
    pub stats: serde_json::Value,
}

const MAX_RESOLUTION: u32 = 16384;

fn check_resolution(resolution: u32) -> Result<()> {
    if !(1..=MAX_RESOLUTION).contains(&resolution) {
        return Err(Error::InvalidInput(format!(
            "shadow-map resolution must be in 1..={MAX_RESOLUTION}, got {resolution}"
        )));
    }
    Ok(())
}

/// The shadow-map baselines: their pipelines, made once and reused.
pub struct Baselines {
    pass: ShadowMapPass,
    /// The last scene committed to Embree, and what it was made from (its
    /// triangle count and eye): built once per scene, not per frame.
    #[cfg(feature = "embree")]
    embree: Option<(usize, DVec3, embree::EmbreeScene)>,
}

/// Where a set of maps is rendered from: perspective from points
/// (camera-relative), or orthographic along a direction.
enum Sources {
    Points(Vec<Vec3>),
    Direction(Vec3),
}

impl Baselines {
    /// Compiles the pipelines; fails when the queue cannot do graphics.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(Baselines {
            pass: ShadowMapPass::new(ctx)?,
            #[cfg(feature = "embree")]
            embree: None,
        })
    }

    /// Embree's shadow rays ([`embree::light_shadows`], all threads), the
    /// scene committed once and kept while the scene stays the same.
    #[cfg(feature = "embree")]
    pub fn embree(
        &mut self,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        light: &Light,
    ) -> Result<BaselineResult> {
        let threads = rayon::current_num_threads();
        let count = scene.triangle_count();
        if !self
            .embree
            .as_ref()
            .is_some_and(|(n, e, _)| *n == count && *e == eye)
        {
            self.embree = None;
            let s = embree::EmbreeScene::from_scene(scene, eye, threads)?;
            self.embree = Some((count, eye, s));
        }
        let (_, _, s) = self.embree.as_ref().expect("made above");
        let mode = embree::RayMode::Single;
        let r = embree::light_shadows(s, scene, eye, samples, light, threads, mode)?;
        Ok(BaselineResult {
            visibility: r.visibility.clone(),
            stats: serde_json::json!({
                "rays": r.rays,
                "ms": r.ms,
                "rays_per_second": r.rays_per_second(),
                "build_ms": s.build_ms,
                "threads": threads,
            }),
        })
    }

    /// A shadow map from the light's centre (a point light's position, an
    /// area light's centre, or a directional light's direction) with
    /// `settings`' PCF kernel: hard shadows, blurred by the kernel.
    pub fn pcf(
        &mut self,
        ctx: &GpuContext,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        light: &Light,
        settings: &PcfSettings,
    ) -> Result<BaselineResult> {
        validate_shadow_inputs(scene, eye, samples, light)?;
        check_resolution(settings.resolution)?;
        let sources = centre_source(light, eye)?;
        let params = filter_params(settings.kernel, None, 0.0, &settings.bias);
        self.run(
            ctx,
            scene,
            eye,
            samples,
            sources,
            settings.resolution,
            &params,
        )
    }

    /// Percentage-closer soft shadows for a light with extent: one map from
    /// the light's centre; the blocker search and the penumbra width use
    /// the light's radius (its samples' largest distance from the centre).
    pub fn pcss(
        &mut self,
        ctx: &GpuContext,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        light: &Light,
        settings: &PcssSettings,
    ) -> Result<BaselineResult> {
        validate_shadow_inputs(scene, eye, samples, light)?;
        check_resolution(settings.resolution)?;
        if settings.kernel == 0
            || settings.max_radius_texels.is_nan()
            || settings.max_radius_texels <= 0.0
        {
            return Err(Error::InvalidInput(
                "PCSS needs a kernel radius of at least 1 and a positive largest radius".into(),
            ));
        }
        let LightSamples::Positions(points) = light.light_samples() else {
            return Err(Error::InvalidInput(
                "PCSS needs a light with a position".into(),
            ));
        };
        let centre = light.center().unwrap_or(eye);
        let radius = points
            .iter()
            .map(|p| (*p - centre).length())
            .fold(0.0, f64::max);
        let sources = Sources::Points(vec![(centre - eye).as_vec3()]);
        let params = filter_params(
            settings.kernel,
            Some(radius as f32),
            settings.max_radius_texels,
            &settings.bias,
        );
        self.run(
            ctx,
            scene,
            eye,
            samples,
            sources,
            settings.resolution,
            &params,
        )
    }

    /// One shadow map per light sample of `light` (its
    /// [`Light::light_samples`]), each looked up with `settings`' kernel,
    /// the lit shares averaged.
    pub fn per_sample_maps(
        &mut self,
        ctx: &GpuContext,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        light: &Light,
        settings: &PerSampleSettings,
    ) -> Result<BaselineResult> {
        validate_shadow_inputs(scene, eye, samples, light)?;
        check_resolution(settings.resolution)?;
        let sources = match light.light_samples() {
            LightSamples::Positions(p) => {
                Sources::Points(p.iter().map(|p| (*p - eye).as_vec3()).collect())
            }
            LightSamples::Direction(d) => Sources::Direction(d.as_vec3()),
        };
        let params = filter_params(settings.kernel, None, 0.0, &settings.bias);
        self.run(
            ctx,
            scene,
            eye,
            samples,
            sources,
            settings.resolution,
            &params,
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn run(
        &mut self,
        ctx: &GpuContext,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        sources: Sources,
        resolution: u32,
        params: &FilterParams,
    ) -> Result<BaselineResult> {
        let t0 = Instant::now();
        let (vs, ts) = crate::render::user_gpu_inputs(scene, eye, samples);
        let receivers: Vec<Vec3> = vs
            .iter()
            .filter(|s| s.flags & crate::gpu::shared::VIEW_SAMPLE_VALID != 0)
            .map(|s| Vec3::from_array(s.position))
            .collect();
        let casters: Vec<Vec3> = ts
            .iter()
            .flat_map(|t| [t.v0, t.v1, t.v2])
            .map(Vec3::from_array)
            .collect();
        let frames: Vec<(LightFrame, f32)> = match &sources {
            Sources::Points(points) => {
                let w = 1.0 / points.len().max(1) as f32;
                points
                    .iter()
                    .map(|o| {
                        (
                            LightFrame::perspective(*o, &receivers, &casters, resolution),
                            w,
                        )
                    })
                    .collect()
            }
            Sources::Direction(d) => vec![(
                LightFrame::orthographic(*d, &receivers, &casters, resolution),
                1.0,
            )],
        };

        let n = vs.len();
        let nt = u32::try_from(ts.len())
            .ok()
            .filter(|&t| t as u64 * 3 <= u32::MAX as u64)
            .ok_or_else(|| Error::InvalidInput("too many triangles for a shadow map".into()))?;
        let view_buf = ctx.create_buffer(BufferDesc::storage(
            "baseline_view_samples",
            (32 * n as u64).max(32),
        ))?;
        if n > 0 {
            ctx.upload(&view_buf, 0, &vs)?;
        }
        let mut desc = BufferDesc::storage("baseline_triangles", (48 * nt as u64).max(48));
        desc.usage |= vk::BufferUsageFlags::VERTEX_BUFFER;
        let tri_buf = ctx.create_buffer(desc)?;
        if nt > 0 {
            ctx.upload(&tri_buf, 0, &ts)?;
        }
        let vis_buf = ctx.create_buffer(BufferDesc::storage(
            "baseline_visibility",
            (4 * n as u64).max(4),
        ))?;
        let mut rec = ctx.begin()?;
        rec.fill_buffer(vis_buf.whole(), 0)?;
        rec.barrier(crate::vulkan::Barrier::TransferToCompute);
        ctx.submit_and_wait(rec)?;
        self.pass.run(
            ctx,
            &view_buf,
            n,
            &tri_buf,
            3 * nt,
            &frames,
            resolution,
            params,
            &vis_buf,
        )?;
        let vis: Vec<f32> = if n > 0 {
            ctx.read_buffer(&vis_buf, 0, n)?
        } else {
            Vec::new()
        };
        ctx.check_validation()?;
        let visibility = samples.iter().zip(vis).map(|(s, v)| s.map(|_| v)).collect();
        Ok(BaselineResult {
            visibility,
            stats: serde_json::json!({
                "maps": frames.len(),
                "resolution": resolution,
                "kernel": params.kernel,
                "pcss": params.pcss_radius.is_some(),
                "wall_ms": t0.elapsed().as_secs_f64() * 1e3,
            }),
        })
    }
}

fn filter_params(kernel: u32, pcss_radius: Option<f32>, max_radius: f32, b: &Bias) -> FilterParams {
    FilterParams {
        kernel,
        pcss_radius,
        max_radius_texels: max_radius,
        constant: b.constant,
        slope: b.slope,
        normal_offset: b.normal_offset,
        receiver_plane: b.receiver_plane,
    }
}

fn centre_source(light: &Light, eye: DVec3) -> Result<Sources> {
    match light.light_samples() {
        LightSamples::Direction(d) => Ok(Sources::Direction(d.as_vec3())),
        LightSamples::Positions(_) => {
            let c = light
                .center()
                .ok_or_else(|| Error::InvalidInput("the light has no centre".into()))?;
            Ok(Sources::Points(vec![(c - eye).as_vec3()]))
        }
    }
}

/// The CPU oracle as a baseline: ray-cast visibility of `samples` against
/// `light`'s samples (building the BVH is part of the timed work).
pub fn oracle(
    scene: &Scene,
    eye: DVec3,
    samples: &[Option<ViewSample>],
    light: &Light,
) -> Result<BaselineResult> {
    validate_shadow_inputs(scene, eye, samples, light)?;
    let t0 = Instant::now();
    let oracle = Oracle::new(&scene.triangles(), eye);
    // The oracle works row by row in parallel: rows of 64 samples.
    let view = ViewSamples {
        width: 64,
        height: samples.len().div_ceil(64) as u32,
        eye,
        samples: samples.to_vec(),
    };
    let vis = oracle.visibility(&view, &light.light_samples(), None);
    Ok(BaselineResult {
        visibility: samples.iter().zip(vis).map(|(s, v)| s.map(|_| v)).collect(),
        stats: serde_json::json!({
            "shadow_rays": oracle.shadow_rays_cast(),
            "wall_ms": t0.elapsed().as_secs_f64() * 1e3,
        }),
    })
}
