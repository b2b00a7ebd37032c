//! A frame, top to bottom ([`Engine::render`]): the GPU's passes in order
//! (the CPU oracle's frame, [`render_reference`], is the reference):
//!
//! 1. view samples (what the camera sees);
//! 2. per light: per-light-texel lists of view samples (count, scan, scatter);
//! 3. each caster's influence region, conservatively rasterized (binned);
//! 4. occlusion of every listed view sample by every covering caster (one
//!    bit, or a light-sample bitmask from the plane look-up texture);
//! 5. visibility = visible light samples / light samples, then shading.
//!
//! Steps 2–5 are [`crate::gpu::hard_shadows::HardShadowPass::run_on`].

use std::time::Instant;

use crate::dump::{Dump, DumpLight, DumpScene};
use crate::light::LightSamples;
use crate::oracle::{Oracle, ViewSamples};
use crate::scene::file::SceneDescription;
use crate::shade::{faces_light, shade};
use crate::Result;

/// A rendered frame: the dump (view samples, visibility, scene, stats) and the shaded image.
pub struct Frame {
    pub dump: Dump,
    pub image: image::RgbImage,
    /// The view samples the frame used (with triangle ids, which the dump omits).
    pub view: ViewSamples,
}

/// Options for a frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameOptions {
    /// Show progress bars on standard error.
    pub progress: bool,
}

fn progress_bar(len: u64, what: &str, show: bool) -> Option<indicatif::ProgressBar> {
    show.then(|| {
        let pb = indicatif::ProgressBar::new(len);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg:>24} [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        pb.set_message(what.to_string());
        pb
    })
}

/// Builds the dump's per-pixel arrays from view samples and per-light visibility.
pub fn make_dump(
    desc: &SceneDescription,
    view: &ViewSamples,
    light_samples: &[LightSamples],
    visibility: &[Vec<f32>],
    evaluated: &[Vec<bool>],
    stats: serde_json::Value,
) -> Dump {
    let eye = desc.camera.eye;
    let mut position = Vec::with_capacity(view.samples.len());
    let mut normal = Vec::with_capacity(view.samples.len());
    for s in &view.samples {
        match s {
            Some(s) => {
                let p = s.position - eye;
                position.push([p.x as f32, p.y as f32, p.z as f32, 1.0]);
                normal.push([s.normal.x as f32, s.normal.y as f32, s.normal.z as f32, 1.0]);
            }
            None => {
                position.push([0.0; 4]);
                normal.push([0.0; 4]);
            }
        }
    }
    let vis = visibility
        .iter()
        .zip(evaluated)
        .map(|(v, e)| {
            view.samples
                .iter()
                .enumerate()
                .map(|(i, s)| match s {
                    Some(_) => [v[i], if e[i] { 1.0 } else { 0.0 }, 0.0, 1.0],
                    None => [0.0; 4],
                })
                .collect()
        })
        .collect();
    Dump {
        width: view.width,
        height: view.height,
        position,
        normal,
        visibility: vis,
        scene: DumpScene {
            camera: desc.camera,
            lights: desc
                .lights
                .iter()
                .zip(light_samples)
                .map(|(l, s)| DumpLight::new(l, s))
                .collect(),
        },
        stats,
    }
}

/// One light's visibility from the oracle, with the "evaluated" flags (a
/// sample facing away from the whole light is decided without shadow rays).
fn oracle_light(
    oracle: &Oracle,
    view: &ViewSamples,
    samples: &LightSamples,
    k: usize,
    progress: bool,
) -> (Vec<f32>, Vec<bool>) {
    let pb = progress_bar(
        view.height as u64,
        &format!("oracle light {k} ({} samples)", samples.len()),
        progress,
    );
    let vis = oracle.visibility(view, samples, pb.as_ref());
    if let Some(pb) = pb {
        pb.finish_and_clear();
    }
    let evaluated = view
        .samples
        .iter()
        .map(|s| s.is_some_and(|s| faces_light(s.position, s.normal, samples)))
        .collect();
    (vis, evaluated)
}

