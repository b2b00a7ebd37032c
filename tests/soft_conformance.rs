//! Issue-4 conformance: the GPU soft-shadow path (lavapipe, validation on)
//! against the CPU oracle fed exactly the engine's view samples and light
//! samples, per (pixel, light sample) pair.

use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::{self, SceneDescription, ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;
use glam::DVec3;

mod common;
use common::{
    engine_light, engine_view_samples, scaled_and_moved, shared_asset_scenes, sphere_light,
    SCALE_CASES,
};

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

/// Exact mode: the largest share of (pixel, light sample) pairs that may
/// disagree with the oracle (issue 4).
const EXACT_SHARE: f64 = 1e-4;
/// Look-up mode at 128³: the aim for the same share. Reported, not
/// asserted: the aim is not met on every scene yet (README, status).
const LUT_SHARE: f64 = 1e-3;
/// Test resolution (the suite's budget; benches use 512²).
const SIZE: u32 = 48;

fn sized(mut desc: SceneDescription) -> SceneDescription {
    desc.camera.width = SIZE;
    desc.camera.height = SIZE;
    desc
}

/// The scene's light with extent, or a sphere (radius 5% of the scene's
/// diagonal) where its point light is.
fn area_light(desc: &SceneDescription) -> Light {
    let l = &desc.lights[0];
    if l.is_area() {
        return l.clone();
    }
    sphere_light(desc, 128)
}

fn scenes() -> Vec<SceneDescription> {
    let mut out: Vec<SceneDescription> = alias_free_shadows::scene::builtin::NAMES
        .iter()
        .map(|n| file::load(&format!("builtin:{n}")).unwrap())
        .collect();
    out.extend(shared_asset_scenes());
    out
}

#[test]
fn every_scene_conforms_in_every_mode() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut lut_over = Vec::new();
    for desc in scenes() {
        let desc = sized(desc);
        let light = area_light(&desc);
        for mode in [SoftMode::Exact, SoftMode::Lut, SoftMode::Approx] {
            let a = agreement(&mut engine, &desc, &light, mode);
            let share = a.disagree as f64 / a.pairs.max(1) as f64;
            eprintln!(
                "{} {mode:?} at {SIZE}²: {} pixels, {} of {} (pixel, light sample) pairs disagree ({share:.2e}), visibility RMSE {:.2e}",
                desc.name, a.pixels, a.disagree, a.pairs, a.rmse
            );
            assert!(a.pixels > 0);
            match mode {
                // Look-up mode has exact mode's masks.
                SoftMode::Exact | SoftMode::Lut => assert!(
                    share <= EXACT_SHARE,
                    "{}: {mode:?} mode disagrees on {share:.2e} of the pairs",
                    desc.name
                ),
                SoftMode::Approx => {
                    if share > LUT_SHARE {
                        lut_over.push(format!("{} {share:.2e}", desc.name));
                    }
                }
            }
        }
    }
    engine.context().check_validation().unwrap();
    eprintln!("approximate mode above its aim of {LUT_SHARE:.0e}: {lut_over:?}");
}

#[test]
fn every_light_kind_conforms() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = sized(file::load("builtin:demo").unwrap());
    let base = desc.lights[0].clone();
    let p = base.center().unwrap();
    let tilt = DVec3::new(0.3, -1.0, 0.2).normalize();
    let kinds = [
        LightShape::Sphere {
            position: p,
            radius: 0.6,
        },
        LightShape::Ellipsoid {
            position: p,
            semi_axes: DVec3::new(0.9, 0.3, 0.5),
            normal: tilt,
            tangent: DVec3::new(1.0, 0.3, 0.0).normalize(),
        },
        LightShape::Disk {
            position: p,
            radius: 0.7,
            normal: tilt,
            tangent: DVec3::new(1.0, 0.0, 0.3).normalize(),
        },
        LightShape::Rect {
            position: p,
            size: glam::DVec2::new(1.2, 0.5),
            normal: tilt,
            tangent: DVec3::new(1.0, 0.3, 0.0).normalize(),
        },
        LightShape::Explicit {
            positions: (0..40)
                .map(|k| {
                    p + DVec3::new(
                        (k % 7) as f64 * 0.1,
                        (k / 7) as f64 * 0.08,
                        (k % 3) as f64 * 0.15,
                    )
                })
                .collect(),
        },
    ];
    for shape in kinds {
        let mut light = Light {
            shape,
            ..base.clone()
        };
        if let LightShape::Explicit { positions } = &light.shape {
            light.samples = positions.len() as u32;
        }
        light.validate().unwrap();
        let a = agreement(&mut engine, &desc, &light, SoftMode::Exact);
        let share = a.disagree as f64 / a.pairs.max(1) as f64;
        let kind = format!("{:?}", light.shape);
        let kind = kind.split([' ', '{']).next().unwrap_or("");
        eprintln!(
            "{kind} light: {} of {} pairs disagree ({share:.2e}), RMSE {:.2e}",
            a.disagree, a.pairs, a.rmse
        );
        assert!(a.pairs > 0);
        assert!(share <= EXACT_SHARE, "{:?}: {share:.2e}", light.shape);
    }
    engine.context().check_validation().unwrap();
}

