//! The dump of a frame (`--dump`): per-pixel view samples and visibility,
//! the scene and the statistics, from the frame's CPU-side results.

use rayon::prelude::*;

use super::super::dump::{Dump, DumpLight, DumpScene};
use crate::light::LightSamples;
use crate::oracle::ViewSamples;
use crate::scene::file::SceneDescription;
use crate::stats::Stats;

/// Builds the dump's per-pixel arrays from view samples and per-light visibility.
pub fn make_dump(
    desc: &SceneDescription,
    view: &ViewSamples,
    light_samples: &[LightSamples],
    visibility: &[Vec<f32>],
    visibility_rgb: &[Option<Vec<[f32; 3]>>],
    evaluated: &[Vec<bool>],
    stats: &Stats,
) -> Dump {
    let eye = desc.camera.eye;
    // Every frame builds its dump (a few ms per megapixel): on both cores.
    let (position, normal): (Vec<[f32; 4]>, Vec<[f32; 4]>) = view
        .samples
        .par_iter()
        .map(|s| match s {
            Some(s) => {
                let p = s.position - eye;
                (
                    [p.x as f32, p.y as f32, p.z as f32, 1.0],
                    [s.normal.x as f32, s.normal.y as f32, s.normal.z as f32, 1.0],
                )
            }
            None => ([0.0; 4], [0.0; 4]),
        })
        .unzip();
    let vis = visibility
        .iter()
        .zip(evaluated)
        .map(|(v, e)| {
            view.samples
                .par_iter()
                .enumerate()
                .map(|(i, s)| match s {
                    Some(_) => [v[i], if e[i] { 1.0 } else { 0.0 }, 0.0, 1.0],
                    None => [0.0; 4],
                })
                .collect()
        })
        .collect();
    let rgb = visibility_rgb
        .iter()
        .map(|v| {
            v.as_ref().map(|v| {
                view.samples
                    .iter()
                    .zip(v)
                    .map(|(s, c)| match s {
                        Some(_) => [c[0], c[1], c[2], 1.0],
                        None => [0.0; 4],
                    })
                    .collect()
            })
        })
        .collect();
    Dump {
        width: view.width,
        height: view.height,
        position,
        normal,
        visibility: vis,
        visibility_rgb: rgb,
        scene: DumpScene {
            camera: desc.camera,
            lights: desc
                .lights
                .iter()
                .zip(light_samples)
                .map(|(l, s)| DumpLight::new(l, s, desc.camera.eye))
                .collect(),
            frames: Vec::new(),
        },
        stats: stats.to_json(),
    }
}