/// The most pixels [`render_reference`] renders (4096²).
pub const MAX_REFERENCE_PIXELS: u64 = 4096 * 4096;

/// Renders a frame with the CPU oracle: primary rays for the view samples,
/// shadow rays for visibility. The reference every GPU frame is compared to.
pub fn render_reference(desc: &SceneDescription, options: FrameOptions) -> Result<Frame> {
    desc.validate()?;
    let pixels = desc.camera.width as u64 * desc.camera.height as u64;
    if pixels > MAX_REFERENCE_PIXELS {
        // About 100 bytes per pixel plus 17 per light: without this an
        // absurd size aborts on a failed allocation instead of an error.
        return Err(crate::Error::InvalidInput(format!(
            "camera: image size {}x{} is more than the CPU reference renders \
             ({MAX_REFERENCE_PIXELS} pixels, 4096x4096)",
            desc.camera.width, desc.camera.height
        )));
    }
    let t0 = Instant::now();
    let triangles = desc.scene.triangles();
    let oracle = Oracle::new(&triangles, desc.camera.eye);
    let bvh_ms = t0.elapsed().as_secs_f64() * 1e3;

    let t1 = Instant::now();
    let view = oracle.primary_view_samples(&desc.camera);
    let view_ms = t1.elapsed().as_secs_f64() * 1e3;
    let view_sample_count = view.samples.iter().filter(|s| s.is_some()).count();

    let mut light_samples = Vec::new();
    let mut visibility = Vec::new();
    let mut evaluated = Vec::new();
    let mut shadow_ms = Vec::new();
    for (k, light) in desc.lights.iter().enumerate() {
        let samples = light.light_samples();
        let t = Instant::now();
        let (vis, ev) = oracle_light(&oracle, &view, &samples, k, options.progress);
        shadow_ms.push(t.elapsed().as_secs_f64() * 1e3);
        evaluated.push(ev);
        visibility.push(vis);
        light_samples.push(samples);
    }
    let t2 = Instant::now();
    let image = shade(&view, &desc.lights, &visibility);
    let shade_ms = t2.elapsed().as_secs_f64() * 1e3;
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    let shadow_rays = oracle.shadow_rays_cast();
    let shadow_total: f64 = shadow_ms.iter().sum();
    let stats = serde_json::json!({
        "device": "cpu oracle (ray casting)",
        "scene": desc.name,
        "settings": desc.shadows,
        "width": desc.camera.width,
        "height": desc.camera.height,
        "ms": {
            "bvh": bvh_ms,
            "view_samples": view_ms,
            "shadow_rays_per_light": shadow_ms,
            "shade": shade_ms,
        },
        "total_ms": total_ms,
        "counters": {
            "triangles": triangles.len(),
            "view_samples": view_sample_count,
            "light_samples": light_samples.iter().map(|s| s.len()).collect::<Vec<_>>(),
            "shadow_rays": shadow_rays,
            "shadow_rays_per_second": if shadow_total > 0.0 { shadow_rays as f64 / (shadow_total / 1e3) } else { 0.0 },
            "threads": rayon::current_num_threads(),
        }
    });
    let dump = make_dump(desc, &view, &light_samples, &visibility, &evaluated, stats);
    Ok(Frame { dump, image, view })
}

// ---------------------------------------------------------------------------
// The GPU frame.

use glam::{DVec3, Vec3};

use crate::cpu::light_view::LightView;
use crate::gpu::hard_shadows::{gpu_inputs, HardShadowOutput, HardShadowPass, SoftLight};
use crate::gpu::shared::{counter, GpuTriangle, GpuViewSample};
use crate::gpu::view_samples::{read_view_samples, ViewSamplePass};
use crate::light::{Light, LightShape};
use crate::oracle::ViewSample;
use crate::scene::file::{ShadowSettings, SoftMode};
use crate::scene::Scene;
use crate::vulkan::BufferDesc;
use crate::vulkan::{ContextOptions, GpuContext};

