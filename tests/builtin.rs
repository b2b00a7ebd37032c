//! Built-in scenes: they build, closed meshes are closed and face outward,
//! counts are what their construction says, cameras and lights frame the
//! shadows, and the committed `assets/<name>.glb` files are current.

use std::path::{Path, PathBuf};

use alias_free_shadows::light::{Distribution, LightShape};
use alias_free_shadows::scene::builtin::{builtin, write_assets, Builtin, NAMES};
use alias_free_shadows::scene::gltf_load::load_gltf;
use alias_free_shadows::scene::{is_closed, AlphaMode, Mesh};
use glam::DVec3;

const REGENERATE: &str = "cargo test --test builtin -- --ignored regenerate_assets";

fn get(name: &str) -> Builtin {
    builtin(name).unwrap_or_else(|e| panic!("builtin {name}: {e}"))
}

fn signed_volume(m: &Mesh) -> f64 {
    (0..m.indices.len())
        .map(|t| {
            let [a, b, c] = m.triangle(t);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Which meshes of each scene must be closed (by name); everything else open.
fn expected_closed(scene: &str, mesh: &str) -> bool {
    !matches!(
        (scene, mesh),
        (_, "ground") | ("hairball", _) | ("fence", _)
    )
}

#[test]
fn every_builtin_builds_with_ground_camera_and_one_light() {
    for name in NAMES {
        let b = get(name);
        b.camera
            .validate()
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((b.camera.width, b.camera.height), (512, 512), "{name}");
        assert_eq!(b.lights.len(), 1, "{name}");
        let l = &b.lights[0];
        assert_eq!(l.distribution, Distribution::Poisson, "{name}");
        assert_eq!(l.seed, 7);
        assert_eq!(l.color, [1.0; 3]);
        assert_eq!(l.intensity, 1.0);
        match (&l.shape, *name) {
            (LightShape::Sphere { radius, .. }, "demo") => {
                assert_eq!(l.samples, 128);
                // About a tenth of the objects' extent.
                let ext = object_bounds(&b);
                let size = (ext.1 - ext.0).max_element();
                assert!(
                    *radius > 0.05 * size && *radius < 0.2 * size,
                    "radius {radius}, objects {size}"
                );
            }
            (LightShape::Point { .. }, n) if n != "demo" => assert_eq!(l.samples, 1),
            (s, n) => panic!("{n}: unexpected light {s:?}"),
        }
        let grounds: Vec<&Mesh> = b
            .scene
            .meshes
            .iter()
            .filter(|m| m.name == "ground")
            .collect();
        assert_eq!(grounds.len(), 1, "{name}");
        assert!(
            b.scene.meshes.len() >= 2,
            "{name}: objects besides the ground"
        );
        for m in &b.scene.meshes {
            assert!(
                m.positions.iter().all(|p| p.is_finite()),
                "{name}/{}",
                m.name
            );
            assert!(m
                .indices
                .iter()
                .flatten()
                .all(|&i| (i as usize) < m.positions.len()));
            if let Some(uv) = &m.uvs {
                assert_eq!(uv.len(), m.positions.len());
            }
            if let Some(mi) = m.material {
                assert!(mi < b.scene.materials.len());
            }
        }
    }
}

#[test]
fn closed_meshes_are_closed_outward_and_open_ones_open() {
    for name in NAMES {
        let b = get(name);
        for m in &b.scene.meshes {
            let want = expected_closed(name, &m.name);
            assert_eq!(is_closed(&m.indices), want, "{name}/{}: is_closed", m.name);
            assert_eq!(m.closed, want, "{name}/{}: Mesh::closed", m.name);
            // No zero-area triangles anywhere.
            for t in 0..m.indices.len() {
                let [a, b2, c] = m.triangle(t);
                assert!(
                    (b2 - a).cross(c - a).length() > 1e-9,
                    "{name}/{} triangle {t} is degenerate",
                    m.name
                );
            }
            if want {
                let v = signed_volume(m);
                assert!(
                    v > 0.0,
                    "{name}/{}: faces must point outward (signed volume {v})",
                    m.name
                );
                // Closed objects stand on or above the ground plane's level (sunk at most 1 cm).
                let lo = m
                    .positions
                    .iter()
                    .map(|p| p.y)
                    .fold(f64::INFINITY, f64::min);
                assert!(lo >= -0.0100001, "{name}/{}: lowest point {lo}", m.name);
            }
        }
    }
}

#[test]
fn closed_volumes_match_their_shapes() {
    // A 32 x 16 UV sphere of radius 1 holds a bit less than 4/3 pi.
    let s = get("plane_sphere");
    let v = signed_volume(&s.scene.meshes[0]);
    assert!(
        v > 0.95 * 4.0 / 3.0 * std::f64::consts::PI && v < 4.0 / 3.0 * std::f64::consts::PI,
        "{v}"
    );
    // Eight steps of 0.4 x 0.25 (stacked columns 1..=8 high) x 2 wide, sunk 1 cm.
    let st = get("stairs");
    let want = 2.0 * 0.4 * 0.25 * (1..=8).sum::<i32>() as f64 + 2.0 * 3.2 * 0.01;
    let v = signed_volume(&st.scene.meshes[0]);
    assert!((v - want).abs() < 1e-9, "stairs volume {v}, want {want}");
}

#[test]
fn triangle_counts_follow_the_construction() {
    let count = |n: &str| get(n).scene.triangle_count();
    // sphere: 2 * 32 segments * 15 bands; ground: 2.
    assert_eq!(count("plane_sphere"), 2 * 32 * 15 + 2);
    // 7 columns of box (12) + 24-sided cylinder (4 * 24) + box (12): the paper's ~840.
    assert_eq!(count("columns"), 7 * (12 + 96 + 12) + 2);
    assert_eq!(count("hairball"), 5000 + 2);
    assert_eq!(count("fence"), 2 + 2);
    // 8 steps: two sides of 2 + 3 * 7 triangles, 8 bottom strips, treads, risers, the back.
    assert_eq!(count("stairs"), 2 * (2 + 3 * 7) + 3 * 2 * 8 + 2 + 2);
    let knot = count("torus_knot") - 2;
    assert!((9_000..=11_000).contains(&knot), "{knot}");
    let demo = count("demo");
    assert!((3_000..=10_000).contains(&demo), "{demo}");
}

#[test]
fn torus_knot_parameter_scales_the_triangle_count() {
    let mut last = 0;
    for n in [100usize, 1_000, 20_000, 250_000] {
        let b = get(&format!("torus_knot:{n}"));
        let got = b.scene.triangle_count() - 2;
        let err = (got as f64 - n as f64).abs() / n as f64;
        assert!(err < 0.1, "torus_knot:{n} gave {got} triangles");
        assert!(got > last);
        last = got;
        assert!(b.scene.meshes[0].closed, "torus_knot:{n}");
    }
    for bad in [
        "torus_knot:99",
        "torus_knot:2000001",
        "torus_knot:abc",
        "torus_knot:",
        "torus_knot:-5",
    ] {
        let e = builtin(bad).unwrap_err().to_string();
        assert!(e.contains("torus_knot"), "{bad}: {e}");
    }
}

#[test]
fn unknown_names_and_stray_parameters_are_errors() {
    let e = builtin("teapot").unwrap_err().to_string();
    assert!(e.contains("teapot"), "{e}");
    for name in NAMES {
        assert!(e.contains(name), "the error lists {name}: {e}");
    }
    let e = builtin("demo:5").unwrap_err().to_string();
    assert!(e.contains("demo") && e.contains("parameter"), "{e}");
    assert!(builtin("").is_err());
}

#[test]
fn builtins_are_deterministic() {
    for name in NAMES {
        let (a, b) = (get(name), get(name));
        assert_eq!(a.scene.meshes.len(), b.scene.meshes.len());
        for (x, y) in a.scene.meshes.iter().zip(&b.scene.meshes) {
            assert_eq!(x.positions, y.positions, "{name}/{}", x.name);
            assert_eq!(x.indices, y.indices, "{name}/{}", x.name);
        }
        assert_eq!(a.camera, b.camera);
        assert_eq!(a.lights, b.lights);
    }
}

#[test]
fn fence_is_an_alpha_masked_textured_quad() {
    let b = get("fence");
    let quad = b.scene.meshes.iter().find(|m| m.name != "ground").unwrap();
    assert_eq!(quad.indices.len(), 2);
    assert!(quad.uvs.is_some());
    let mat = &b.scene.materials[quad.material.unwrap()];
    assert_eq!(mat.alpha_mode, AlphaMode::Mask);
    assert_eq!(mat.alpha_cutoff, 0.5);
    let img = mat
        .base_color_texture
        .as_ref()
        .unwrap()
        .image
        .as_ref()
        .unwrap();
    let opaque = img.pixels().filter(|p| p[3] == 255).count();
    let clear = img.pixels().filter(|p| p[3] == 0).count();
    assert_eq!(opaque + clear, img.pixels().count(), "alpha is 0 or 255");
    let frac = opaque as f64 / (img.width() * img.height()) as f64;
    assert!(frac > 0.2 && frac < 0.8, "lattice coverage {frac}");
}

// ---------------------------------------------------------------------------
// Framing: cast rays from the camera and shadow rays to the light.

fn object_bounds(b: &Builtin) -> (DVec3, DVec3) {
    let mut it = b
        .scene
        .meshes
        .iter()
        .filter(|m| m.name != "ground")
        .flat_map(|m| m.positions.iter());
    let first = *it.next().unwrap();
    it.fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p)))
}