/// One explicit light sample is a point light: the soft pipeline must give
/// the hard path's answer at every view sample.
#[test]
fn a_one_sample_light_equals_the_hard_path() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for spec in ["builtin:demo", "builtin:fence", "builtin:hairball"] {
        let desc = sized(file::load(spec).unwrap());
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        let p = desc.lights[0].center().unwrap();
        let point = Light {
            shape: LightShape::Point { position: p },
            samples: 1,
            ..desc.lights[0].clone()
        };
        let one = Light {
            shape: LightShape::Explicit { positions: vec![p] },
            samples: 1,
            ..desc.lights[0].clone()
        };
        let hard = engine
            .hard_shadows(&desc.scene, eye, &view.samples, &point, 512)
            .unwrap();
        let settings = ShadowSettings {
            mode: SoftMode::Exact,
            ..Default::default()
        };
        let soft = engine
            .soft_shadows(&desc.scene, eye, &view.samples, &one, &settings)
            .unwrap();
        let mut differ = 0;
        let mut lit = 0;
        for i in 0..view.samples.len() {
            let h = hard.lit[i] == Some(true);
            let s = soft.visible[i * soft.mask_words] & 1 == 1;
            differ += (h != s) as usize;
            lit += h as usize;
        }
        eprintln!("{spec}: {lit} lit, {differ} differ");
        assert!(lit > 0);
        assert_eq!(
            differ, 0,
            "{spec}: the one-sample soft result differs from the hard path"
        );
    }
    engine.context().check_validation().unwrap();
}

/// Issue 5, scale: soft shadows of the same scene 1e-4 and 1e5 times its
/// size and 1e4 units from the origin agree with the oracle in exact mode as
/// well as at the origin.
#[test]
fn scaled_and_distant_scenes_conform() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for name in ["demo", "stairs"] {
        let mut base = sized(file::load(&format!("builtin:{name}")).unwrap());
        base.lights = vec![area_light(&base)];
        for (scale, offset) in SCALE_CASES {
            let desc = scaled_and_moved(&base, scale, offset);
            let light = desc.lights[0].clone();
            let a = agreement(&mut engine, &desc, &light, SoftMode::Exact);
            let share = a.disagree as f64 / a.pairs.max(1) as f64;
            eprintln!(
                "{}: {} of {} pairs disagree ({share:.2e})",
                desc.name, a.disagree, a.pairs
            );
            assert!(a.pixels > 0);
            assert!(share <= EXACT_SHARE, "{}: {share:.2e}", desc.name);
        }
    }
    engine.context().check_validation().unwrap();
}

/// Issue 5, load: over a million triangles (a torus knot) at 32² under a
/// 64-sample sphere light, exact mode, against the oracle (the caster
/// buffers pass the binding limit: the triangles run in batches).
#[test]
fn a_million_triangles_conform() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut desc = file::load("builtin:torus_knot:1100000").unwrap();
    // Smaller than the other scenes: the suite's time budget.
    desc.camera.width = 32;
    desc.camera.height = 32;
    let triangles = desc.scene.triangle_count();
    assert!(triangles >= 1_000_000, "{triangles} triangles");
    let light = Light {
        samples: 64,
        ..area_light(&desc)
    };
    let a = agreement(&mut engine, &desc, &light, SoftMode::Exact);
    let share = a.disagree as f64 / a.pairs.max(1) as f64;
    eprintln!(
        "torus knot, {triangles} triangles: {} of {} pairs disagree ({share:.2e}), RMSE {:.2e}",
        a.disagree, a.pairs, a.rmse
    );
    assert!(a.pixels > 0);
    assert!(share <= EXACT_SHARE, "{share:.2e}");
    engine.context().check_validation().unwrap();
}