/// The engine: a Vulkan context and the compiled passes, reused frame after frame.
pub struct Engine {
    ctx: GpuContext,
    view: ViewSamplePass,
    hard: HardShadowPass,
}

/// Hard-shadow visibility of a set of view samples for one light.
#[derive(Clone, Debug)]
pub struct HardShadowResult {
    /// Per view sample: `None` when it faces away from the light (unlit
    /// without a shadow test), else whether it is lit.
    pub lit: Vec<Option<bool>>,
    /// Statistics (counters and milliseconds per pass).
    pub stats: serde_json::Value,
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
    /// Statistics (counters and milliseconds per pass).
    pub stats: serde_json::Value,
}

/// The checks [`Engine::hard_shadows`] and [`Engine::soft_shadows`] make on
/// their inputs before any GPU work: `eye` finite; `light` valid
/// ([`Light::validate`]) and in range of the eye
/// ([`Light::validate_relative_to`]); `scene` valid ([`Scene::validate`]);
/// every view sample's position finite and within
/// [`MAX_RELATIVE_COORDINATE`](crate::scene::MAX_RELATIVE_COORDINATE) of
/// the eye along each axis, its normal finite and non-zero in `f32`, and its
/// triangle [`NO_TRIANGLE`](crate::oracle::NO_TRIANGLE) or a triangle of
/// the scene. The error names the view sample or the field.
pub fn validate_shadow_inputs(
    scene: &Scene,
    eye: DVec3,
    samples: &[Option<ViewSample>],
    light: &Light,
) -> Result<()> {
    use crate::Error::InvalidInput;
    if !eye.is_finite() {
        return Err(InvalidInput(format!("`eye` is not finite: {eye:?}")));
    }
    light.validate()?;
    light.validate_relative_to(eye)?;
    scene.validate(eye)?;
    let triangles = scene.triangle_count();
    for (i, s) in samples.iter().enumerate() {
        let Some(s) = s else { continue };
        if !s.position.is_finite() || !s.normal.is_finite() {
            return Err(InvalidInput(format!(
                "view sample {i} is not finite: {s:?}"
            )));
        }
        if !crate::scene::within_range(s.position - eye) {
            return Err(InvalidInput(format!(
                "view sample {i}: the position {:?} is more than {:e} from the eye {eye:?} along an axis \
                 (the GPU passes work in f32 relative to the eye)",
                s.position,
                crate::scene::MAX_RELATIVE_COORDINATE
            )));
        }
        // What the GPU gets: zero when the normal is zero, or too small or
        // too large for f32.
        if s.normal.as_vec3().normalize_or_zero() == Vec3::ZERO {
            return Err(InvalidInput(format!(
                "view sample {i}: the normal {:?} is zero or not representable in f32",
                s.normal
            )));
        }
        if s.triangle != crate::oracle::NO_TRIANGLE && s.triangle as usize >= triangles {
            return Err(InvalidInput(format!(
                "view sample {i}: triangle {} does not exist (the scene has {triangles}; \
                 NO_TRIANGLE for a sample on none)",
                s.triangle
            )));
        }
    }
    Ok(())
}

/// Corners of the polygon bounding the light's silhouette (influence regions).
pub const INFLUENCE_POLYGON_DEGREE: u32 = 6;

