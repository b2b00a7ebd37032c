//! Issue 17, coherent shading (paper §4.3): no light leaks into a triangle
//! that faces away from the light, and the shading is continuous across
//! the shared edges of a smooth mesh. Both are checked on the triangles
//! themselves and, for the first, on a shaded picture; each check also
//! shows that plain smooth (Phong) or flat shading would fail it.

use alias_free_shadows::bench::{bench_light, load_scene};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::scene::file::SceneDescription;
use alias_free_shadows::shade::{shade, ShadingNormals};
use glam::DVec3;

/// Built-in smooth meshes (no `NORMAL`: generated), and Suzanne (glTF
/// `NORMAL`) when `../shared` is there.
fn scenes() -> Vec<SceneDescription> {
    let mut out = vec![
        load_scene("builtin:torus_knot:3000", 64).unwrap(),
        load_scene("builtin:plane_sphere", 64).unwrap(),
    ];
    let suzanne = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/assets/Suzanne/Suzanne.gltf"
    );
    if std::path::Path::new(suzanne).exists() {
        let desc = load_scene(suzanne, 64).unwrap();
        assert!(
            desc.scene.meshes.iter().any(|m| m.normals.is_some()),
            "Suzanne's NORMAL is read"
        );
        out.push(desc);
    }
    out
}

fn light_centre(desc: &SceneDescription) -> DVec3 {
    bench_light(desc, 1).unwrap().center().unwrap()
}

fn corners(desc: &SceneDescription) -> Vec<[DVec3; 3]> {
    desc.scene.triangles().iter().map(|t| t.vertices).collect()
}

/// Points on a triangle: centroid, near each corner, edge midpoints.
const BARYCENTRICS: [[f64; 3]; 7] = [
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
    [0.98, 0.01, 0.01],
    [0.01, 0.98, 0.01],
    [0.01, 0.01, 0.98],
    [0.5, 0.5, 0.0],
    [0.0, 0.5, 0.5],
    [0.5, 0.0, 0.5],
];

#[test]
fn light_back_facing_triangles_shade_to_zero() {
    for desc in scenes() {
        let normals = ShadingNormals::new(&desc.scene);
        let light = light_centre(&desc);
        let to_light = |p: DVec3| (light - p).normalize();
        let (mut back_facing, mut phong_leaks) = (0, 0);
        for (t, v) in corners(&desc).iter().enumerate() {
            let face = normals.face_normal(t);
            // Both sides: a double-sided surface is seen from either.
            for side in [1.0, -1.0] {
                if face == DVec3::ZERO || v.iter().any(|&p| side * face.dot(light - p) >= 0.0) {
                    continue;
                }
                back_facing += 1;
                for b in BARYCENTRICS {
                    let b = DVec3::from_array(b);
                    let lambert = normals.lambert(t, b, side * face, to_light);
                    assert_eq!(
                        lambert, 0.0,
                        "{}: triangle {t}, side {side}, at {b}",
                        desc.name
                    );
                    let n: DVec3 = (0..3)
                        .map(|i| b[i] * side * normals.corner_normal(t, i))
                        .sum();
                    let p: DVec3 = (0..3).map(|i| b[i] * v[i]).sum();
                    if n.normalize().dot(to_light(p)) > 1e-3 {
                        phong_leaks += 1;
                    }
                }
            }
        }
        assert!(back_facing > 0, "{}: some triangles face away", desc.name);
        assert!(
            phong_leaks > 0,
            "{}: plain smooth normals would light some of them (the test has teeth)",
            desc.name
        );
        println!(
            "{}: {back_facing} back-facing (triangle, side), Phong lights {phong_leaks} points",
            desc.name
        );
    }
}

