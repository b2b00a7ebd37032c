//! Helpers shared by the conformance tests (each test binary uses some).
#![allow(dead_code)]

pub mod bands;

use alias_free_shadows::oracle::{Oracle, ViewSamples};
use alias_free_shadows::scene::file::{default_view, place_on_ground, SceneDescription};

/// The `../shared/assets` models (those present), each on a ground plane
/// with its default camera and light.
pub fn shared_asset_scenes() -> Vec<SceneDescription> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets");
    let mut out = Vec::new();
    for model in [
        "Lantern/Lantern.gltf",
        "BoomBox/BoomBox.gltf",
        "Suzanne/Suzanne.gltf",
    ] {
        let path = root.join(model);
        if !path.is_file() {
            continue;
        }
        let mut scene = alias_free_shadows::scene::gltf_load::load_gltf(&path).unwrap();
        place_on_ground(&mut scene);
        let (camera, light) = default_view(&scene);
        out.push(SceneDescription {
            name: model.into(),
            scene,
            camera,
            lights: vec![light],
            shadows: Default::default(),
        });
    }
    out
}

/// Mask words that differ between two runs of the same samples.
pub fn words_differ(a: &[u32], b: &[u32]) -> usize {
    assert_eq!(a.len(), b.len(), "the runs' masks differ in length");
    a.iter().zip(b).filter(|(x, y)| x != y).count()
}

/// `light`'s soft shadows of `view` in `mode` (default settings otherwise).
pub fn soft_in_mode(
    engine: &mut alias_free_shadows::render::Engine,
    desc: &SceneDescription,
    view: &ViewSamples,
    light: &alias_free_shadows::light::Light,
    mode: alias_free_shadows::scene::file::SoftMode,
) -> alias_free_shadows::render::SoftShadowResult {
    let settings = alias_free_shadows::scene::file::ShadowSettings {
        mode,
        ..Default::default()
    };
    engine
        .soft_shadows(
            &desc.scene,
            desc.camera.eye,
            &view.samples,
            light,
            &settings,
        )
        .unwrap()
}

/// The engine's view samples as the oracle sees them: camera-relative f32
/// positions and normals converted back, exactly.
pub fn engine_view_samples(oracle: &Oracle, desc: &SceneDescription) -> ViewSamples {
    alias_free_shadows::bench::f32_view_samples(oracle, desc)
}

/// `desc` with every position scaled by `scale` about the origin, then
/// moved by `offset`: meshes, camera and the lights (point and sphere
/// lights; a sphere's radius scales too). The same scene at another size
/// or place: its shadows must not change.
pub fn scaled_and_moved(
    desc: &SceneDescription,
    scale: f64,
    offset: glam::DVec3,
) -> SceneDescription {
    use alias_free_shadows::light::LightShape;
    let m =
        glam::DMat4::from_translation(offset) * glam::DMat4::from_scale(glam::DVec3::splat(scale));
    let mut out = desc.clone();
    for mesh in &mut out.scene.meshes {
        mesh.transform(&m);
    }
    out.camera.eye = m.transform_point3(desc.camera.eye);
    out.camera.target = m.transform_point3(desc.camera.target);
    for l in &mut out.lights {
        l.shape = match &l.shape {
            LightShape::Point { position } => LightShape::Point {
                position: m.transform_point3(*position),
            },
            LightShape::Sphere { position, radius } => LightShape::Sphere {
                position: m.transform_point3(*position),
                radius: radius * scale,
            },
            other => panic!("scaled_and_moved: light {other:?} not supported"),
        };
    }
    out.name = format!("{} x{scale:e} +{offset}", desc.name);
    out
}

/// A sphere light of radius 5% of the scene's diagonal at the scene's
/// light (or above its bounds when the light has no centre), `samples`
/// samples, the rest as the scene's light.
pub fn sphere_light(desc: &SceneDescription, samples: u32) -> alias_free_shadows::light::Light {
    use alias_free_shadows::light::{Light, LightShape};
    let l = &desc.lights[0];
    let (lo, hi) = desc.scene.bounds().unwrap();
    Light {
        shape: LightShape::Sphere {
            position: l.center().unwrap_or(hi + (hi - lo) * 0.5),
            radius: 0.05 * (hi - lo).length(),
        },
        samples,
        ..l.clone()
    }
}

/// Issue 5's scale cases for [`scaled_and_moved`]: 1e-4 and 1e5 times the
/// size, and 1e4 units from the origin.
pub const SCALE_CASES: [(f64, glam::DVec3); 3] = [
    (1e-4, glam::DVec3::ZERO),
    (1e5, glam::DVec3::ZERO),
    (1.0, glam::DVec3::new(1e4, 3e3, -1e4)),
];

/// The light samples as the engine has them (camera-relative f32), back
/// in world space.
pub fn engine_light(
    light: &alias_free_shadows::light::Light,
    eye: glam::DVec3,
) -> alias_free_shadows::light::LightSamples {
    use alias_free_shadows::light::LightSamples;
    match light.light_samples() {
        LightSamples::Positions(p) => LightSamples::Positions(
            p.iter()
                .map(|q| eye + (*q - eye).as_vec3().as_dvec3())
                .collect(),
        ),
        d => d,
    }
}

/// Standard base64 with padding (data URIs in test glTF files).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Pixels of a rendered frame whose visible light-sample count for light
/// `k` differs from the oracle's (given the frame's own view samples and
/// light samples) by more pairs than lie in the documented bands, and the
/// pixels compared. `agree(pixel, oracle mask)` is called for every pixel
/// whose count equals the oracle's, for further checks.
#[allow(dead_code)]
pub fn pixels_off_the_oracle(
    desc: &alias_free_shadows::scene::file::SceneDescription,
    frame: &alias_free_shadows::render::Frame,
    k: usize,
    mut agree: impl FnMut(usize, &[u64]),
) -> (usize, usize) {
    use alias_free_shadows::light::LightSamples;
    use alias_free_shadows::oracle::{LightTarget, Oracle};
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let ls = engine_light(&desc.lights[k], eye);
    let LightSamples::Positions(points) = &ls else {
        panic!("an area light")
    };
    let want = oracle.visibility_masks(&frame.view, &ls);
    let n = points.len();
    let (mut off, mut pixels) = (0, 0);
    for (i, s) in frame.view.samples.iter().enumerate() {
        let Some(s) = s else { continue };
        pixels += 1;
        let want_count = (0..n)
            .filter(|&j| want[i][j / 64] >> (j % 64) & 1 == 1)
            .count();
        let got_count = (frame.dump.visibility[k][i][0] * n as f32).round() as usize;
        let diff = got_count.abs_diff(want_count);
        if diff == 0 {
            agree(i, &want[i]);
            continue;
        }
        let in_band = points
            .iter()
            .filter(|&&q| bands::in_any_band(&oracle, &desc.scene, eye, s, LightTarget::Point(q)))
            .count();
        if in_band < diff {
            off += 1;
        }
    }
    (off, pixels)
}