/// A light with extent as the soft-shadow passes see it (camera-relative
/// samples), and the point it is seen from (their centre).
pub fn soft_light(
    light: &Light,
    eye: DVec3,
    settings: &ShadowSettings,
) -> Option<(SoftLight, LightView)> {
    if !light.is_area() {
        return None;
    }
    let samples = match light.light_samples() {
        crate::light::LightSamples::Positions(p) => p,
        crate::light::LightSamples::Direction(_) => return None,
    };
    let sl = SoftLight {
        samples: samples.iter().map(|p| (*p - eye).as_vec3()).collect(),
        exact: settings.mode == SoftMode::Exact,
        lut_resolution: settings.lut_resolution,
        polygon_degree: INFLUENCE_POLYGON_DEGREE,
    };
    let (centre, _) = sl.bounds();
    Some((sl, LightView::Point { position: centre }))
}

fn soft_stats(
    out: &HardShadowOutput,
    resolution: u32,
    faces: usize,
    sl: &SoftLight,
) -> serde_json::Value {
    let mut st = hard_stats(out, resolution, faces);
    let c = &out.counters;
    st["light_samples"] = serde_json::json!(sl.samples.len());
    st["mode"] = serde_json::json!(if sl.exact { "exact" } else { "lut" });
    st["lut_resolution"] = serde_json::json!(sl.lut_resolution);
    st["blocking_tests"] = serde_json::json!(c[counter::BLOCKING]);
    st["blocking_share"] =
        serde_json::json!(c[counter::BLOCKING] as f64 / c[counter::TESTS].max(1) as f64);
    // The look-up texture is built once per light shape and reused: its
    // build time (ms.lut_build) appears only in the frame that built it.
    st["lut_built"] = serde_json::json!(out.soft.as_ref().is_some_and(|s| s.lut_built));
    st
}

/// The light as the hard-shadow passes see it, camera-relative; `None`
/// for lights with extent (handled by the soft-shadow path).
pub fn light_view(light: &Light, eye: DVec3) -> Option<LightView> {
    match &light.shape {
        LightShape::Point { position } => Some(LightView::Point {
            position: (*position - eye).as_vec3(),
        }),
        LightShape::Directional { direction } => Some(LightView::Directional {
            direction: direction.as_vec3(),
        }),
        _ => None,
    }
}

/// User view samples and the scene's triangles in GPU form, camera-relative
/// (the shared first step of [`Engine::hard_shadows`] and
/// [`Engine::soft_shadows`]).
pub(crate) fn user_gpu_inputs(
    scene: &Scene,
    eye: DVec3,
    samples: &[Option<ViewSample>],
) -> (Vec<GpuViewSample>, Vec<GpuTriangle>) {
    let with_ids: Vec<_> = samples
        .iter()
        .map(|s| {
            s.map(|s| {
                (
                    (s.position - eye).as_vec3(),
                    s.normal.as_vec3().normalize_or_zero(),
                    s.triangle,
                )
            })
        })
        .collect();
    gpu_inputs(&with_ids, &user_gpu_triangles(scene, eye, samples))
}

/// The scene's triangles as [`Engine::hard_shadows`] and
/// [`Engine::soft_shadows`] send them for user view samples: as
/// [`gpu_triangles`], and a closed mesh that some sample may see from the
/// inside is treated as open too.
pub fn user_gpu_triangles(
    scene: &Scene,
    eye: DVec3,
    samples: &[Option<ViewSample>],
) -> Vec<([Vec3; 3], bool)> {
    let mut triangles = gpu_triangles(scene, eye);
    let opened = closed_meshes_seen_from_inside(scene, samples);
    let meshes = scene.triangles();
    for (t, m) in triangles.iter_mut().zip(&meshes) {
        t.1 &= !opened[m.mesh as usize];
    }
    triangles
}

