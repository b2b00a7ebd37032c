//! Alpha-tested casters (issue 16: glTF MASK, BLEND cast as MASK at 0.5)
//! against the oracle, whose alpha test is its own (`oracle::coverage`, in
//! f64): the view samples see through the holes, hard and soft shadows
//! pass through them, on `builtin:fence`, the shared TransmissionTest and
//! StainedGlassLamp on a ground, and random alpha-tested quads with random
//! lattice textures, filters, wrap modes and lights of every kind.
//!
//! A (view sample, light sample) pair may disagree only in the documented
//! bands (`common::bands`), or in the alpha band: its segment crosses an
//! alpha-tested triangle at a point whose opacity flips within [`BAND`]
//! times the segment's length of it, in the triangle's plane (a texel edge
//! or the cutoff there; what the GPU's f32 crossing point can straddle).
//! A pixel's view sample may differ from the oracle's first hit only where
//! either lies within `BAND` times its distance of an edge of its triangle
//! (the raster's choice between neighbours), or where an alpha-tested
//! triangle on its ray is in the alpha band.

use std::sync::Arc;

use alias_free_shadows::light::{Distribution, Light, LightSamples, LightShape};
use alias_free_shadows::oracle::{LightTarget, Oracle, ViewSample, ViewSamples};
use alias_free_shadows::render::{Engine, FrameOptions};
use alias_free_shadows::scene::file::{self, default_view, place_on_ground, SceneDescription};
use alias_free_shadows::scene::file::{ShadowSettings, SoftMode};
use alias_free_shadows::scene::{
    AlphaMode, Camera, MagFilter, Material, Mesh, Sampler, Scene, SceneTriangle, Texture, Wrap,
};
use alias_free_shadows::vulkan::ContextOptions;
use glam::{DVec2, DVec3};

mod common;
use common::bands::{in_any_band, BAND};
use common::{base64, engine_light, engine_view_samples};

const SIZE: u32 = 64;

/// `builtin:fence` and the shared alpha-tested models on a ground.
fn scenes() -> Vec<SceneDescription> {
    let mut out = vec![file::load("builtin:fence").unwrap()];
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets");
    for model in [
        "TransmissionTest/TransmissionTest.glb",
        "StainedGlassLamp/StainedGlassLamp.gltf",
    ] {
        let path = root.join(model);
        if !path.is_file() {
            continue;
        }
        // As `afs render MODEL --ground` sees it: the file's camera (or a
        // framing one) and light, on a ground.
        let mut desc = file::load(path.to_str().unwrap()).unwrap();
        place_on_ground(&mut desc.scene);
        desc.name = model.into();
        out.push(desc);
    }
    for d in &mut out {
        d.camera.width = SIZE;
        d.camera.height = SIZE;
    }
    out
}

/// The scene with every alpha test off (opaque casters): what ignoring
/// the masks would give.
fn opaque(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    for m in &mut s.materials {
        m.alpha_mode = AlphaMode::Opaque;
    }
    s
}

/// Whether the segment from `p` to `q` (or the ray from `p` along `q - p`
/// when `ray`) crosses an alpha-tested triangle of `tris` in the alpha band.
fn in_alpha_band(oracle: &Oracle, tris: &[SceneTriangle], p: DVec3, q: DVec3, ray: bool) -> bool {
    let d = q - p;
    tris.iter().enumerate().any(|(t, tri)| {
        if tri.alpha.is_none() {
            return false;
        }
        let [a, b, c] = tri.vertices;
        let n = (b - a).cross(c - a);
        let dn = n.dot(d);
        if dn == 0.0 {
            return false;
        }
        let tau = n.dot(a - p) / dn;
        if tau <= 0.0 || (!ray && tau >= 1.0) {
            return false;
        }
        let x = p + d * tau;
        let rho = BAND * (x - p).length().max(BAND);
        // Inside the triangle grown by rho.
        let inside = [(a, b), (b, c), (c, a)].iter().all(|&(u, v)| {
            let e = v - u;
            let out = e.cross(n).normalize();
            out.dot(x - u) <= rho
        });
        inside && oracle.alpha_flips_near(t as u32, x, rho)
    })
}