#[test]
fn shading_is_continuous_across_shared_edges() {
    for desc in scenes() {
        let normals = ShadingNormals::new(&desc.scene);
        let light = light_centre(&desc);
        let to_light = |p: DVec3| (light - p).normalize();
        // Edges shared by two triangles of a mesh, by vertex position.
        let mut edges: std::collections::HashMap<_, Vec<(usize, usize, usize)>> =
            Default::default();
        let mut t = 0;
        for mesh in &desc.scene.meshes {
            let key = |v: u32| mesh.positions[v as usize].to_array().map(f64::to_bits);
            for tri in &mesh.indices {
                for i in 0..3 {
                    let (a, b) = (key(tri[i]), key(tri[(i + 1) % 3]));
                    let k = if a < b { (a, b) } else { (b, a) };
                    edges.entry(k).or_default().push((t, i, (i + 1) % 3));
                }
                t += 1;
            }
        }
        let (mut checked, mut flat_jumps, mut worst) = (0, 0, 0.0f64);
        for sides in edges.values().filter(|s| s.len() == 2) {
            let [(t0, a0, b0), (t1, a1, b1)] = [sides[0], sides[1]];
            let (n0, n1) = (normals.face_normal(t0), normals.face_normal(t1));
            // Inside a smoothing group only (a crease may jump).
            if n0 == DVec3::ZERO || n1 == DVec3::ZERO || n0.dot(n1) < 0.9 {
                continue;
            }
            let v0 = desc.scene.triangles()[t0].vertices;
            for f in [0.25, 0.5, 0.75] {
                let p = v0[a0] * (1.0 - f) + v0[b0] * f;
                let at = |t: usize, a: usize, b: usize, va: DVec3| {
                    // The same point in t's corners: the edge runs a -> b
                    // in t0 and b -> a in a consistently oriented t1.
                    let g = if va == v0[a0] { f } else { 1.0 - f };
                    let mut bary = DVec3::ZERO;
                    bary[a] = 1.0 - g;
                    bary[b] = g;
                    normals.lambert(t, bary, normals.face_normal(t), to_light)
                };
                let s0 = at(t0, a0, b0, v0[a0]);
                let v1 = desc.scene.triangles()[t1].vertices;
                let s1 = at(t1, a1, b1, v1[a1]);
                worst = worst.max((s0 - s1).abs());
                let flat = |n: DVec3| n.dot((light - p).normalize()).max(0.0);
                if (flat(n0) - flat(n1)).abs() > 1e-3 {
                    flat_jumps += 1;
                }
                checked += 1;
            }
        }
        assert!(checked > 100, "{}: {checked} edge points", desc.name);
        assert!(
            worst <= 1e-9,
            "{}: the shading jumps by {worst} across an edge",
            desc.name
        );
        assert!(
            flat_jumps > 0,
            "{}: flat shading would jump (the test has teeth)",
            desc.name
        );
        println!(
            "{}: {checked} edge points, largest jump {worst:e}, flat would jump at {flat_jumps}",
            desc.name
        );
    }
}

/// In the picture: every pixel on a light-back-facing triangle (as seen
/// from the camera) is the ambient colour, with the light fully visible.
#[test]
fn back_facing_pixels_are_ambient_in_the_picture() {
    let desc = load_scene("builtin:torus_knot:3000", 64).unwrap();
    let oracle = Oracle::new(&desc.scene.triangles(), desc.camera.eye);
    let view = oracle.primary_view_samples(&desc.camera);
    let light = light_centre(&desc);
    let lights = vec![bench_light(&desc, 1)
        .map(|l| alias_free_shadows::light::Light {
            shape: alias_free_shadows::light::LightShape::Point { position: light },
            ..l
        })
        .unwrap()];
    let visible = vec![vec![1.0f32; view.samples.len()]];
    let normals = ShadingNormals::new(&desc.scene);
    let image = shade(&desc.scene, &normals, &view, &lights, &visible);
    let none = vec![vec![0.0f32; view.samples.len()]];
    let dark = shade(&desc.scene, &normals, &view, &lights, &none);
    let triangles = desc.scene.triangles();
    let mut back_facing = 0;
    for (i, s) in view.samples.iter().enumerate() {
        let Some(s) = s else { continue };
        let v = triangles[s.triangle as usize].vertices;
        if v.iter().all(|&p| s.normal.dot(light - p) < 0.0) {
            back_facing += 1;
            let (x, y) = (i as u32 % view.width, i as u32 / view.width);
            assert_eq!(
                image.get_pixel(x, y),
                dark.get_pixel(x, y),
                "pixel ({x}, {y})"
            );
        }
    }
    assert!(back_facing > 20, "{back_facing} back-facing pixels");
}