/// Issue 5, load: view samples whose masks would pass the device's binding
/// limit run in batches. Forced here with a small batch: the batched
/// results equal the single run's, bit for bit in exact mode and sample for
/// sample in hard shadows. In look-up mode a batch has its own light-window
/// fit, so its influence regions cover other texels, and a triangle that
/// hides no light sample exactly may still return look-up bits where its
/// region reaches (see tests/soft_shadows.rs): a few words may differ there,
/// counted and bounded by the look-up aim.
#[test]
fn batched_runs_equal_one_run() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = sized(file::load("builtin:demo").unwrap());
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, &desc);
    let light = Light {
        samples: 200,
        ..area_light(&desc)
    };
    for mode in [SoftMode::Exact, SoftMode::Lut, SoftMode::Approx] {
        let settings = ShadowSettings {
            mode,
            ..Default::default()
        };
        engine.set_view_sample_batch_limit(None);
        let one = engine
            .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
            .unwrap();
        engine.set_view_sample_batch_limit(Some(700));
        let batched = engine
            .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
            .unwrap();
        assert_eq!(one.visible.len(), batched.visible.len());
        let differ = one
            .visible
            .iter()
            .zip(&batched.visible)
            .filter(|(a, b)| a != b)
            .count();
        eprintln!(
            "{mode:?}: {} mask words, {differ} differ between one run and batches of 700",
            one.visible.len()
        );
        match mode {
            SoftMode::Exact | SoftMode::Lut => assert_eq!(differ, 0),
            SoftMode::Approx => {
                assert!(differ as f64 <= LUT_SHARE * one.visible.len() as f64)
            }
        }
    }
    let point = Light {
        shape: LightShape::Point {
            position: desc.lights[0].center().unwrap(),
        },
        ..desc.lights[0].clone()
    };
    engine.set_view_sample_batch_limit(None);
    let one = engine
        .hard_shadows(&desc.scene, eye, &view.samples, &point, 256)
        .unwrap();
    engine.set_view_sample_batch_limit(Some(700));
    let batched = engine
        .hard_shadows(&desc.scene, eye, &view.samples, &point, 256)
        .unwrap();
    assert_eq!(one.lit, batched.lit);
    engine.set_view_sample_batch_limit(None);
    engine.context().check_validation().unwrap();
}

/// A frame reads no light-sample masks back (only a textured light's
/// colours use them): its visibility equals, bit for bit, the library's
/// soft shadows of the frame's own view samples, which do read them, in
/// one run, in triangle batches (whose AND still needs each batch's masks)
/// and in view-sample batches.
#[test]
fn frames_without_masks_keep_their_visibility() {
    use alias_free_shadows::render::FrameOptions;
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut desc = sized(file::load("builtin:demo").unwrap());
    let light = Light {
        samples: 200,
        ..area_light(&desc)
    };
    desc.lights = vec![light.clone()];
    let eye = desc.camera.eye;
    let batch = desc.scene.triangle_count() / 3 + 1;
    for (triangles, samples) in [(None, None), (Some(batch), None), (None, Some(700))] {
        engine.set_triangle_batch_limit(triangles);
        engine.set_view_sample_batch_limit(samples);
        for mode in [SoftMode::Exact, SoftMode::Lut] {
            desc.shadows.mode = mode;
            let frame = engine.render(&desc, FrameOptions::default()).unwrap();
            let library = engine
                .soft_shadows(&desc.scene, eye, &frame.view.samples, &light, &desc.shadows)
                .unwrap();
            assert!(!library.visible.is_empty(), "the library's masks");
            let want: Vec<f32> = library
                .visibility
                .iter()
                .map(|v| v.unwrap_or(0.0))
                .collect();
            let got: Vec<f32> = frame.dump.visibility[0].iter().map(|p| p[0]).collect();
            let what = format!("{mode:?}, batches {triangles:?} triangles, {samples:?} samples");
            assert_eq!(got.len(), want.len(), "{what}");
            let differ = got
                .iter()
                .zip(&want)
                .filter(|(a, b)| a.to_bits() != b.to_bits())
                .count();
            assert_eq!(differ, 0, "{what}: pixels whose visibility differs");
        }
    }
    engine.set_triangle_batch_limit(None);
    engine.set_view_sample_batch_limit(None);
    engine.context().check_validation().unwrap();
}