/// Distance from `x` to the nearest edge of triangle `v`.
fn edge_distance(v: [DVec3; 3], x: DVec3) -> f64 {
    [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])]
        .iter()
        .map(|&(a, b)| {
            let e = b - a;
            let t = ((x - a).dot(e) / e.dot(e)).clamp(0.0, 1.0);
            (a + e * t - x).length()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn view_samples_see_through_the_holes() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut seen_through = 0;
    for desc in scenes() {
        let eye = desc.camera.eye;
        let tris = desc.scene.triangles();
        let oracle = Oracle::new(&tris, eye);
        let want = oracle.primary_view_samples(&desc.camera);
        let solid =
            Oracle::new(&opaque(&desc.scene).triangles(), eye).primary_view_samples(&desc.camera);
        let got = engine.render(&desc, FrameOptions::default()).unwrap().view;
        let (mut through, mut in_band, mut outside) = (0, 0, 0);
        for (i, (g, w)) in got.samples.iter().zip(&want.samples).enumerate() {
            let hole = w.map(|w| w.triangle) != solid.samples[i].map(|s| s.triangle);
            through += hole as usize;
            if g.map(|g| g.triangle) == w.map(|w| w.triangle) {
                continue;
            }
            // Near an edge of either triangle, or an alpha test in band on
            // the ray as far as the farther of the two.
            let near_edge = |s: &Option<ViewSample>| {
                s.is_some_and(|s| {
                    let v = tris[s.triangle as usize].vertices;
                    edge_distance(v, s.position) <= BAND * (s.position - eye).length()
                })
            };
            let far = [g, w]
                .iter()
                .filter_map(|s| s.map(|s| s.position))
                .max_by(|a, b| (*a - eye).length().total_cmp(&(*b - eye).length()));
            let (x, y) = (i as u32 % SIZE, i as u32 / SIZE);
            let alpha_band = match far {
                Some(f) if g.is_some() && w.is_some() => {
                    in_alpha_band(&oracle, &tris, eye, f, false)
                }
                _ => in_alpha_band(
                    &oracle,
                    &tris,
                    eye,
                    eye + desc.camera.ray_direction(x, y),
                    true,
                ),
            };
            if near_edge(g) || near_edge(w) || alpha_band {
                in_band += 1;
            } else {
                outside += 1;
                eprintln!("{}: pixel ({x}, {y}): GPU {g:?}, oracle {w:?}", desc.name);
            }
        }
        eprintln!(
            "{}: {through} pixels see through a hole; {in_band} differ from the oracle in band, {outside} outside",
            desc.name
        );
        assert_eq!(outside, 0, "{}: view samples off the oracle's", desc.name);
        seen_through += through;
    }
    assert!(
        seen_through > 0,
        "no pixel saw through a hole: the test proves nothing"
    );
    engine.context().check_validation().unwrap();
}

/// The pairs of `view` and `light` where the engine and the oracle
/// disagree outside every band, and the pairs compared.
fn check_shadows(
    engine: &mut Engine,
    desc: &SceneDescription,
    view: &ViewSamples,
    light: &Light,
    mode: Option<SoftMode>,
) -> (usize, usize, usize) {
    let eye = desc.camera.eye;
    let tris = desc.scene.triangles();
    let oracle = Oracle::new(&tris, eye);
    // The light samples as the engine has them (camera-relative f32).
    let targets: Vec<LightTarget> = match engine_light(light, eye) {
        LightSamples::Positions(p) => p.into_iter().map(LightTarget::Point).collect(),
        LightSamples::Direction(d) => vec![LightTarget::Direction(d)],
    };
    let got: Vec<Vec<bool>> = match mode {
        None => {
            let r = engine
                .hard_shadows(&desc.scene, eye, &view.samples, light, 256)
                .unwrap();
            r.lit.iter().map(|l| vec![*l == Some(true)]).collect()
        }
        Some(mode) => {
            let settings = ShadowSettings {
                mode,
                ..Default::default()
            };
            let r = engine
                .soft_shadows(&desc.scene, eye, &view.samples, light, &settings)
                .unwrap();
            (0..view.samples.len())
                .map(|i| {
                    let w = &r.visible[i * r.mask_words..(i + 1) * r.mask_words];
                    (0..targets.len())
                        .map(|j| w[j / 32] >> (j % 32) & 1 == 1)
                        .collect()
                })
                .collect()
        }
    };
    let (mut pairs, mut in_band, mut outside) = (0, 0, 0);
    for (i, s) in view.samples.iter().enumerate() {
        let Some(s) = s else { continue };
        for (j, &t) in targets.iter().enumerate() {
            pairs += 1;
            if got[i][j] == oracle.sample_visible(s, t) {
                continue;
            }
            let (q, ray) = match t {
                LightTarget::Point(q) => (q, false),
                LightTarget::Direction(d) => (s.position - d, true),
            };
            if in_any_band(&oracle, &desc.scene, eye, s, t)
                || in_alpha_band(&oracle, &tris, s.position, q, ray)
            {
                in_band += 1;
            } else {
                outside += 1;
                eprintln!(
                    "{}: sample {i} ({:?}, triangle {}), light sample {j}: GPU {}, oracle {}",
                    desc.name, s.position, s.triangle, got[i][j], !got[i][j]
                );
            }
        }
    }
    (pairs, in_band, outside)
}

/// Light-sample pairs where the masks make a difference: visible through a
/// hole by the oracle, blocked when the masks are ignored.
fn through_holes(desc: &SceneDescription, view: &ViewSamples, light: &Light) -> usize {
    let eye = desc.camera.eye;
    let with = Oracle::new(&desc.scene.triangles(), eye);
    let without = Oracle::new(&opaque(&desc.scene).triangles(), eye);
    let ls = light.light_samples();
    let a = with.visibility_masks(view, &ls);
    let b = without.visibility_masks(view, &ls);
    a.iter()
        .zip(&b)
        .map(|(x, y)| {
            x.iter()
                .zip(y)
                .map(|(p, q)| (p & !q).count_ones() as usize)
                .sum::<usize>()
        })
        .sum()
}

#[test]
fn shadows_pass_through_the_holes() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut lit_through = 0;
    for desc in scenes() {
        let oracle = Oracle::new(&desc.scene.triangles(), desc.camera.eye);
        let view = engine_view_samples(&oracle, &desc);
        let centre = desc.lights[0].center().unwrap();
        let point = Light {
            shape: LightShape::Point { position: centre },
            samples: 1,
            ..desc.lights[0].clone()
        };
        let sphere = common::sphere_light(&desc, 128);
        for (light, mode) in [
            (&point, None),
            (&sphere, Some(SoftMode::Exact)),
            (&sphere, Some(SoftMode::Lut)),
        ] {
            let holes = through_holes(&desc, &view, light);
            let (pairs, in_band, outside) = check_shadows(&mut engine, &desc, &view, light, mode);
            eprintln!(
                "{} {mode:?}: {pairs} pairs, {holes} lit through holes; {in_band} differ in band, {outside} outside",
                desc.name
            );
            lit_through += holes;
            assert_eq!(
                outside, 0,
                "{} {mode:?}: pairs off the oracle outside the bands",
                desc.name
            );
        }
    }
    assert!(
        lit_through > 0,
        "no light passed a hole: the test proves nothing"
    );
    engine.context().check_validation().unwrap();
}

