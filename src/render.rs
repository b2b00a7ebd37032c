//! A frame, top to bottom. Until the GPU passes exist, the frame's
//! visibility comes from the CPU oracle ([`render_reference`]); the GPU
//! pipeline will list its passes here in the same order:
//!
//! 1. view samples (what the camera sees);
//! 2. per-light-texel lists of view samples (count, scan, scatter);
//! 3. each caster's influence region, conservatively rasterized;
//! 4. occlusion of every listed view sample by every covering caster;
//! 5. visibility = visible light samples / light samples, then shading.

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

/// Renders a frame with the CPU oracle: primary rays for the view samples,
/// shadow rays for visibility. The reference every GPU frame is compared to.
pub fn render_reference(desc: &SceneDescription, options: FrameOptions) -> Result<Frame> {
    desc.validate()?;
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
        let pb = progress_bar(
            view.height as u64,
            &format!("oracle light {k} ({} samples)", samples.len()),
            options.progress,
        );
        let vis = oracle.visibility(&view, &samples, pb.as_ref());
        if let Some(pb) = pb {
            pb.finish_and_clear();
        }
        shadow_ms.push(t.elapsed().as_secs_f64() * 1e3);
        evaluated.push(
            view.samples
                .iter()
                .map(|s| s.is_some_and(|s| faces_light(s.position, s.normal, &samples)))
                .collect(),
        );
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
    Ok(Frame { dump, image })
}