/// Issue 5, load: triangles whose caster buffers would pass the device's
/// binding limit (over a million here) run in batches whose masks are
/// ANDed. Forced here with small batches (a sample's own triangle must be
/// skipped by global id across batches): the batched results equal the
/// single run's bit for bit, in both modes and for hard shadows.
#[test]
fn triangle_batches_equal_one_run() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = sized(file::load("builtin:demo").unwrap());
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, &desc);
    let light = Light {
        samples: 200,
        ..area_light(&desc)
    };
    let batch = desc.scene.triangle_count() / 3 + 1;
    for mode in [SoftMode::Exact, SoftMode::Lut, SoftMode::Approx] {
        let settings = ShadowSettings {
            mode,
            ..Default::default()
        };
        engine.set_triangle_batch_limit(None);
        let one = engine
            .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
            .unwrap();
        engine.set_triangle_batch_limit(Some(batch));
        let batched = engine
            .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
            .unwrap();
        let differ = one
            .visible
            .iter()
            .zip(&batched.visible)
            .filter(|(a, b)| a != b)
            .count();
        eprintln!(
            "{mode:?}: {} mask words, {differ} differ between one run and batches of {batch} triangles",
            one.visible.len()
        );
        assert_eq!(one.visible.len(), batched.visible.len());
        assert_eq!(differ, 0);
        assert_eq!(one.visibility, batched.visibility);
    }
    let point = Light {
        shape: LightShape::Point {
            position: desc.lights[0].center().unwrap(),
        },
        ..desc.lights[0].clone()
    };
    engine.set_triangle_batch_limit(None);
    let one = engine
        .hard_shadows(&desc.scene, eye, &view.samples, &point, 256)
        .unwrap();
    engine.set_triangle_batch_limit(Some(batch));
    let batched = engine
        .hard_shadows(&desc.scene, eye, &view.samples, &point, 256)
        .unwrap();
    assert_eq!(one.lit, batched.lit);
    engine.set_triangle_batch_limit(None);
    engine.context().check_validation().unwrap();
}

/// A whole frame with its view samples resolved in bands of rows and its
/// light run in batches of view samples (forced here, as an image past one
/// storage binding takes them), with the progress bar on: the same frame
/// as one dispatch and one run, bit for bit, soft and hard.
#[test]
fn bands_and_batches_equal_one_frame() {
    use alias_free_shadows::render::FrameOptions;
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut desc = file::load("builtin:demo").unwrap();
    desc.camera.width = 50;
    desc.camera.height = 150;
    let point = Light {
        shape: LightShape::Point {
            position: desc.lights[0].center().unwrap(),
        },
        ..desc.lights[0].clone()
    };
    for light in [desc.lights[0].clone(), point] {
        desc.lights = vec![light];
        let one = engine.render(&desc, FrameOptions::default()).unwrap();
        engine.set_view_sample_band_limit(Some(64));
        engine.set_view_sample_batch_limit(Some(1000));
        let banded = engine
            .render(&desc, FrameOptions { progress: true })
            .unwrap();
        engine.set_view_sample_band_limit(None);
        engine.set_view_sample_batch_limit(None);
        assert!(one.view.samples.iter().any(|s| s.is_some()));
        assert_eq!(one.view.samples, banded.view.samples);
        assert_eq!(one.dump.visibility, banded.dump.visibility);
        assert_eq!(one.image, banded.image);
        let shadowed = one.dump.visibility[0]
            .iter()
            .filter(|v| v[0] < 1.0 && v[3] > 0.0)
            .count();
        assert!(shadowed > 0, "the light casts some shadow");
    }
    engine.context().check_validation().unwrap();
}

/// A unit-less box from `lo` to `hi` as a glTF exporter writes it: four
/// vertices per face (per-face normals and UVs), outward counter-clockwise
/// triangles; the last `faces` of its six (fewer: a box open at the top).
fn seamed_box(
    lo: DVec3,
    hi: DVec3,
    faces: usize,
    positions: &mut Vec<DVec3>,
    indices: &mut Vec<[u32; 3]>,
) {
    let d = hi - lo;
    // (corner, two edges counter-clockwise seen from outside), in units of d.
    let f: [([f64; 3], [f64; 3], [f64; 3]); 6] = [
        ([0., 1., 0.], [0., 0., 1.], [1., 0., 0.]), // +y
        ([1., 0., 0.], [0., 1., 0.], [0., 0., 1.]), // +x
        ([0., 0., 0.], [0., 0., 1.], [0., 1., 0.]), // -x
        ([0., 0., 1.], [1., 0., 0.], [0., 1., 0.]), // +z
        ([0., 0., 0.], [0., 1., 0.], [1., 0., 0.]), // -z
        ([0., 0., 0.], [1., 0., 0.], [0., 0., 1.]), // -y
    ];
    for (o, u, v) in f.iter().skip(6 - faces) {
        let at = |a: f64, b: f64| {
            lo + d * DVec3::new(
                o[0] + a * u[0] + b * v[0],
                o[1] + a * u[1] + b * v[1],
                o[2] + a * u[2] + b * v[2],
            )
        };
        let base = positions.len() as u32;
        positions.extend([at(0., 0.), at(1., 0.), at(1., 1.), at(0., 1.)]);
        indices.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    }
}