/// A tiny deterministic generator (xorshift).
struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f()
    }
    fn below(&mut self, n: u32) -> u32 {
        (self.f() * n as f64) as u32 % n
    }
    fn unit(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            if v.length() > 0.1 && v.length() < 1.0 {
                return v.normalize();
            }
        }
    }
}

/// A random lattice texture: alphas 0 and 255 (NEAREST), or any byte
/// (LINEAR, so that the cutoff falls between texel centres).
fn random_texture(rng: &mut Rng, linear: bool) -> image::RgbaImage {
    let (w, h) = (1 + rng.below(12), 1 + rng.below(12));
    image::RgbaImage::from_fn(w, h, |_, _| {
        let a = if linear {
            rng.below(256) as u8
        } else {
            [0, 255][rng.below(2) as usize]
        };
        image::Rgba([200, 150, 90, a])
    })
}

/// Random alpha-tested quads over a ground, lit by a light of `kind`.
fn random_case(seed: u64, kind: u32) -> SceneDescription {
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let wraps = [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat];
    let mut meshes = Vec::new();
    let mut materials = Vec::new();
    for q in 0..1 + rng.below(3) as usize {
        let c = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(0.6, 1.8),
            rng.range(-1.0, 1.0),
        );
        let (u, v) = (
            rng.unit() * rng.range(0.4, 1.2),
            rng.unit() * rng.range(0.4, 1.2),
        );
        let positions = vec![c - u - v, c + u - v, c + u + v, c - u + v];
        let mut m = Mesh::new(format!("quad{q}"), positions, vec![[0, 1, 2], [0, 2, 3]]);
        // Texture coordinates spanning a few periods (the wrap modes matter).
        let (o, s) = (
            DVec2::new(rng.range(-1.5, 0.5), rng.range(-1.5, 0.5)),
            DVec2::new(rng.range(0.5, 3.0), rng.range(0.5, 3.0)),
        );
        m.uvs = Some(vec![
            o,
            o + DVec2::new(s.x, 0.0),
            o + s,
            o + DVec2::new(0.0, s.y),
        ]);
        m.material = Some(q);
        meshes.push(m);
        let linear = rng.below(2) == 1;
        materials.push(Material {
            name: format!("lattice{q}"),
            alpha_mode: if rng.below(5) == 0 {
                AlphaMode::Blend
            } else {
                AlphaMode::Mask
            },
            alpha_cutoff: rng.range(0.2, 0.8) as f32,
            base_color_factor: [1.0, 1.0, 1.0, rng.range(0.7, 1.0) as f32],
            base_color_texture: Some(Texture {
                source: "random lattice".into(),
                image: Some(Arc::new(random_texture(&mut rng, linear))),
                sampler: Sampler {
                    mag_filter: if linear {
                        MagFilter::Linear
                    } else {
                        MagFilter::Nearest
                    },
                    wrap_s: wraps[rng.below(3) as usize],
                    wrap_t: wraps[rng.below(3) as usize],
                },
            }),
        });
    }
    let mut scene = Scene {
        meshes,
        materials,
        ..Scene::default()
    };
    scene.add_ground(0.0, 4.0);
    let eye = DVec3::new(
        rng.range(-3.0, 3.0),
        rng.range(2.5, 4.0),
        rng.range(3.0, 5.0),
    );
    let camera = Camera {
        eye,
        target: DVec3::new(0.0, 0.6, 0.0),
        up: DVec3::Y,
        fov_y_deg: 55.0,
        width: 32,
        height: 32,
    };
    let at = DVec3::new(
        rng.range(-1.5, 1.5),
        rng.range(3.5, 5.0),
        rng.range(-1.5, 1.5),
    );
    let (normal, tangent) = (-at.normalize(), DVec3::X);
    let tangent = (tangent - normal * tangent.dot(normal)).normalize();
    let r = rng.range(0.1, 0.6);
    let shape = match kind {
        0 => LightShape::Point { position: at },
        1 => LightShape::Directional {
            direction: -at.normalize(),
        },
        2 => LightShape::Sphere {
            position: at,
            radius: r,
        },
        3 => LightShape::Disk {
            position: at,
            radius: r,
            normal,
            tangent,
        },
        4 => LightShape::Rect {
            position: at,
            size: DVec2::new(2.0 * r, r),
            normal,
            tangent,
        },
        5 => LightShape::Ellipsoid {
            position: at,
            semi_axes: DVec3::new(r, 0.5 * r, 0.3 * r),
            normal,
            tangent,
        },
        _ => LightShape::Explicit {
            positions: (0..20).map(|_| at + rng.unit() * r).collect(),
        },
    };
    let samples = match shape {
        LightShape::Point { .. } | LightShape::Directional { .. } => 1,
        LightShape::Explicit { ref positions } => positions.len() as u32,
        _ => 32 + rng.below(160),
    };
    let light = Light {
        shape,
        samples,
        distribution: Distribution::Poisson,
        seed: seed + 1,
        color: [1.0; 3],
        intensity: 1.0,
        emission: None,
        per_pixel_rotation: false,
    };
    SceneDescription {
        name: format!("random alpha case {seed} (light kind {kind})"),
        scene,
        camera,
        lights: vec![light],
        shadows: Default::default(),
    }
}

