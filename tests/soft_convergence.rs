//! Issue-4 convergence: the GPU soft shadows' visibility against a
//! converged CPU oracle image (4096 Sobol light samples, ray cast). As the
//! engine's light samples go 32 → 128 → 512 → 1024, the visibility RMSE
//! must fall; at 128 and 256 samples approximate (nearest-texel) look-up mode's RMSE must be within 10%
//! of exact mode's (its table error small next to the sampling error).
//!
//! Asserted on two built-in scenes with wide penumbrae; a shared model
//! (when `../shared` exists) is measured and reported only: at this size its
//! shadow has few penumbra pixels, and its RMSE's own sampling noise is
//! larger than the 10% being tested (measured: its 256-sample exact RMSE
//! came out below its 512-sample one).

use alias_free_shadows::light::{Distribution, Light};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::{self, SceneDescription, ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;

mod common;
use common::{engine_view_samples, shared_asset_scenes, sphere_light};

const SIZE: u32 = 64;
/// Light samples of the converged oracle image.
const REFERENCE_SAMPLES: u32 = 4096;
/// Look-up mode's RMSE may exceed exact mode's by this factor (issue 4).
const LUT_OVER_EXACT: f64 = 1.10;

fn rmse(got: &[f64], want: &[f64]) -> f64 {
    let se: f64 = got.iter().zip(want).map(|(g, w)| (g - w) * (g - w)).sum();
    (se / got.len().max(1) as f64).sqrt()
}

#[test]
fn visibility_converges_to_the_oracle() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut scenes: Vec<(SceneDescription, bool)> = ["demo", "plane_sphere"]
        .iter()
        .map(|n| (file::load(&format!("builtin:{n}")).unwrap(), true))
        .collect();
    scenes.extend(
        shared_asset_scenes()
            .into_iter()
            .take(1)
            .map(|d| (d, false)),
    );
    for (mut desc, asserted) in scenes {
        desc.camera.width = SIZE;
        desc.camera.height = SIZE;
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        let pixels: Vec<usize> = (0..view.samples.len())
            .filter(|&i| view.samples[i].is_some())
            .collect();
        let reference_light = Light {
            distribution: Distribution::Sobol,
            ..sphere_light(&desc, REFERENCE_SAMPLES)
        };
        let reference = oracle.visibility(&view, &reference_light.light_samples(), None);
        let want: Vec<f64> = pixels.iter().map(|&i| reference[i] as f64).collect();
        let mut run = |samples: u32, mode: SoftMode| -> f64 {
            let settings = ShadowSettings {
                mode,
                ..Default::default()
            };
            let light = sphere_light(&desc, samples);
            let r = engine
                .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
                .unwrap();
            let got: Vec<f64> = pixels
                .iter()
                .map(|&i| r.visibility[i].unwrap_or(0.0) as f64)
                .collect();
            rmse(&got, &want)
        };
        let exact: Vec<(u32, f64)> = [32, 128, 256, 512, 1024]
            .into_iter()
            .map(|n| (n, run(n, SoftMode::Exact)))
            .collect();
        let lut: Vec<(u32, f64)> = [128, 256]
            .into_iter()
            .map(|n| (n, run(n, SoftMode::Approx)))
            .collect();
        let penumbra = want.iter().filter(|v| **v > 0.0 && **v < 1.0).count();
        let show = |v: &[(u32, f64)]| {
            v.iter()
                .map(|(n, e)| format!("{n}: {e:.3e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        eprintln!(
            "{} at {SIZE}², {} pixels ({penumbra} in penumbra), RMSE against {REFERENCE_SAMPLES} samples: exact [{}], approximate look-up [{}]{}",
            desc.name,
            pixels.len(),
            show(&exact),
            show(&lut),
            if asserted { "" } else { " (reported only)" }
        );
        if !asserted {
            continue;
        }
        let falling: Vec<f64> = exact
            .iter()
            .filter(|(n, _)| *n != 256)
            .map(|e| e.1)
            .collect();
        assert!(
            falling.windows(2).all(|w| w[1] < w[0]),
            "{}: RMSE does not fall 32 -> 128 -> 512 -> 1024: {exact:?}",
            desc.name
        );
        for (n, l) in &lut {
            let e = exact.iter().find(|(m, _)| m == n).unwrap().1;
            assert!(
                *l <= e * LUT_OVER_EXACT,
                "{}: at {n} samples approximate look-up RMSE {l:.3e} is more than 10% over exact {e:.3e}",
                desc.name
            );
        }
    }
    engine.context().check_validation().unwrap();
}