/// Möller-Trumbore; the hit distance along `d`.
fn hit(o: DVec3, d: DVec3, [a, b, c]: [DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 1e-9).then_some(t)
}

/// Nearest hit: (distance, mesh index).
fn trace(tris: &[([DVec3; 3], usize)], o: DVec3, d: DVec3) -> Option<(f64, usize)> {
    tris.iter()
        .filter_map(|(t, m)| hit(o, d, *t).map(|h| (h, *m)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

#[test]
fn cameras_frame_the_objects_and_their_shadows() {
    let mut failures = Vec::new();
    for name in NAMES {
        let b = get(name);
        let cam = {
            let mut c = b.camera;
            c.width = 24;
            c.height = 24;
            c
        };
        let tris: Vec<([DVec3; 3], usize)> = b
            .scene
            .meshes
            .iter()
            .enumerate()
            .flat_map(|(mi, m)| (0..m.indices.len()).map(move |t| (m.triangle(t), mi)))
            .collect();
        let ground = b
            .scene
            .meshes
            .iter()
            .position(|m| m.name == "ground")
            .unwrap();
        let light = match &b.lights[0].shape {
            LightShape::Point { position } | LightShape::Sphere { position, .. } => *position,
            s => panic!("{s:?}"),
        };
        let (mut covered, mut objects, mut ground_px, mut shadowed) = (0, 0, 0, 0);
        for y in 0..cam.height {
            for x in 0..cam.width {
                let d = cam.ray_direction(x, y);
                let Some((t, m)) = trace(&tris, cam.eye, d) else {
                    continue;
                };
                covered += 1;
                if m != ground {
                    objects += 1;
                    continue;
                }
                ground_px += 1;
                let p = cam.eye + d * t;
                let to_light = light - p;
                let dist = to_light.length();
                if trace(&tris, p, to_light / dist).is_some_and(|(h, _)| h < dist) {
                    shadowed += 1;
                }
            }
        }
        let px = (cam.width * cam.height) as f64;
        let (covered, objects) = (covered as f64 / px, objects as f64 / px);
        let shadow = shadowed as f64 / ground_px.max(1) as f64;
        eprintln!(
            "{name}: covered {covered:.2}, objects {objects:.2}, shadowed ground {shadow:.2}"
        );
        if covered <= 0.9 {
            failures.push(format!(
                "{name}: the ground and objects fill only {covered:.2} of the view"
            ));
        }
        if !(objects > 0.04 && objects < 0.6) {
            failures.push(format!("{name}: objects cover {objects:.2} of the view"));
        }
        if !(shadow > 0.03 && shadow < 0.6) {
            failures.push(format!(
                "{name}: shadows cover {shadow:.2} of the visible ground"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

// ---------------------------------------------------------------------------
// Committed assets.

fn assets_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets")
}

#[test]
fn committed_assets_match_the_generators() {
    for name in NAMES {
        let path = assets_dir().join(format!("{name}.glb"));
        let stale = |why: String| -> ! {
            panic!(
                "{} is stale or missing ({why}); regenerate with `{REGENERATE}`",
                path.display()
            )
        };
        let size = std::fs::metadata(&path)
            .unwrap_or_else(|e| stale(e.to_string()))
            .len();
        assert!(
            size < 2 * 1024 * 1024,
            "{}: {size} bytes, keep it under 2 MB",
            path.display()
        );
        let loaded = load_gltf(&path).unwrap_or_else(|e| stale(e.to_string()));
        let generated = get(name).scene;
        if loaded.triangle_count() != generated.triangle_count() {
            stale(format!(
                "{} triangles, the generator makes {}",
                loaded.triangle_count(),
                generated.triangle_count()
            ));
        }
        if loaded.meshes.len() != generated.meshes.len() {
            stale(format!(
                "{} meshes, the generator makes {}",
                loaded.meshes.len(),
                generated.meshes.len()
            ));
        }
        for (l, g) in loaded.meshes.iter().zip(&generated.meshes) {
            if l.name != format!("{}/primitive#0", g.name) {
                stale(format!(
                    "mesh {:?} where the generator has {:?}",
                    l.name, g.name
                ));
            }
            if l.indices != g.indices || l.positions.len() != g.positions.len() {
                stale(format!("mesh {:?}: different triangles", g.name));
            }
            for (k, (p, q)) in l.positions.iter().zip(&g.positions).enumerate() {
                let q32 = DVec3::new(q.x as f32 as f64, q.y as f32 as f64, q.z as f32 as f64);
                if *p != q32 {
                    stale(format!(
                        "mesh {:?} vertex {k}: {p:?} in the file, {q:?} generated",
                        g.name
                    ));
                }
            }
            if l.closed != g.closed {
                stale(format!(
                    "mesh {:?}: closed {} in the file, {} generated",
                    g.name, l.closed, g.closed
                ));
            }
            if l.uvs.is_some() != g.uvs.is_some() {
                stale(format!("mesh {:?}: texture coordinates differ", g.name));
            }
        }
        for (l, g) in loaded.materials.iter().zip(&generated.materials) {
            let limg = l.base_color_texture.as_ref().and_then(|t| t.image.as_ref());
            let gimg = g.base_color_texture.as_ref().and_then(|t| t.image.as_ref());
            if l.alpha_mode != g.alpha_mode || l.alpha_cutoff != g.alpha_cutoff || limg != gimg {
                stale(format!("material {:?} differs", g.name));
            }
        }
        if loaded.materials.len() != generated.materials.len() {
            stale("different materials".into());
        }
    }
}

/// Rewrites `assets/<name>.glb` for every built-in scene. Run with
/// `cargo test --test builtin -- --ignored regenerate_assets`.
#[test]
#[ignore]
fn regenerate_assets() {
    write_assets(&assets_dir()).unwrap();
}

#[test]
fn write_assets_writes_every_scene() {
    let dir = tempfile::tempdir().unwrap();
    write_assets(dir.path()).unwrap();
    for name in NAMES {
        let s = load_gltf(&dir.path().join(format!("{name}.glb"))).unwrap();
        assert_eq!(
            s.triangle_count(),
            get(name).scene.triangle_count(),
            "{name}"
        );
    }
}