#[test]
fn random_alpha_quads_agree_with_the_oracle() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let cases: u64 = std::env::var("AFS_ALPHA_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(21);
    let (mut pairs, mut in_band, mut holes) = (0, 0, 0);
    for seed in 0..cases {
        let kind = (seed % 7) as u32;
        let desc = random_case(seed, kind);
        let oracle = Oracle::new(&desc.scene.triangles(), desc.camera.eye);
        let view = engine_view_samples(&oracle, &desc);
        let light = &desc.lights[0];
        holes += through_holes(&desc, &view, light);
        let modes: &[Option<SoftMode>] = match kind {
            0 | 1 => &[None],
            _ => &[Some(SoftMode::Exact), Some(SoftMode::Lut)],
        };
        for &mode in modes {
            let (p, b, outside) = check_shadows(&mut engine, &desc, &view, light, mode);
            pairs += p;
            in_band += b;
            assert_eq!(
                outside, 0,
                "{} {mode:?}: {outside} pairs off the oracle outside the bands",
                desc.name
            );
        }
    }
    eprintln!(
        "{cases} random cases: {pairs} pairs, {holes} lit through holes, {in_band} differ in band"
    );
    assert!(holes > 0, "no light passed a hole");
    assert!(
        in_band as f64 <= 1e-3 * pairs as f64,
        "{in_band} of {pairs} pairs in band"
    );
    engine.context().check_validation().unwrap();
}