/// Per mesh: whether some user view sample may see a closed mesh from the
/// inside, so that the passes must treat it as open (skipping the faces
/// that face the light, paper §3.3, is right only for samples outside the
/// solid). That is a sample on one of its triangles whose normal opposes
/// the triangle's winding, or any sample not on its triangles that lies
/// inside it (tested exactly for the samples in its bounding box, up to a
/// budget of triangle tests; past it, any sample in the box). Treating a
/// closed mesh as open is always correct, only slower.
fn closed_meshes_seen_from_inside(scene: &Scene, samples: &[Option<ViewSample>]) -> Vec<bool> {
    let mut opened = vec![false; scene.meshes.len()];
    let boxes: Vec<Option<(DVec3, DVec3)>> = scene
        .meshes
        .iter()
        .map(|m| {
            if !m.closed || m.positions.is_empty() {
                return None;
            }
            let (lo, hi) = m
                .positions
                .iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(*p), hi.max(*p))
                });
            // A margin for samples rounded just outside the surface.
            let margin = (hi - lo).length() * 1e-6 + lo.abs().max(hi.abs()).max_element() * 1e-12;
            Some((lo - margin, hi + margin))
        })
        .collect();
    if boxes.iter().all(Option::is_none) {
        return opened;
    }
    let triangles = scene.triangles();
    // Per closed mesh, samples in its box not on its own surface: tested
    // for containment exactly where that is cheap, else the mesh opens.
    let mut in_box: Vec<Vec<DVec3>> = vec![Vec::new(); scene.meshes.len()];
    for s in samples.iter().flatten() {
        // The closed mesh the sample lies on, seen from the outside.
        let mut own = None;
        if let Some(t) = triangles.get(s.triangle as usize).filter(|t| t.closed) {
            let v = t.vertices;
            if (v[1] - v[0]).cross(v[2] - v[0]).dot(s.normal) > 0.0 {
                own = Some(t.mesh as usize);
            } else {
                opened[t.mesh as usize] = true;
            }
        }
        for (m, b) in boxes.iter().enumerate() {
            if let Some((lo, hi)) = b {
                if own != Some(m) && s.position.cmpge(*lo).all() && s.position.cmple(*hi).all() {
                    in_box[m].push(s.position);
                }
            }
        }
    }
    /// Triangle tests allowed per mesh for exact containment.
    const CONTAINMENT_BUDGET: usize = 20_000_000;
    for (m, points) in in_box.iter().enumerate() {
        if opened[m] || points.is_empty() {
            continue;
        }
        let mesh = &scene.meshes[m];
        // A sample on or just outside the surface (f32 rounding) may count
        // as inside: that only opens the mesh, which is always correct.
        opened[m] = points.len().saturating_mul(mesh.indices.len()) > CONTAINMENT_BUDGET
            || points.iter().any(|p| mesh.contains(*p));
    }
    opened
}

/// The scene's triangles, camera-relative, in global-id order, each with
/// whether the passes may treat it as part of a closed mesh. A closed mesh
/// that contains the eye is treated as open: its view samples are on the
/// inside, where skipping the faces that face the light (paper §3.3) would
/// drop the very faces that hide the light.
pub fn gpu_triangles(scene: &Scene, eye: DVec3) -> Vec<([Vec3; 3], bool)> {
    let inside = scene.closed_meshes_containing(eye);
    scene
        .triangles()
        .iter()
        .map(|t| {
            (
                t.vertices.map(|v| (v - eye).as_vec3()),
                t.closed && !inside[t.mesh as usize],
            )
        })
        .collect()
}

