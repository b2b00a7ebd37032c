//! The light-texel resolution decides only how the work is cut, never the
//! answer: the texel lists and the casters' influence regions are
//! conservative at any texel size. So the automatic resolution
//! (`LightTexels::Auto`, the default) and fixed ones, coarse and fine, must
//! give the same lit flags (hard) and the same light-sample masks (soft,
//! exact and look-up modes), bit for bit; and each run is checked against
//! the CPU oracle, so that agreeing runs cannot all be wrong the same way.

use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::oracle::{LightTarget, Oracle};
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::{
    self, LightTexels, SceneDescription, ShadowSettings, SoftMode,
};
use alias_free_shadows::vulkan::ContextOptions;

mod common;
use common::{bands, engine_light, engine_view_samples, sphere_light, words_differ};

/// Exact mode's share of (pixel, light sample) pairs that may disagree with
/// the oracle (tests/soft_conformance.rs, issue 4).
const EXACT_SHARE: f64 = 1e-4;

fn target(light: &Light) -> LightTarget {
    match &light.shape {
        LightShape::Point { position } => LightTarget::Point(*position),
        LightShape::Directional { direction } => LightTarget::Direction(*direction),
        _ => unreachable!("hard shadows take point and directional lights"),
    }
}

const SIZE: u32 = 48;

fn scene(spec: &str) -> SceneDescription {
    let mut d = file::load(spec).unwrap();
    d.camera.width = SIZE;
    d.camera.height = SIZE;
    d
}

/// Built-ins with large and small casters, an alpha-tested lattice and a
/// dense mesh (many casters per texel at coarse resolutions).
const SCENES: [&str; 4] = [
    "builtin:demo",
    "builtin:fence",
    "builtin:plane_sphere",
    "builtin:torus_knot:6000",
];

/// Fixed resolutions on both sides of what Auto picks at this size.
const FIXED: [u32; 3] = [8, 128, 512];

#[test]
fn hard_shadows_do_not_depend_on_the_light_texels() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for spec in SCENES {
        let desc = scene(spec);
        let eye = desc.camera.eye;
        // A point light where the scene's light is (some built-ins light
        // with a sphere).
        let light = &Light {
            shape: LightShape::Point {
                position: desc.lights[0]
                    .center()
                    .expect("the scene's light has a centre"),
            },
            samples: 1,
            ..desc.lights[0].clone()
        };
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        let want = oracle.visibility(&view, &light.light_samples(), None);
        let auto = engine
            .hard_shadows(&desc.scene, eye, &view.samples, light, LightTexels::Auto)
            .unwrap();
        let picked = auto.stats.light_texels;
        assert!(!FIXED.contains(&picked), "{spec}: auto picked {picked}");
        // Against the oracle, as tests/hard_conformance.rs: only samples in
        // an epsilon band may disagree.
        let mut outside_band = 0;
        for (i, s) in view.samples.iter().enumerate() {
            let Some(s) = s else { continue };
            let lit = auto.lit[i] == Some(true);
            if lit != (want[i] > 0.5)
                && !bands::in_any_band(&oracle, &desc.scene, eye, s, target(light))
            {
                outside_band += 1;
            }
        }
        assert_eq!(
            outside_band, 0,
            "{spec}: auto ({picked}) against the oracle"
        );
        for texels in FIXED {
            let fixed = engine
                .hard_shadows(&desc.scene, eye, &view.samples, light, texels)
                .unwrap();
            assert_eq!(fixed.stats.light_texels, texels);
            let differ = auto
                .lit
                .iter()
                .zip(&fixed.lit)
                .filter(|(a, b)| a != b)
                .count();
            eprintln!("{spec}: hard, auto ({picked}) against {texels}: {differ} flags differ");
            assert_eq!(differ, 0, "{spec}: hard, auto ({picked}) against {texels}");
        }
    }
    engine.context().check_validation().unwrap();
}

#[test]
fn soft_masks_do_not_depend_on_the_light_texels() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for spec in SCENES {
        let desc = scene(spec);
        let eye = desc.camera.eye;
        let light = sphere_light(&desc, 128);
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        let ls = engine_light(&light, eye);
        let want = oracle.visibility_masks(&view, &ls);
        for mode in [SoftMode::Exact, SoftMode::Lut] {
            let run = |engine: &mut Engine, texels: LightTexels| {
                let settings = ShadowSettings {
                    mode,
                    soft_light_texels: texels,
                    ..Default::default()
                };
                engine
                    .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
                    .unwrap()
            };
            let auto = run(&mut engine, LightTexels::Auto);
            let picked = auto.stats.light_texels;
            assert!(!FIXED.contains(&picked), "{spec}: auto picked {picked}");
            // Against the oracle per (pixel, light sample) pair, with
            // tests/soft_conformance.rs's band.
            let (mut pairs, mut disagree) = (0u64, 0u64);
            for (i, s) in view.samples.iter().enumerate() {
                if s.is_none() {
                    continue;
                }
                let words = &auto.visible[i * auto.mask_words..(i + 1) * auto.mask_words];
                for j in 0..ls.len() {
                    let got = words[j / 32] >> (j % 32) & 1 == 1;
                    let w = want[i][j / 64] >> (j % 64) & 1 == 1;
                    pairs += 1;
                    disagree += (got != w) as u64;
                }
            }
            assert!(pairs > 0, "{spec}: no view samples");
            let share = disagree as f64 / pairs as f64;
            assert!(
                share <= EXACT_SHARE,
                "{spec} {mode:?}: auto ({picked}): {disagree} of {pairs} pairs off the oracle"
            );
            for texels in FIXED {
                let fixed = run(&mut engine, LightTexels::Fixed(texels));
                let differ = words_differ(&auto.visible, &fixed.visible);
                eprintln!(
                    "{spec}: soft {mode:?}, auto ({picked}) against {texels}: {differ} mask words differ"
                );
                assert_eq!(
                    differ, 0,
                    "{spec} {mode:?}: auto ({picked}) against {texels}"
                );
            }
        }
    }
    engine.context().check_validation().unwrap();
}