#[test]
fn a_mask_whose_texture_is_missing_casts_opaque_with_a_warning() {
    // A vertical MASK quad whose texture file is missing, over a ground.
    let positions: [[f32; 3]; 4] = [
        [-1.0, 0.2, 0.0],
        [1.0, 0.2, 0.0],
        [1.0, 1.8, 0.0],
        [-1.0, 1.8, 0.0],
    ];
    let uvs: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin: Vec<u8> = Vec::new();
    bin.extend(positions.iter().flatten().flat_map(|v| v.to_le_bytes()));
    bin.extend(uvs.iter().flatten().flat_map(|v| v.to_le_bytes()));
    bin.extend(indices.iter().flat_map(|v| v.to_le_bytes()));
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
 "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0}}]}}],
 "materials": [{{"name": "lattice", "alphaMode": "MASK", "pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}}}}}],
 "textures": [{{"source": 0}}], "images": [{{"uri": "missing.png"}}],
 "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
 "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                 {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}],
 "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, 0.2, 0], "max": [1, 1.8, 0]}},
               {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
               {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}}]}}"#,
        len = bin.len(),
        data = base64(&bin)
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("quad.gltf");
    std::fs::write(&path, json).unwrap();
    let mut scene = alias_free_shadows::scene::gltf_load::load_gltf(&path).unwrap();
    assert!(
        scene.warnings.iter().any(|w| w.contains("casts as opaque")),
        "{:?}",
        scene.warnings
    );
    assert!(scene.triangles().iter().all(|t| t.alpha.is_none()));
    // Its shadow is the solid quad's: the GPU against the oracle of the
    // same scene with the mask off, every pixel.
    place_on_ground(&mut scene);
    let (_, mut light) = default_view(&scene);
    light.shape = LightShape::Point {
        position: DVec3::new(0.5, 4.0, 2.0),
    };
    let camera = Camera {
        eye: DVec3::new(0.0, 3.0, 5.0),
        target: DVec3::new(0.0, 0.5, -1.0),
        up: DVec3::Y,
        fov_y_deg: 50.0,
        width: 32,
        height: 32,
    };
    let oracle = Oracle::new(&opaque(&scene).triangles(), camera.eye);
    let desc = SceneDescription {
        name: "missing texture".into(),
        scene,
        camera,
        lights: vec![light.clone()],
        shadows: Default::default(),
    };
    let view = engine_view_samples(&oracle, &desc);
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let lit = engine
        .hard_shadows(&desc.scene, camera.eye, &view.samples, &light, 256)
        .unwrap()
        .lit;
    let want = oracle.visibility(&view, &light.light_samples(), None);
    let (mut shadowed, mut differ) = (0, 0);
    for (s, (l, w)) in view.samples.iter().zip(lit.iter().zip(&want)) {
        if s.is_some() {
            shadowed += (*w < 0.5) as usize;
            differ += ((*l == Some(true)) != (*w > 0.5)) as usize;
        }
    }
    assert!(shadowed > 0, "the quad casts no shadow here");
    assert_eq!(differ, 0);
    engine.context().check_validation().unwrap();
}