fn hard_stats(out: &HardShadowOutput, resolution: u32, faces: usize) -> serde_json::Value {
    let occupied = out.list_lengths.iter().filter(|&&c| c > 0).count();
    let listed: u64 = out.list_lengths.iter().map(|&c| c as u64).sum();
    let max_list = out.list_lengths.iter().copied().max().unwrap_or(0);
    let c = &out.counters;
    let culled = c[counter::DEGENERATE] + c[counter::FRONT_FACING_CLOSED] + c[counter::CULLED];
    // Passes run once per 128-sample block appear once per block: summed.
    let mut ms = serde_json::Map::new();
    for t in &out.timings {
        let prev = ms.get(&t.name).and_then(|v| v.as_f64());
        let v = match (prev, t.ms) {
            (Some(a), Some(b)) => Some(a + b),
            (None, b) => b,
            (a, None) => a,
        };
        ms.insert(t.name.clone(), serde_json::json!(v));
    }
    serde_json::json!({
        "light_texels": resolution,
        "light_faces": faces,
        "listed_view_samples": listed,
        "occupied_texels": occupied,
        "occupied_texels_percent": 100.0 * occupied as f64 / (faces as f64 * (resolution as f64).powi(2)).max(1.0),
        "average_list_length": listed as f64 / occupied.max(1) as f64,
        "max_list_length": max_list,
        "triangles_submitted": c[counter::DEGENERATE] + c[counter::FRONT_FACING_CLOSED] + c[counter::CULLED] + c[counter::RASTERIZED],
        "triangles_culled": culled,
        "triangles_degenerate": c[counter::DEGENERATE],
        "triangles_front_facing_closed": c[counter::FRONT_FACING_CLOSED],
        "triangles_outside_frustum": c[counter::CULLED],
        "triangles_rasterized": c[counter::RASTERIZED],
        "caster_face_pairs": c[counter::PAIRS],
        "texels_visited": c[counter::TEXELS_VISITED],
        "view_sample_triangle_tests": c[counter::TESTS],
        "gpu_buffer_bytes": out.buffer_bytes,
        "ms": ms,
        "gpu_ms": out.timings.iter().filter_map(|t| t.ms).sum::<f64>(),
    })
}

impl Engine {
    /// Creates the Vulkan context (device from `options`, `AFS_DEVICE`, or
    /// the default choice) and compiles the passes.
    pub fn new(options: &ContextOptions) -> Result<Self> {
        let ctx = GpuContext::new(options)?;
        let hard = HardShadowPass::new(&ctx)?;
        let view = ViewSamplePass::new(&ctx)?;
        Ok(Engine { ctx, view, hard })
    }

    /// The Vulkan context.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Hard-shadow visibility of user-supplied view samples (world-space
    /// positions and unit geometric normals; `triangle` = the scene triangle
    /// each lies on, or [`crate::oracle::NO_TRIANGLE`]) for a point or
    /// directional `light`. Positions are made relative to `eye` (the
    /// camera) before they go to the GPU in `f32`.
    pub fn hard_shadows(
        &mut self,
        scene: &Scene,
        eye: DVec3,
        samples: &[Option<ViewSample>],
        light: &Light,
        light_texels: u32,
    ) -> Result<HardShadowResult> {
        validate_shadow_inputs(scene, eye, samples, light)?;
        let lv = light_view(light, eye).ok_or_else(|| {
            crate::Error::InvalidInput("hard shadows need a point or directional light".into())
        })?;
        let (vs, ts) = user_gpu_inputs(scene, eye, samples);
        self.hard_shadows_gpu(&vs, &ts, &lv, light_texels)
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
        let (sl, lv) = soft_light(light, eye, settings).ok_or_else(|| {
            crate::Error::InvalidInput("soft shadows need a light with extent".into())
        })?;
        let (vs, ts) = user_gpu_inputs(scene, eye, samples);
        let out = self.hard.run(
            &self.ctx,
            &vs,
            &ts,
            &lv,
            settings.soft_light_texels,
            Some(&sl),
        )?;
        let stats = soft_stats(&out, settings.soft_light_texels, lv.face_count(), &sl);
        let so = out.soft.expect("a soft run returns soft output");
        Ok(SoftShadowResult {
            visibility: so.visibility,
            visible: so.visible,
            mask_words: so.mask_words,
            stats,
        })
    }

    /// Limits the view samples per shadow run: larger sets are split into
    /// batches, as they are anyway when their buffers would pass the
    /// device's binding limits. For tests of that path; `None` lifts it.
    pub fn set_view_sample_batch_limit(&mut self, limit: Option<usize>) {
        self.hard.set_batch_limit(limit);
    }

