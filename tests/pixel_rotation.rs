//! Per-pixel rotation (paper §4.2, issue 17): with `per_pixel_rotation`
//! each view sample sees a symmetric light's samples turned by its own
//! angle about the light's axis. The GPU (lavapipe, validation on) against
//! the CPU oracle given the same per-pixel samples, per (pixel, light
//! sample) pair; look-up mode against exact mode word by word; and the
//! rotation shown to matter (the unturned oracle disagrees).

use alias_free_shadows::light::{pixel_rotation_table, Light, LightSamples, LightShape};
use alias_free_shadows::oracle::{LightTarget, Oracle, ViewSamples};
use alias_free_shadows::render::{Engine, FrameOptions};
use alias_free_shadows::scene::file::{self, SceneDescription, ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;
use glam::DVec3;

mod common;
use common::{engine_light, engine_view_samples, soft_in_mode, words_differ};

/// The largest share of (pixel, light sample) pairs that may disagree with
/// the oracle: exact mode's bound in `soft_conformance.rs`.
const EXACT_SHARE: f64 = 1e-4;
const SIZE: u32 = 40;
const SAMPLES: u32 = 64;

fn sized(spec: &str) -> SceneDescription {
    let mut desc = file::load(spec).unwrap();
    desc.camera.width = SIZE;
    desc.camera.height = SIZE;
    desc
}

/// A sphere, a disk and an ellipsoid round its axis where the scene's
/// first light is, each turned per pixel.
fn symmetric_lights(desc: &SceneDescription) -> Vec<Light> {
    let base = desc.lights[0].clone();
    let p = base.center().unwrap();
    let (lo, hi) = desc.scene.bounds().unwrap();
    let toward = ((lo + hi) * 0.5 - p).normalize();
    let r = 0.1 * p.distance((lo + hi) * 0.5);
    let tangent = alias_free_shadows::light::default_tangent(toward);
    [
        LightShape::Sphere {
            position: p,
            radius: r,
        },
        LightShape::Disk {
            position: p,
            radius: r,
            normal: toward,
            tangent,
        },
        LightShape::Ellipsoid {
            position: p,
            semi_axes: DVec3::new(r, r, 0.4 * r),
            normal: toward,
            tangent,
        },
    ]
    .into_iter()
    .map(|shape| {
        let l = Light {
            shape,
            samples: SAMPLES,
            per_pixel_rotation: true,
            emission: None,
            ..base.clone()
        };
        l.validate().unwrap();
        l
    })
    .collect()
}

/// Per pixel, the oracle's visible light samples (bit j of word j / 32):
/// with `turned`, each pixel's samples turned by its angle, as the dump
/// documents; else the light's samples as they are.
fn oracle_masks(
    desc: &SceneDescription,
    view: &ViewSamples,
    light: &Light,
    turned: bool,
) -> Vec<Vec<u32>> {
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let LightSamples::Positions(points) = engine_light(light, eye) else {
        panic!("an area light")
    };
    let rotation = light.pixel_rotation(eye).unwrap();
    let table = pixel_rotation_table();
    view.samples
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let mut mask = vec![0u32; points.len().div_ceil(32)];
            if let Some(s) = s {
                for (j, &q) in points.iter().enumerate() {
                    let q = if turned {
                        rotation.turn(q, i as u32, &table)
                    } else {
                        q
                    };
                    if oracle.sample_visible(s, LightTarget::Point(q)) {
                        mask[j / 32] |= 1 << (j % 32);
                    }
                }
            }
            mask
        })
        .collect()
}

/// (pairs, pairs that disagree) between the GPU's visible masks and `want`.
fn disagreement(
    visible: &[u32],
    words: usize,
    want: &[Vec<u32>],
    view: &ViewSamples,
    n: usize,
) -> (u64, u64) {
    let (mut pairs, mut off) = (0u64, 0u64);
    for (i, s) in view.samples.iter().enumerate() {
        if s.is_none() {
            continue;
        }
        let got = &visible[i * words..(i + 1) * words];
        for j in 0..n {
            pairs += 1;
            let g = got[j / 32] >> (j % 32) & 1;
            let w = want[i][j / 32] >> (j % 32) & 1;
            off += (g != w) as u64;
        }
    }
    (pairs, off)
}

/// Look-up and exact modes, turned per pixel, agree with the oracle given
/// the same turned samples, on a plain scene and an alpha-tested one; the
/// oracle without the turn disagrees far beyond that bound.
#[test]
fn rotated_samples_conform_to_the_oracle() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for spec in ["builtin:demo", "builtin:fence"] {
        let desc = sized(spec);
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        for light in symmetric_lights(&desc) {
            let kind = format!("{:?}", light.shape);
            let kind = kind.split([' ', '{']).next().unwrap_or("").to_string();
            let want = oracle_masks(&desc, &view, &light, true);
            let unturned = oracle_masks(&desc, &view, &light, false);
            for mode in [SoftMode::Lut, SoftMode::Exact] {
                let settings = ShadowSettings {
                    mode,
                    ..Default::default()
                };
                let r = engine
                    .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
                    .unwrap();
                let n = SAMPLES as usize;
                let (pairs, off) = disagreement(&r.visible, r.mask_words, &want, &view, n);
                let (_, off_unturned) = disagreement(&r.visible, r.mask_words, &unturned, &view, n);
                let share = off as f64 / pairs.max(1) as f64;
                let share_unturned = off_unturned as f64 / pairs.max(1) as f64;
                eprintln!(
                    "{spec} {kind} {mode:?}: {off} of {pairs} pairs off the turned oracle ({share:.2e}); \
                     {off_unturned} off the unturned one ({share_unturned:.2e})"
                );
                assert!(pairs > 1000, "{spec}: too few pairs");
                assert!(share <= EXACT_SHARE, "{spec} {kind} {mode:?}: {share:.2e}");
                // The turn changes what the pixels see.
                assert!(
                    share_unturned > 10.0 * EXACT_SHARE,
                    "{spec} {kind} {mode:?}: the turn changed nothing ({share_unturned:.2e})"
                );
            }
        }
    }
    engine.context().check_validation().unwrap();
}

