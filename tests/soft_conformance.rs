//! Issue-4 conformance: the GPU soft-shadow path (lavapipe, validation on)
//! against the CPU oracle fed exactly the engine's view samples and light
//! samples, per (pixel, light sample) pair.

use alias_free_shadows::light::{Light, LightSamples};
use alias_free_shadows::oracle::{Oracle, ViewSamples};
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::{self, SceneDescription, ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;

/// The engine's view samples as the oracle sees them: camera-relative f32
/// positions and normals converted back, exactly.
fn engine_view_samples(oracle: &Oracle, desc: &SceneDescription) -> ViewSamples {
    let eye = desc.camera.eye;
    let mut view = oracle.primary_view_samples(&desc.camera);
    for s in view.samples.iter_mut().flatten() {
        s.position = eye + (s.position - eye).as_vec3().as_dvec3();
        s.normal = s.normal.as_vec3().as_dvec3();
    }
    view
}

/// The light samples as the engine has them (camera-relative f32), back in world space.
fn engine_light(light: &Light, eye: glam::DVec3) -> LightSamples {
    match light.light_samples() {
        LightSamples::Positions(p) => LightSamples::Positions(
            p.iter()
                .map(|q| eye + (*q - eye).as_vec3().as_dvec3())
                .collect(),
        ),
        d => d,
    }
}

struct Agreement {
    pairs: u64,
    disagree: u64,
    rmse: f64,
    pixels: usize,
}

fn agreement(
    engine: &mut Engine,
    desc: &SceneDescription,
    light: &Light,
    mode: SoftMode,
) -> Agreement {
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, desc);
    let settings = ShadowSettings {
        mode,
        ..Default::default()
    };
    let r = engine
        .soft_shadows(&desc.scene, eye, &view.samples, light, &settings)
        .unwrap();
    let ls = engine_light(light, eye);
    let want = oracle.visibility_masks(&view, &ls);
    let n = ls.len();
    let (mut pairs, mut disagree, mut se, mut pixels) = (0u64, 0u64, 0.0f64, 0usize);
    for (i, s) in view.samples.iter().enumerate() {
        if s.is_none() {
            continue;
        }
        pixels += 1;
        let words = &r.visible[i * r.mask_words..(i + 1) * r.mask_words];
        let mut got_count = 0;
        let mut want_count = 0;
        for j in 0..n {
            let got = words[j / 32] >> (j % 32) & 1 == 1;
            let w = want[i][j / 64] >> (j % 64) & 1 == 1;
            pairs += 1;
            disagree += (got != w) as u64;
            got_count += got as usize;
            want_count += w as usize;
        }
        let d = (got_count as f64 - want_count as f64) / n as f64;
        se += d * d;
    }
    Agreement {
        pairs,
        disagree,
        rmse: (se / pixels.max(1) as f64).sqrt(),
        pixels,
    }
}

#[test]
fn builtins_conform_in_exact_and_lut_modes() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for name in ["demo"] {
        let mut desc = file::load(&format!("builtin:{name}")).unwrap();
        desc.camera.width = 64;
        desc.camera.height = 64;
        let light = desc.lights[0].clone();
        for mode in [SoftMode::Exact, SoftMode::Lut] {
            let a = agreement(&mut engine, &desc, &light, mode);
            eprintln!(
                "{name} {mode:?}: {} pixels, {} of {} pairs disagree ({:.2e}), visibility RMSE {:.2e}",
                a.pixels, a.disagree, a.pairs, a.disagree as f64 / a.pairs as f64, a.rmse
            );
        }
    }
    engine.context().check_validation().unwrap();
}