    /// Limits the triangles per shadow run: more are split into batches
    /// whose results are combined, as they are anyway when the caster
    /// buffers would pass the device's binding limits (scenes of millions
    /// of triangles). For tests of that path; `None` lifts it.
    pub fn set_triangle_batch_limit(&mut self, limit: Option<usize>) {
        self.hard.set_triangle_batch_limit(limit);
    }

    /// The plane look-up texture the GPU builds for `light` (a light with
    /// extent) with `settings`' resolution: per texel, then per 128-sample
    /// block, the bits of the samples behind the texel's plane. For tests
    /// against [`crate::cpu::soft::build_lut`].
    pub fn plane_lut_bits(
        &mut self,
        light: &Light,
        eye: DVec3,
        settings: &ShadowSettings,
    ) -> Result<Vec<[u32; 4]>> {
        light.validate()?;
        let (sl, _) = soft_light(light, eye, settings).ok_or_else(|| {
            crate::Error::InvalidInput("a look-up texture needs a light with extent".into())
        })?;
        self.hard.plane_lut_bits(&self.ctx, &sl)
    }

    /// [`Engine::hard_shadows`] on inputs already in GPU form.
    pub fn hard_shadows_gpu(
        &mut self,
        view_samples: &[GpuViewSample],
        triangles: &[GpuTriangle],
        light: &LightView,
        light_texels: u32,
    ) -> Result<HardShadowResult> {
        use crate::gpu::shared::VIEW_SAMPLE_VALID;
        let finite = |v: &[f32; 3]| v.iter().all(|c| c.is_finite());
        for (i, s) in view_samples.iter().enumerate() {
            if s.flags & VIEW_SAMPLE_VALID != 0 && !(finite(&s.position) && finite(&s.normal)) {
                return Err(crate::Error::InvalidInput(format!(
                    "view sample {i} is not finite: {s:?}"
                )));
            }
        }
        for (i, t) in triangles.iter().enumerate() {
            if !(finite(&t.v0) && finite(&t.v1) && finite(&t.v2)) {
                return Err(crate::Error::InvalidInput(format!(
                    "triangle {i} is not finite: {t:?}"
                )));
            }
        }
        match light {
            LightView::Point { position } if !position.is_finite() => {
                return Err(crate::Error::InvalidInput(format!(
                    "light: `position` is not finite: {position:?}"
                )))
            }
            LightView::Directional { direction }
                if !direction.is_finite() || direction.length_squared() == 0.0 =>
            {
                return Err(crate::Error::InvalidInput(format!(
                    "light: `direction` must be finite and non-zero: {direction:?}"
                )))
            }
            _ => {}
        }
        let out = self.hard.run(
            &self.ctx,
            view_samples,
            triangles,
            light,
            light_texels,
            None,
        )?;
        let stats = hard_stats(&out, light_texels, light.face_count());
        Ok(HardShadowResult {
            lit: out.lit,
            stats,
        })
    }