/// Look-up mode gives exact mode's masks bit for bit with the turn too.
#[test]
fn rotated_lookup_masks_equal_exact_masks() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for spec in [
        "builtin:demo",
        "builtin:torus_knot",
        "builtin:hairball",
        "builtin:fence",
    ] {
        let desc = sized(spec);
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        for mut light in symmetric_lights(&desc) {
            for samples in [64, 256] {
                light.samples = samples;
                let lut = soft_in_mode(&mut engine, &desc, &view, &light, SoftMode::Lut);
                let exact = soft_in_mode(&mut engine, &desc, &view, &light, SoftMode::Exact);
                let differ = words_differ(&lut.visible, &exact.visible);
                assert_eq!(
                    differ, 0,
                    "{spec} {:?} {samples} samples: {differ} mask words differ",
                    light.shape
                );
            }
        }
    }
    engine.context().check_validation().unwrap();
}

/// A frame with a turned light: the dump says so (axis and seed), and
/// `afs reference`'s frame (the oracle turning each pixel's samples) has
/// the GPU frame's visibility within the bands.
#[test]
fn rendered_frames_record_the_rotation_and_match_the_reference() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut desc = sized("builtin:demo");
    desc.lights = symmetric_lights(&desc)[..2].to_vec();
    let frame = engine.render(&desc, FrameOptions::default()).unwrap();
    let reference =
        alias_free_shadows::render::render_reference(&desc, FrameOptions::default()).unwrap();
    for (k, light) in desc.lights.iter().enumerate() {
        let d = &frame.dump.scene.lights[k];
        assert!(d.per_pixel_rotation);
        let rot = light.pixel_rotation(desc.camera.eye).unwrap();
        assert_eq!(d.rotation_axis, Some(rot.axis.to_array()));
        assert_eq!(d.rotation_seed, Some(rot.seed));
        let (mut pixels, mut off) = (0, 0);
        for (i, (g, w)) in frame.dump.visibility[k]
            .iter()
            .zip(&reference.dump.visibility[k])
            .enumerate()
        {
            if frame.view.samples[i].is_none() || reference.view.samples[i].is_none() {
                continue;
            }
            pixels += 1;
            // More than two light samples apart: not rounding at an edge.
            off += ((g[0] - w[0]).abs() > 2.5 / SAMPLES as f32) as usize;
        }
        eprintln!("light {k}: {off} of {pixels} pixels more than 2 samples off the reference");
        assert!(pixels > 1000);
        assert!(
            off * 100 <= pixels,
            "light {k}: {off} of {pixels} pixels off"
        );
    }
    engine.context().check_validation().unwrap();
}

/// Lights that a turn changes, or whose texture it would move, are refused
/// with the field named.
#[test]
fn asymmetric_and_textured_lights_refuse_rotation() {
    let desc = sized("builtin:demo");
    let lights = symmetric_lights(&desc);
    let mut ellipsoid = lights[2].clone();
    if let LightShape::Ellipsoid { semi_axes, .. } = &mut ellipsoid.shape {
        semi_axes.y *= 0.5;
    }
    let rect = Light {
        shape: LightShape::Rect {
            position: DVec3::ZERO,
            size: glam::DVec2::new(1.0, 1.0),
            normal: DVec3::Y,
            tangent: DVec3::X,
        },
        ..lights[0].clone()
    };
    let textured = Light {
        emission: Some(alias_free_shadows::light::LightEmission {
            path: "t.png".into(),
            image: std::sync::Arc::new(image::RgbImage::new(2, 2)),
        }),
        ..lights[1].clone()
    };
    for (l, what) in [
        (ellipsoid, "semi-axes"),
        (rect, "sphere"),
        (textured, "texture"),
    ] {
        let e = l.validate().unwrap_err().to_string();
        assert!(e.contains("per_pixel_rotation") && e.contains(what), "{e}");
    }
    let mut desc = sized("builtin:demo");
    let e = file::replace_light(&mut desc, "rect:rotate=true")
        .unwrap_err()
        .to_string();
    assert!(e.contains("per_pixel_rotation"), "{e}");
    let e = file::replace_light(&mut desc, "sphere:rotate=yes")
        .unwrap_err()
        .to_string();
    assert!(e.contains("rotate"), "{e}");
    file::replace_light(&mut desc, "disk:rotate=true").unwrap();
    assert!(desc.lights[0].per_pixel_rotation);
}

/// View samples run in batches (forced small) turn by their frame-wide
/// pixel index: the same masks as one run.
#[test]
fn batched_view_samples_keep_their_pixels_angles() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = sized("builtin:demo");
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, &desc);
    let light = symmetric_lights(&desc).remove(1);
    let settings = ShadowSettings::default();
    let whole = engine
        .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
        .unwrap();
    engine.set_view_sample_batch_limit(Some(300));
    let batched = engine
        .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
        .unwrap();
    engine.set_view_sample_batch_limit(None);
    let differ = words_differ(&whole.visible, &batched.visible);
    assert_eq!(
        differ, 0,
        "{differ} mask words differ between one run and batches"
    );
    engine.context().check_validation().unwrap();
}
