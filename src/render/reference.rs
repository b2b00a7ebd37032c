//! The CPU oracle's frame ([`render_reference`]): primary rays for the view
//! samples, shadow rays for visibility; the reference every GPU frame is
//! compared to.

use std::time::Instant;

use super::dump_assembly::make_dump;
use super::{Frame, FrameOptions};
use crate::light::channel_visibility;
use crate::light::LightSamples;
use crate::oracle::{Oracle, ViewSamples};
use crate::scene::file::SceneDescription;
use crate::shade::{faces_light, shade_coloured};
use crate::stats::{ReferenceCounters, ReferenceMs, ReferenceStats, Stats};
use crate::Result;

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
    let mut visibility_rgb = Vec::new();
    let mut evaluated = Vec::new();
    let mut shadow_ms = Vec::new();
    for (k, light) in desc.lights.iter().enumerate() {
        let samples = light.light_samples();
        let t = Instant::now();
        // (A textured light is never turned: Light::validate.)
        let rotation = light.pixel_rotation(desc.camera.eye);
        let (vis, ev, rgb) = match light.sample_colors() {
            Some(colors) => oracle_coloured_light(&oracle, &view, &samples, &colors),
            None => {
                let rot = rotation.as_ref();
                let (vis, ev) = oracle_light(&oracle, &view, &samples, rot, k, options.progress);
                (vis, ev, None)
            }
        };
        shadow_ms.push(t.elapsed().as_secs_f64() * 1e3);
        evaluated.push(ev);
        visibility.push(vis);
        visibility_rgb.push(rgb);
        light_samples.push(samples);
    }
    let t2 = Instant::now();
    let normals = crate::shade::ShadingNormals::new(&desc.scene);
    let image = shade_coloured(
        &desc.scene,
        &normals,
        &view,
        &desc.lights,
        &crate::shade::light_colors(&desc.lights),
        &visibility,
        &visibility_rgb,
    );
    let shade_ms = t2.elapsed().as_secs_f64() * 1e3;
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    let shadow_rays = oracle.shadow_rays_cast();
    let shadow_total: f64 = shadow_ms.iter().sum();
    let stats = Stats::Reference(ReferenceStats {
        device: "cpu oracle (ray casting)".into(),
        scene: desc.name.clone(),
        settings: desc.shadows,
        width: desc.camera.width,
        height: desc.camera.height,
        ms: ReferenceMs {
            bvh: bvh_ms,
            view_samples: view_ms,
            shadow_rays_per_light: shadow_ms,
            shade: shade_ms,
        },
        total_ms,
        counters: ReferenceCounters {
            triangles: triangles.len(),
            view_samples: view_sample_count,
            light_samples: light_samples.iter().map(|s| s.len()).collect(),
            shadow_rays,
            shadow_rays_per_second: if shadow_total > 0.0 {
                shadow_rays as f64 / (shadow_total / 1e3)
            } else {
                0.0
            },
            threads: rayon::current_num_threads(),
        },
    });
    let dump = make_dump(
        desc,
        &view,
        &light_samples,
        &visibility,
        &visibility_rgb,
        &evaluated,
        &stats,
    );
    Ok(Frame {
        dump,
        image,
        view,
        stats,
    })
}

/// One light's visibility from the oracle, with the "evaluated" flags (a
/// sample facing away from the whole light is decided without shadow rays);
/// with a `rotation`, each pixel sees the samples turned by its angle.
fn oracle_light(
    oracle: &Oracle,
    view: &ViewSamples,
    samples: &LightSamples,
    rotation: Option<&crate::light::PixelRotation>,
    k: usize,
    progress: bool,
) -> (Vec<f32>, Vec<bool>) {
    let turned = if rotation.is_some() {
        ", turned per pixel"
    } else {
        ""
    };
    let pb = progress_bar(
        view.height as u64,
        &format!("oracle light {k} ({} samples{turned})", samples.len()),
        progress,
    );
    let vis = match (rotation, samples) {
        (Some(rot), LightSamples::Positions(points)) => {
            oracle.visibility_rotated(view, points, rot, pb.as_ref())
        }
        _ => oracle.visibility(view, samples, pb.as_ref()),
    };
    if let Some(pb) = pb {
        pb.finish_and_clear();
    }
    let table = crate::light::pixel_rotation_table();
    let evaluated = view
        .samples
        .iter()
        .enumerate()
        .map(|(i, s)| {
            s.is_some_and(|s| match (rotation, samples) {
                (Some(rot), LightSamples::Positions(points)) => points
                    .iter()
                    .map(|&l| rot.turn(l, i as u32, &table))
                    .any(|l| s.normal.dot(l - s.position) > 0.0),
                _ => faces_light(s.position, s.normal, samples),
            })
        })
        .collect();
    (vis, evaluated)
}

/// A light with an emission texture: the oracle's masks give both the
/// visible fraction and each channel's visible share of the emission
/// (`colors`: per light sample).
#[allow(clippy::type_complexity)]
fn oracle_coloured_light(
    oracle: &Oracle,
    view: &ViewSamples,
    samples: &LightSamples,
    colors: &[[f32; 3]],
) -> (Vec<f32>, Vec<bool>, Option<Vec<[f32; 3]>>) {
    let masks = oracle.visibility_masks(view, samples);
    let n = samples.len();
    let bit = |m: &[u64], j: usize| m[j / 64] >> (j % 64) & 1 == 1;
    let vis = masks
        .iter()
        .map(|m| match m.is_empty() || n == 0 {
            true => 0.0,
            false => ((0..n).filter(|&j| bit(m, j)).count() as f64 / n as f64) as f32,
        })
        .collect();
    let rgb = masks
        .iter()
        .map(|m| match m.is_empty() {
            true => [0.0; 3],
            false => channel_visibility(colors, |j| bit(m, j)),
        })
        .collect();
    let evaluated = view
        .samples
        .iter()
        .map(|s| s.is_some_and(|s| faces_light(s.position, s.normal, samples)))
        .collect();
    (vis, evaluated, Some(rgb))
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