/// Closed parts of an open mesh (`scene::split_closed_parts`, as the glTF
/// loader applies it) cast as closed meshes: a seamed cube sunk a little
/// into an open ground, a cube floating above it, a box open at the top
/// (whose inside the camera sees: treated as closed, its walls would let
/// light in), all in one mesh. The oracle tests every face of every part; exact and
/// look-up modes must agree with it as on any scene, with the closed rule
/// dropping faces (the counter says it fired).
#[test]
fn closed_parts_of_an_open_mesh_conform() {
    use alias_free_shadows::scene::{split_closed_parts, Mesh, Scene};
    let (mut positions, mut indices) = (Vec::new(), Vec::new());
    let g = 4.0;
    positions.extend([
        DVec3::new(-g, 0.0, -g),
        DVec3::new(g, 0.0, -g),
        DVec3::new(g, 0.0, g),
        DVec3::new(-g, 0.0, g),
    ]);
    indices.extend([[0, 3, 2], [0, 2, 1]]);
    seamed_box(
        DVec3::new(-1.5, -0.01, -0.5),
        DVec3::new(-0.5, 0.99, 0.5),
        6,
        &mut positions,
        &mut indices,
    );
    seamed_box(
        DVec3::new(-1.2, 1.6, -0.3),
        DVec3::new(-0.6, 2.0, 0.3),
        6,
        &mut positions,
        &mut indices,
    );
    seamed_box(
        DVec3::new(0.5, 0.0, -0.5),
        DVec3::new(1.5, 1.0, 0.5),
        5,
        &mut positions,
        &mut indices,
    );
    let mesh = Mesh::new("parts", positions, indices);
    assert!(!mesh.closed);
    let meshes = split_closed_parts(mesh);
    let closed: Vec<bool> = meshes.iter().map(|m| m.closed).collect();
    assert_eq!(closed, [false, true, true], "the two cubes split off");
    let scene = Scene {
        meshes,
        ..Default::default()
    };
    let (mut camera, _) = file::default_view(&scene);
    camera.width = SIZE;
    camera.height = SIZE;
    // Close on the parts: the ground fills the rest of the picture.
    camera.eye = DVec3::new(0.5, 3.0, 4.5);
    camera.target = DVec3::new(-0.3, 0.7, 0.0);
    camera.up = DVec3::Y;
    let light = Light {
        shape: LightShape::Sphere {
            position: DVec3::new(-2.0, 6.0, 3.0),
            radius: 0.6,
        },
        samples: 128,
        ..file::load("builtin:demo").unwrap().lights[0].clone()
    };
    let desc = SceneDescription {
        name: "closed parts".into(),
        scene,
        camera,
        lights: vec![light.clone()],
        shadows: Default::default(),
    };
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for mode in [SoftMode::Exact, SoftMode::Lut] {
        let a = agreement(&mut engine, &desc, &light, mode);
        let share = a.disagree as f64 / a.pairs.max(1) as f64;
        eprintln!(
            "closed parts {mode:?}: {} pixels, {} of {} pairs disagree ({share:.2e})",
            a.pixels, a.disagree, a.pairs
        );
        assert!(a.pixels > SIZE as usize * SIZE as usize / 4);
        assert!(
            share <= EXACT_SHARE,
            "{mode:?}: {share:.2e} of the pairs disagree"
        );
    }
    // A rendered frame (its own view samples; frames open no mesh for
    // samples seen from inside, so the split alone decides what is closed).
    let frame = engine
        .render(&desc, alias_free_shadows::render::FrameOptions::default())
        .unwrap();
    let (off, pixels) = common::pixels_off_the_oracle(&desc, &frame, 0, |_, _| {});
    eprintln!("closed parts, frame: {off} of {pixels} pixels off the oracle");
    assert!(pixels > SIZE as usize * SIZE as usize / 4);
    assert_eq!(off, 0, "{off} of {pixels} pixels off the oracle");
    // The closed rule fired: faces of the cubes that face the whole light
    // were dropped.
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, &desc);
    let r = engine
        .soft_shadows(
            &desc.scene,
            eye,
            &view.samples,
            &light,
            &ShadowSettings::default(),
        )
        .unwrap();
    assert!(
        r.stats.triangles_front_facing_closed > 0,
        "no closed face was dropped"
    );
    engine.context().check_validation().unwrap();
}