    /// Renders a frame: view samples, then per light the hard-shadow passes
    /// (point and directional lights) or, for lights with extent until the
    /// soft-shadow passes exist, the CPU oracle; then shading and the dump.
    pub fn render(&mut self, desc: &SceneDescription, _options: FrameOptions) -> Result<Frame> {
        desc.validate()?;
        let t0 = Instant::now();
        let eye = desc.camera.eye;
        let triangles = desc.scene.triangles();
        let gpu_tris = gpu_triangles(&desc.scene, eye);

        // 1. View samples: rasterized on the GPU, exact ray-plane positions.
        let (_, gpu_tris) = gpu_inputs(&[], &gpu_tris);
        let (view_buf, view_ms) = self.view.render(&self.ctx, &desc.camera, &gpu_tris)?;
        let n = (desc.camera.width * desc.camera.height) as usize;
        let gpu_view = read_view_samples(&self.ctx, &view_buf, n)?;
        // The CPU copy (shading, dump, oracle fallback) is exactly what the GPU has.
        let view = ViewSamples {
            width: desc.camera.width,
            height: desc.camera.height,
            eye,
            samples: gpu_view
                .iter()
                .map(|s| {
                    (s.flags != 0).then(|| ViewSample {
                        position: eye + Vec3::from_array(s.position).as_dvec3(),
                        normal: Vec3::from_array(s.normal).as_dvec3(),
                        triangle: s.triangle,
                    })
                })
                .collect(),
        };
        let tri_buf = self.ctx.create_buffer(BufferDesc::storage(
            "triangles",
            (48 * gpu_tris.len() as u64).max(16),
        ))?;
        if !gpu_tris.is_empty() {
            self.ctx.upload_staged(&tri_buf, 0, &gpu_tris)?;
        }
        // 2-5. Per light: lists, casters, rasterization, occlusion, resolve.
        let mut light_samples = Vec::new();
        let mut visibility = Vec::new();
        let mut evaluated = Vec::new();
        let mut light_stats = Vec::new();
        for (k, light) in desc.lights.iter().enumerate() {
            let samples = light.light_samples();
            // Point and directional lights: hard shadows; lights with
            // extent: the same passes with light-sample bitmasks.
            let (lv, soft) = match light_view(light, eye) {
                Some(lv) => (lv, None),
                None => {
                    let (sl, lv) = soft_light(light, eye, &desc.shadows).ok_or_else(|| {
                        crate::Error::InvalidInput(format!("light {k} has no samples"))
                    })?;
                    (lv, Some(sl))
                }
            };
            // The view samples stay on the GPU: no upload between passes.
            let t_light = Instant::now();
            let texels = match soft {
                Some(_) => desc.shadows.soft_light_texels,
                None => desc.shadows.light_texels,
            };
            let out = self.hard.run_on(
                &self.ctx,
                &view_buf,
                n,
                &tri_buf,
                gpu_tris.len(),
                &lv,
                texels,
                soft.as_ref(),
            )?;
            let faces = lv.face_count();
            let mut stats = match &soft {
                Some(sl) => soft_stats(&out, texels, faces, sl),
                None => hard_stats(&out, texels, faces),
            };
            stats["wall_ms"] = serde_json::json!(t_light.elapsed().as_secs_f64() * 1e3);
            let path = match &out.soft {
                Some(so) => {
                    visibility.push(so.visibility.iter().map(|v| v.unwrap_or(0.0)).collect());
                    evaluated.push(so.visibility.iter().map(|v| v.is_some()).collect());
                    "gpu soft shadows"
                }
                None => {
                    visibility.push(
                        out.lit
                            .iter()
                            .map(|l| if *l == Some(true) { 1.0 } else { 0.0 })
                            .collect(),
                    );
                    evaluated.push(out.lit.iter().map(|l| l.is_some()).collect());
                    "gpu hard shadows"
                }
            };
            light_stats.push(serde_json::json!({"light": k, "path": path, "stats": stats}));
            light_samples.push(samples);
        }
        let t = Instant::now();
        let image = shade(&view, &desc.lights, &visibility);
        let shade_ms = t.elapsed().as_secs_f64() * 1e3;
        let stats = serde_json::json!({
            "device": self.ctx.info().name,
            "scene": desc.name,
            "settings": desc.shadows,
            "width": desc.camera.width,
            "height": desc.camera.height,
            "ms": { "view_samples_gpu": view_ms, "shade_cpu": shade_ms },
            "lights": light_stats,
            "total_ms": t0.elapsed().as_secs_f64() * 1e3,
            "counters": {
                "triangles": triangles.len(),
                "view_samples": gpu_view.iter().filter(|s| s.flags != 0).count(),
            }
        });
        let dump = make_dump(desc, &view, &light_samples, &visibility, &evaluated, stats);
        Ok(Frame { dump, image, view })
    }
}
