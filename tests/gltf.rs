//! glTF loading and writing: hand-built files with known answers, the real
//! sample models in `../shared/assets`, and malformed input (which must give
//! an error naming the file, never a panic).

use std::path::{Path, PathBuf};

use alias_free_shadows::light::LightShape;
use alias_free_shadows::scene::builtin::builtin;
use alias_free_shadows::scene::gltf_load::{load_gltf, load_gltf_slice};
use alias_free_shadows::scene::gltf_write::write_glb;
use alias_free_shadows::scene::{is_closed, AlphaMode, Material, Mesh, Scene, Texture};
use glam::{DVec2, DVec3};
use serde_json::{json, Value};

mod common;
use common::base64;

// ---------------------------------------------------------------------------
// Building test files by hand.

/// A glTF document under construction: JSON plus one binary buffer.
struct Doc {
    root: Value,
    bin: Vec<u8>,
}

impl Doc {
    fn new() -> Self {
        Doc {
            root: json!({"asset": {"version": "2.0"}, "accessors": [], "bufferViews": []}),
            bin: Vec::new(),
        }
    }

    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let views = self.root["bufferViews"].as_array_mut().unwrap();
        views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        views.len() - 1
    }

    fn accessor(&mut self, bytes: &[u8], mut acc: Value) -> usize {
        acc["bufferView"] = json!(self.view(bytes));
        let accs = self.root["accessors"].as_array_mut().unwrap();
        accs.push(acc);
        accs.len() - 1
    }

    fn positions(&mut self, p: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = p.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let mut lo = [f32::MAX; 3];
        let mut hi = [f32::MIN; 3];
        for v in p {
            for c in 0..3 {
                lo[c] = lo[c].min(v[c]);
                hi[c] = hi[c].max(v[c]);
            }
        }
        // JSON has no NaN or infinity: keep min/max finite for such test files.
        let clean = |a: [f32; 3]| a.map(|v| if v.is_finite() { v } else { 0.0 });
        self.accessor(
            &bytes,
            json!({"componentType": 5126, "count": p.len(), "type": "VEC3", "min": clean(lo), "max": clean(hi)}),
        )
    }

    fn uvs(&mut self, uv: &[[f32; 2]]) -> usize {
        let bytes: Vec<u8> = uv.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        self.accessor(
            &bytes,
            json!({"componentType": 5126, "count": uv.len(), "type": "VEC2"}),
        )
    }

    fn indices_u8(&mut self, i: &[u8]) -> usize {
        self.accessor(
            i,
            json!({"componentType": 5121, "count": i.len(), "type": "SCALAR"}),
        )
    }

    fn indices_u16(&mut self, i: &[u16]) -> usize {
        let bytes: Vec<u8> = i.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.accessor(
            &bytes,
            json!({"componentType": 5123, "count": i.len(), "type": "SCALAR"}),
        )
    }

    fn indices_u32(&mut self, i: &[u32]) -> usize {
        let bytes: Vec<u8> = i.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.accessor(
            &bytes,
            json!({"componentType": 5125, "count": i.len(), "type": "SCALAR"}),
        )
    }

    /// A one-primitive mesh; returns its index.
    fn mesh(&mut self, name: &str, prim: Value) -> usize {
        let meshes = self
            .root
            .as_object_mut()
            .unwrap()
            .entry("meshes")
            .or_insert(json!([]));
        let meshes = meshes.as_array_mut().unwrap();
        meshes.push(json!({"name": name, "primitives": [prim]}));
        meshes.len() - 1
    }

    /// Sets the nodes and a default scene made of `roots`.
    fn nodes(&mut self, nodes: Value, roots: &[usize]) {
        self.root["nodes"] = nodes;
        self.root["scenes"] = json!([{"nodes": roots}]);
        self.root["scene"] = json!(0);
    }

    /// `.gltf` bytes with the buffer embedded as a base64 data URI.
    fn gltf(&self) -> Vec<u8> {
        let mut root = self.root.clone();
        if !self.bin.is_empty() {
            root["buffers"] = json!([{
                "byteLength": self.bin.len(),
                "uri": format!("data:application/octet-stream;base64,{}", base64(&self.bin)),
            }]);
        }
        serde_json::to_vec_pretty(&root).unwrap()
    }

    /// `.gltf` bytes referring to an external buffer file `uri`.
    fn gltf_external(&self, uri: &str) -> Vec<u8> {
        let mut root = self.root.clone();
        root["buffers"] = json!([{"byteLength": self.bin.len(), "uri": uri}]);
        serde_json::to_vec_pretty(&root).unwrap()
    }

    /// `.glb` bytes, assembled here by hand (not with the crate's writer).
    fn glb(&self) -> Vec<u8> {
        let mut root = self.root.clone();
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        if !bin.is_empty() {
            root["buffers"] = json!([{"byteLength": bin.len()}]);
        }
        let mut js = serde_json::to_vec(&root).unwrap();
        while !js.len().is_multiple_of(4) {
            js.push(b' ');
        }
        let total = 12 + 8 + js.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(js.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&js);
        if !bin.is_empty() {
            out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&bin);
        }
        out
    }
}

fn load(bytes: &[u8], name: &str) -> alias_free_shadows::Result<Scene> {
    load_gltf_slice(bytes, None, name)
}

fn load_ok(bytes: &[u8]) -> Scene {
    match load(bytes, "test.gltf") {
        Ok(s) => s,
        Err(e) => panic!("expected the file to load, got: {e}"),
    }
}

/// The error text, failing the test when loading succeeded.
fn load_err(bytes: &[u8], name: &str) -> String {
    match load(bytes, name) {
        Ok(s) => panic!(
            "expected an error for {name}, got a scene with {} triangles",
            s.triangle_count()
        ),
        Err(e) => e.to_string(),
    }
}

fn assert_close(got: DVec3, want: [f64; 3], tol: f64) {
    let want = DVec3::from(want);
    assert!(
        (got - want).abs().max_element() <= tol,
        "got {got:?}, want {want:?}"
    );
}

fn normal(m: &Mesh, t: usize) -> DVec3 {
    let [a, b, c] = m.triangle(t);
    (b - a).cross(c - a)
}

fn signed_volume(m: &Mesh) -> f64 {
    (0..m.indices.len())
        .map(|t| {
            let [a, b, c] = m.triangle(t);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// A unit cube (0..1) with 24 vertices (four per face, as exporters write
/// them for per-face normals and UVs) and outward counter-clockwise triangles.
fn seamed_cube(faces: usize) -> (Vec<[f32; 3]>, Vec<u16>) {
    // (corner of the face, two edge vectors in counter-clockwise order seen from outside)
    let f: [([f32; 3], [f32; 3], [f32; 3]); 6] = [
        ([1., 0., 0.], [0., 1., 0.], [0., 0., 1.]), // +x
        ([0., 0., 0.], [0., 0., 1.], [0., 1., 0.]), // -x
        ([0., 1., 0.], [0., 0., 1.], [1., 0., 0.]), // +y
        ([0., 0., 0.], [1., 0., 0.], [0., 0., 1.]), // -y
        ([0., 0., 1.], [1., 0., 0.], [0., 1., 0.]), // +z
        ([0., 0., 0.], [0., 1., 0.], [1., 0., 0.]), // -z
    ];
    let mut p = Vec::new();
    let mut idx = Vec::new();
    for (o, u, v) in f.iter().take(faces) {
        let base = p.len() as u16;
        let add = |a: f32, b: f32| {
            [
                o[0] + a * u[0] + b * v[0],
                o[1] + a * u[1] + b * v[1],
                o[2] + a * u[2] + b * v[2],
            ]
        };
        p.extend([add(0., 0.), add(1., 0.), add(1., 1.), add(0., 1.)]);
        idx.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    (p, idx)
}

const S: f32 = std::f32::consts::FRAC_1_SQRT_2;

// ---------------------------------------------------------------------------
// Hand-built files with known answers.

#[test]
fn trs_node_transform_gives_exact_world_positions() {
    let mut d = Doc::new();
    let pos = d.positions(&[[1., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
    d.mesh("tri", json!({"attributes": {"POSITION": pos}}));
    d.nodes(
        json!([{"mesh": 0, "translation": [10., 20., 30.], "rotation": [0., 0., S, S], "scale": [2., 3., 4.]}]),
        &[0],
    );
    for bytes in [d.gltf(), d.glb()] {
        let s = load_ok(&bytes);
        assert_eq!(s.meshes.len(), 1);
        let m = &s.meshes[0];
        assert_eq!(m.name, "tri/primitive#0");
        assert_eq!(m.indices, vec![[0, 1, 2]]);
        // scale, then 90 degrees about z ((x, y) -> (-y, x)), then translate.
        assert_close(m.positions[0], [10., 22., 30.], 1e-6);
        assert_close(m.positions[1], [7., 20., 30.], 1e-6);
        assert_close(m.positions[2], [10., 20., 34.], 1e-6);
        assert!(!m.closed);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }
}

#[test]
fn node_hierarchy_composes_parent_and_child_transforms() {
    let mut d = Doc::new();
    let pos = d.positions(&[[1., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
    d.mesh("tri", json!({"attributes": {"POSITION": pos}}));
    // grandparent: column-major matrix translating by (100, 0, 0);
    // parent: translate (0, 5, 0), scale 2; child: translate (1, 0, 0), 180 degrees about y.
    d.nodes(
        json!([
            {"children": [1], "matrix": [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 100., 0., 0., 1.]},
            {"children": [2], "translation": [0., 5., 0.], "scale": [2., 2., 2.]},
            {"mesh": 0, "translation": [1., 0., 0.], "rotation": [0., 1., 0., 0.]},
        ]),
        &[0],
    );
    let s = load_ok(&d.gltf());
    let m = &s.meshes[0];
    assert_close(m.positions[0], [100., 5., 0.], 1e-9);
    assert_close(m.positions[1], [102., 7., 0.], 1e-9);
    assert_close(m.positions[2], [102., 5., -2.], 1e-9);
}

#[test]
fn only_nodes_of_the_default_scene_are_loaded() {
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    d.mesh("a", json!({"attributes": {"POSITION": pos}}));
    d.mesh("b", json!({"attributes": {"POSITION": pos}}));
    d.root["nodes"] = json!([{"mesh": 0}, {"mesh": 1}]);
    d.root["scenes"] = json!([{"nodes": [0]}, {"nodes": [1]}]);
    d.root["scene"] = json!(1);
    let s = load_ok(&d.gltf());
    assert_eq!(s.meshes.len(), 1);
    assert_eq!(s.meshes[0].name, "b/primitive#0");
    // Without "scene", the first scene.
    d.root.as_object_mut().unwrap().remove("scene");
    assert_eq!(load_ok(&d.gltf()).meshes[0].name, "a/primitive#0");
    // Without scenes, every root node.
    d.root.as_object_mut().unwrap().remove("scenes");
    assert_eq!(load_ok(&d.gltf()).meshes.len(), 2);
}

#[test]
fn indexed_primitives_of_every_index_type() {
    let quad = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let idx = [0u8, 1, 2, 0, 2, 3];
    for ty in 0..3 {
        let mut d = Doc::new();
        let pos = d.positions(&quad);
        let ia = match ty {
            0 => d.indices_u8(&idx),
            1 => d.indices_u16(&idx.map(|i| i as u16)),
            _ => d.indices_u32(&idx.map(|i| i as u32)),
        };
        d.mesh(
            "quad",
            json!({"attributes": {"POSITION": pos}, "indices": ia, "mode": 4}),
        );
        // The same mesh instanced by two nodes.
        d.nodes(
            json!([{"mesh": 0}, {"mesh": 0, "translation": [0., 0., 5.]}]),
            &[0, 1],
        );
        let s = load_ok(&d.glb());
        assert_eq!(s.triangle_count(), 4, "index type {ty}");
        assert_eq!(s.meshes.len(), 2);
        assert_eq!(s.meshes[0].indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(s.meshes[1].positions[2], DVec3::new(1., 1., 5.));
    }
}

#[test]
fn triangle_strip_and_fan_become_front_facing_triangles() {
    // Strip: (v0 v1 v2), (v1 v3 v2), (v2 v3 v4), all counter-clockwise seen from +z.
    let mut d = Doc::new();
    let pos = d.positions(&[
        [0., 0., 0.],
        [1., 0., 0.],
        [0., 1., 0.],
        [1., 1., 0.],
        [0., 2., 0.],
    ]);
    d.mesh("strip", json!({"attributes": {"POSITION": pos}, "mode": 5}));
    // Fan around v0: (v1 v2 v0), (v2 v3 v0), (v3 v4 v0).
    let pos2 = d.positions(&[
        [0., 0., 0.],
        [1., 0., 0.],
        [1., 1., 0.],
        [0., 1., 0.],
        [-1., 1., 0.],
    ]);
    let fan_idx = d.indices_u16(&[0, 1, 2, 3, 4]);
    d.mesh(
        "fan",
        json!({"attributes": {"POSITION": pos2}, "indices": fan_idx, "mode": 6}),
    );
    d.nodes(json!([{"mesh": 0}, {"mesh": 1}]), &[0, 1]);
    let s = load_ok(&d.gltf());
    assert_eq!(s.meshes.len(), 2);
    let strip = &s.meshes[0];
    assert_eq!(strip.indices.len(), 3);
    let fan = &s.meshes[1];
    assert_eq!(fan.indices.len(), 3);
    for m in [strip, fan] {
        for t in 0..3 {
            let n = normal(m, t);
            assert!(
                n.z > 0.0 && n.x == 0.0 && n.y == 0.0,
                "{} triangle {t}: normal {n:?}",
                m.name
            );
        }
    }
    // The strip's triangles are exactly the spec's.
    let mut tris: Vec<[u32; 3]> = strip.indices.iter().map(|t| rotate_min_first(*t)).collect();
    tris.sort();
    assert_eq!(tris, vec![[0, 1, 2], [1, 3, 2], [2, 3, 4]]);
}

fn rotate_min_first(t: [u32; 3]) -> [u32; 3] {
    let k = (0..3).min_by_key(|&k| t[k]).unwrap();
    [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
}

#[test]
fn mirrored_transform_keeps_front_faces_and_outward_orientation() {
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    d.mesh("tri", json!({"attributes": {"POSITION": pos}}));
    let (cube, idx) = seamed_cube(6);
    let cpos = d.positions(&cube);
    let cidx = d.indices_u16(&idx);
    d.mesh(
        "cube",
        json!({"attributes": {"POSITION": cpos}, "indices": cidx}),
    );
    d.nodes(
        json!([{"mesh": 0, "scale": [-1., 1., 1.]}, {"mesh": 1, "scale": [1., -2., 1.], "translation": [0., 10., 0.]}]),
        &[0, 1],
    );
    let s = load_ok(&d.gltf());
    let tri = &s.meshes[0];
    assert_eq!(tri.positions[1], DVec3::new(-1., 0., 0.));
    // Mirroring x does not turn the triangle around: its front still faces +z.
    assert!(normal(tri, 0).z > 0.0, "{:?}", normal(tri, 0));
    let cube = &s.meshes[1];
    assert!(cube.closed);
    assert!(
        signed_volume(cube) > 1.99 && signed_volume(cube) < 2.01,
        "volume {}",
        signed_volume(cube)
    );
}

#[test]
fn closed_is_computed_on_positions_welded_across_seams() {
    let mut d = Doc::new();
    let (cube, idx) = seamed_cube(6);
    let p = d.positions(&cube);
    let i = d.indices_u16(&idx);
    d.mesh("cube", json!({"attributes": {"POSITION": p}, "indices": i}));
    let (open, oidx) = seamed_cube(5);
    let p2 = d.positions(&open);
    let i2 = d.indices_u16(&oidx);
    d.mesh(
        "open_box",
        json!({"attributes": {"POSITION": p2}, "indices": i2}),
    );
    d.nodes(json!([{"mesh": 0}, {"mesh": 1}]), &[0, 1]);
    let s = load_ok(&d.glb());
    let cube = &s.meshes[0];
    // Unwelded as stored (24 vertices), so `is_closed` on the raw indices is false...
    assert_eq!(cube.positions.len(), 24);
    assert!(!is_closed(&cube.indices));
    // ...but the loader welds by position for the flag.
    assert!(cube.closed);
    assert!((signed_volume(cube) - 1.0).abs() < 1e-12);
    assert!(!s.meshes[1].closed);
}

/// One primitive holding two seamed cubes (closed) and an open box (five
/// faces): the closed cubes become closed meshes of their own, the box
/// stays open under the primitive's name, and nothing is lost or moved.
#[test]
fn closed_parts_of_an_open_primitive_cast_as_closed_meshes() {
    // One primitive: the open box at the origin, then a seamed cube at
    // each x offset of `cubes`.
    let load_parts = |name: &str, cubes: &[f32]| {
        let (cube, cidx) = seamed_cube(6);
        let (mut positions, mut indices) = seamed_cube(5);
        for &dx in cubes {
            let base = positions.len() as u16;
            positions.extend(cube.iter().map(|v| [v[0] + dx, v[1], v[2]]));
            indices.extend(cidx.iter().map(|i| i + base));
        }
        let mut d = Doc::new();
        let p = d.positions(&positions);
        let i = d.indices_u16(&indices);
        d.mesh(name, json!({"attributes": {"POSITION": p}, "indices": i}));
        d.nodes(json!([{"mesh": 0}]), &[0]);
        load_ok(&d.glb())
    };
    let s = load_parts("parts", &[2.0, 4.0]);
    let names: Vec<&str> = s.meshes.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "parts/primitive#0",
            "parts/primitive#0/closed#0",
            "parts/primitive#0/closed#1"
        ]
    );
    assert_eq!(
        s.meshes.iter().map(|m| m.closed).collect::<Vec<_>>(),
        [false, true, true]
    );
    assert_eq!(s.meshes[0].indices.len(), 10);
    assert_eq!(s.meshes[0].positions.len(), 20, "only the box's vertices");
    for (k, dx) in [(1, 2.0), (2, 4.0)] {
        let m = &s.meshes[k];
        assert_eq!((m.indices.len(), m.positions.len()), (12, 24));
        assert!(
            (signed_volume(m) - 1.0).abs() < 1e-12,
            "outward, unit volume"
        );
        let lo = m.positions.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
        assert_eq!(lo, DVec3::new(dx, 0.0, 0.0));
    }
    // A cube that shares a corner position with the box joins its part:
    // that part is open, so nothing splits.
    let s = load_parts("joined", &[1.0]);
    assert_eq!(s.meshes.len(), 1);
    assert!(!s.meshes[0].closed);
    assert_eq!(s.meshes[0].indices.len(), 22);
}

#[test]
fn points_and_lines_are_skipped_with_a_warning() {
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    d.mesh(
        "points",
        json!({"attributes": {"POSITION": pos}, "mode": 0}),
    );
    d.mesh("lines", json!({"attributes": {"POSITION": pos}, "mode": 1}));
    d.mesh("tri", json!({"attributes": {"POSITION": pos}, "mode": 4}));
    d.nodes(json!([{"mesh": 0}, {"mesh": 1}, {"mesh": 2}]), &[0, 1, 2]);
    let s = load_ok(&d.gltf());
    assert_eq!(s.meshes.len(), 1);
    assert_eq!(s.meshes[0].name, "tri/primitive#0");
    assert_eq!(s.warnings.len(), 2, "{:?}", s.warnings);
    assert!(
        s.warnings[0].contains("points/primitive#0"),
        "{:?}",
        s.warnings
    );
    assert!(
        s.warnings[1].contains("lines/primitive#0"),
        "{:?}",
        s.warnings
    );
}

#[test]
fn perspective_cameras_are_read_and_orthographic_ones_skipped() {
    let mut d = Doc::new();
    d.root["cameras"] = json!([
        {"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}},
        {"type": "orthographic", "orthographic": {"xmag": 1., "ymag": 1., "znear": 0.1, "zfar": 10.}},
        {"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}},
    ]);
    // 90 degrees about y turns the camera's -z view direction to -x.
    d.nodes(
        json!([
            {"camera": 0, "translation": [1., 2., 3.], "rotation": [0., S, 0., S]},
            {"camera": 1},
            {"children": [3], "translation": [0., 0., 10.]},
            {"camera": 2},
        ]),
        &[0, 1, 2],
    );
    let s = load_ok(&d.gltf());
    assert_eq!(s.cameras.len(), 2, "{:?}", s.cameras);
    let c = &s.cameras[0];
    assert_close(c.eye, [1., 2., 3.], 1e-12);
    assert_close((c.target - c.eye).normalize(), [-1., 0., 0.], 1e-6);
    assert_close(c.up.normalize(), [0., 1., 0.], 1e-6);
    assert!((c.fov_y_deg - 0.8f32 as f64 * 180.0 / std::f64::consts::PI).abs() < 1e-9);
    assert_eq!((c.width, c.height), (768, 512));
    let c2 = &s.cameras[1];
    assert_close(c2.eye, [0., 0., 10.], 0.0);
    assert_close((c2.target - c2.eye).normalize(), [0., 0., -1.], 1e-12);
    assert_eq!((c2.width, c2.height), (512, 512));
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(s.warnings[0].contains("orthographic"), "{:?}", s.warnings);
}

/// `KHR_lights_punctual`: point lights at their node's origin,
/// directional ones along its -z, spot lights as point lights with a
/// warning; the colour kept; a scene loaded from the file uses them instead
/// of the default light.
#[test]
fn punctual_lights_are_read() {
    let mut d = Doc::new();
    d.root["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    d.root["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 40.0},
        {"type": "directional"},
        {"type": "spot", "spot": {"outerConeAngle": 0.5}},
    ]}});
    // -90 degrees about x turns the light's -z to -y (straight down).
    d.nodes(
        json!([
            {"children": [1], "translation": [0., 1., 0.]},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [1., 2., 3.]},
            {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": [-S, 0., 0., S]},
            {"extensions": {"KHR_lights_punctual": {"light": 2}}, "translation": [0., 5., 0.]},
            {"extensions": {"KHR_lights_punctual": {"light": 7}}},
        ]),
        &[0, 2, 3, 4],
    );
    let s = load_ok(&d.gltf());
    assert_eq!(s.lights.len(), 3, "{:?}", s.lights);
    match s.lights[0].shape {
        LightShape::Point { position } => assert_close(position, [1., 3., 3.], 1e-12),
        ref other => panic!("{other:?}"),
    }
    assert_eq!(s.lights[0].color, [1.0, 0.5, 0.25]);
    match s.lights[1].shape {
        LightShape::Directional { direction } => assert_close(direction, [0., -1., 0.], 1e-6),
        ref other => panic!("{other:?}"),
    }
    match s.lights[2].shape {
        LightShape::Point { position } => assert_close(position, [0., 5., 0.], 1e-12),
        ref other => panic!("{other:?}"),
    }
    let warned = |needle: &str| s.warnings.iter().any(|w| w.contains(needle));
    assert!(warned("is used as a point light"), "{:?}", s.warnings);
    assert!(warned("light 7 does not exist"), "{:?}", s.warnings);

    // Through the scene loader: the file's lights, not the default one.
    let dir = tempfile::tempdir().unwrap();
    let mut d2 = Doc::new();
    let pos = d2.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 0., 1.]]);
    d2.root["meshes"] = json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]);
    d2.root["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    d2.root["extensions"] = json!({"KHR_lights_punctual": {"lights": [{"type": "point"}]}});
    d2.nodes(
        json!([
            {"mesh": 0},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0.25, 4., 0.25]},
        ]),
        &[0, 1],
    );
    let path = dir.path().join("lit.gltf");
    std::fs::write(&path, d2.gltf()).unwrap();
    let desc = alias_free_shadows::scene::file::load(path.to_str().unwrap()).unwrap();
    assert_eq!(desc.lights.len(), 1);
    assert_eq!(
        desc.lights[0].shape,
        LightShape::Point {
            position: DVec3::new(0.25, 4., 0.25)
        }
    );
}

#[test]
fn sparse_accessors_replace_base_values() {
    let mut d = Doc::new();
    let base: Vec<u8> = [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let bv = d.view(&base);
    let iv = d.view(&1u16.to_le_bytes());
    let vals: Vec<u8> = [5f32, 6., 7.]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let vv = d.view(&vals);
    d.root["accessors"] = json!([{
        "bufferView": bv, "componentType": 5126, "count": 3, "type": "VEC3",
        "min": [0, 0, 0], "max": [5, 6, 7],
        "sparse": {"count": 1, "indices": {"bufferView": iv, "componentType": 5123},
                   "values": {"bufferView": vv}}
    }]);
    d.mesh("sparse", json!({"attributes": {"POSITION": 0}}));
    d.nodes(json!([{"mesh": 0}]), &[0]);
    let s = load_ok(&d.gltf());
    assert_eq!(
        s.meshes[0].positions,
        vec![DVec3::ZERO, DVec3::new(5., 6., 7.), DVec3::new(0., 1., 0.)]
    );
}

#[test]
fn quantized_positions_and_tolerated_extensions() {
    let mut d = Doc::new();
    let q: Vec<u8> = [[0i16, 0, 0], [32767, 0, 0], [0, 32767, 0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    d.accessor(
        &q,
        json!({"componentType": 5122, "normalized": true, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}),
    );
    d.mesh("q", json!({"attributes": {"POSITION": 0}}));
    d.nodes(json!([{"mesh": 0}]), &[0]);
    d.root["extensionsUsed"] = json!(["KHR_mesh_quantization", "KHR_materials_unlit"]);
    d.root["extensionsRequired"] = json!(["KHR_mesh_quantization", "KHR_materials_unlit"]);
    let s = load_ok(&d.gltf());
    assert_eq!(s.meshes[0].positions[1], DVec3::new(1., 0., 0.));
    assert_eq!(s.meshes[0].positions[2], DVec3::new(0., 1., 0.));
}

fn png(img: &image::RgbaImage) -> Vec<u8> {
    let mut c = std::io::Cursor::new(Vec::new());
    img.write_to(&mut c, image::ImageFormat::Png).unwrap();
    c.into_inner()
}

fn test_image() -> image::RgbaImage {
    image::RgbaImage::from_fn(2, 2, |x, y| {
        image::Rgba([10 * x as u8, 20 * y as u8, 30, if x == y { 255 } else { 0 }])
    })
}

#[test]
fn base_colour_textures_from_buffer_views_and_data_uris() {
    let img = test_image();
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    let uv = d.uvs(&[[0., 0.], [1., 0.], [0., 1.]]);
    let view = d.view(&png(&img));
    d.root["images"] = json!([
        {"bufferView": view, "mimeType": "image/png"},
        {"uri": format!("data:image/png;base64,{}", base64(&png(&img)))},
    ]);
    d.root["textures"] = json!([{"source": 0}, {"source": 1}]);
    d.root["materials"] = json!([
        {"name": "masked", "alphaMode": "MASK", "alphaCutoff": 0.3,
         "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, 0.75], "baseColorTexture": {"index": 0}}},
        {"name": "blend", "alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}},
        {},
    ]);
    d.mesh(
        "t",
        json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 0}),
    );
    d.nodes(json!([{"mesh": 0}]), &[0]);
    for bytes in [d.glb(), d.gltf()] {
        let s = load_ok(&bytes);
        // The one warning: BLEND casts as MASK at 0.5 (the issue's rule).
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(
            s.warnings[0].contains("material \"blend\": BLEND is cast and seen as MASK"),
            "{:?}",
            s.warnings
        );
        assert_eq!(s.materials.len(), 3);
        let m = &s.materials[0];
        assert_eq!(m.name, "masked");
        assert_eq!(m.alpha_mode, AlphaMode::Mask);
        assert_eq!(m.alpha_cutoff, 0.3);
        assert_eq!(m.base_color_factor, [0.5, 0.25, 1.0, 0.75]);
        assert_eq!(
            m.base_color_texture.as_ref().unwrap().image.as_deref(),
            Some(&img)
        );
        let b = &s.materials[1];
        assert_eq!(b.alpha_mode, AlphaMode::Blend);
        assert_eq!(b.alpha_cutoff, 0.5);
        assert_eq!(b.base_color_factor, [1.0; 4]);
        assert_eq!(
            b.base_color_texture.as_ref().unwrap().image.as_deref(),
            Some(&img)
        );
        let o = &s.materials[2];
        assert_eq!(o.alpha_mode, AlphaMode::Opaque);
        assert!(o.base_color_texture.is_none());
        let mesh = &s.meshes[0];
        assert_eq!(mesh.material, Some(0));
        assert_eq!(
            mesh.uvs.as_deref(),
            Some(&[DVec2::new(0., 0.), DVec2::new(1., 0.), DVec2::new(0., 1.)][..])
        );
    }
}

#[test]
fn missing_texture_files_are_warnings_not_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    std::fs::write(dir.path().join("present.png"), png(&test_image())).unwrap();
    std::fs::write(dir.path().join("corrupt.png"), b"not a png").unwrap();
    d.root["images"] = json!([{"uri": "missing_base.png"}, {"uri": "missing%20normal.png"}, {"uri": "present.png"}, {"uri": "corrupt.png"}]);
    d.root["textures"] = json!([{"source": 0}, {"source": 1}, {"source": 2}, {"source": 3}]);
    d.root["materials"] = json!([
        {"name": "m0", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "normalTexture": {"index": 1}},
        {"name": "m1", "pbrMetallicRoughness": {"baseColorTexture": {"index": 2}}, "occlusionTexture": {"index": 2}},
        {"name": "m2", "pbrMetallicRoughness": {"baseColorTexture": {"index": 3}}},
    ]);
    d.mesh("t", json!({"attributes": {"POSITION": pos}, "material": 0}));
    d.nodes(json!([{"mesh": 0}]), &[0]);
    let path = dir.path().join("model.gltf");
    std::fs::write(&path, d.gltf()).unwrap();
    let s = load_gltf(&path).unwrap();
    assert_eq!(s.triangle_count(), 1);
    let w = s.warnings.join("\n");
    assert_eq!(s.warnings.len(), 3, "{w}");
    assert!(
        w.contains("missing_base.png") && w.contains("not found"),
        "{w}"
    );
    assert!(
        w.contains("missing normal.png") && w.contains("shadows do not need it"),
        "{w}"
    );
    assert!(w.contains("corrupt.png") && w.contains("decoded"), "{w}");
    let t0 = s.materials[0].base_color_texture.as_ref().unwrap();
    assert!(t0.image.is_none());
    assert!(t0.source.contains("missing_base.png"));
    assert_eq!(
        s.materials[1]
            .base_color_texture
            .as_ref()
            .unwrap()
            .image
            .as_deref(),
        Some(&test_image())
    );
    assert!(s.materials[2]
        .base_color_texture
        .as_ref()
        .unwrap()
        .image
        .is_none());
}

#[test]
fn gltf_with_external_bin_loads_relative_to_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    d.mesh("external", json!({"attributes": {"POSITION": pos}}));
    d.nodes(json!([{"mesh": 0}]), &[0]);
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let path = dir.path().join("sub/model.gltf");
    std::fs::write(&path, d.gltf_external("model%20data.bin")).unwrap();
    std::fs::write(dir.path().join("sub/model data.bin"), &d.bin).unwrap();
    let s = load_gltf(&path).unwrap();
    assert_eq!(s.meshes[0].positions[1], DVec3::new(1., 0., 0.));
}

#[test]
fn empty_scenes_load_as_empty() {
    let s = load_ok(br#"{"asset": {"version": "2.0"}}"#);
    assert_eq!(s.triangle_count(), 0);
    assert!(s.meshes.is_empty() && s.cameras.is_empty());
    let s = load_ok(br#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"name": "empty"}]}"#);
    assert_eq!(s.triangle_count(), 0);
    let mut d = Doc::new();
    d.nodes(json!([{"name": "nothing"}]), &[0]);
    assert_eq!(load_ok(&d.glb()).triangle_count(), 0);
}

// ---------------------------------------------------------------------------
// Writing.

#[test]
fn written_glb_round_trips_through_the_loader() {
    let img = test_image();
    let mut quad = Mesh::new(
        "quad",
        vec![
            DVec3::new(0.5, 0.25, -1.0),
            DVec3::new(2.0, 0.25, -1.0),
            DVec3::new(2.0, 1.75, -1.0),
            DVec3::new(0.5, 1.75, -1.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    quad.uvs = Some(vec![
        DVec2::new(0., 1.),
        DVec2::new(1., 1.),
        DVec2::new(1., 0.),
        DVec2::new(0., 0.),
    ]);
    quad.material = Some(1);
    let (cube, idx) = seamed_cube(6);
    let cube = Mesh::new(
        "cube",
        cube.iter()
            .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .collect(),
        idx.chunks(3)
            .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32])
            .collect(),
    );
    let scene = Scene {
        meshes: vec![quad.clone(), Mesh::new("empty", vec![], vec![]), cube],
        materials: vec![
            Material::default(),
            Material {
                name: "lattice".into(),
                alpha_mode: AlphaMode::Mask,
                alpha_cutoff: 0.25,
                base_color_factor: [1.0, 0.5, 0.25, 1.0],
                base_color_texture: Some(Texture {
                    source: "test".into(),
                    image: Some(std::sync::Arc::new(img.clone())),
                    sampler: Default::default(),
                }),
            },
        ],
        ..Scene::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.glb");
    write_glb(&scene, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
        bytes.len()
    );
    assert_eq!(bytes.len() % 4, 0);
    // The JSON chunk is plain glTF 2.0 as other tools expect it.
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let js: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    assert_eq!(js["asset"]["version"], "2.0");
    assert_eq!(js["accessors"][0]["min"], json!([0.5, 0.25, -1.0]));
    assert_eq!(js["accessors"][0]["max"], json!([2.0, 1.75, -1.0]));
    assert_eq!(js["materials"][1]["alphaMode"], "MASK");
    assert_eq!(js["images"][0]["mimeType"], "image/png");
    // And the gltf crate's own importer (with its validation) accepts it.
    let (doc, buffers, images) = gltf::import(&path).expect("gltf::import reads the written file");
    assert_eq!(doc.meshes().count(), 2);
    assert_eq!(buffers.len(), 1);
    assert_eq!(images.len(), 1);

    let back = load_gltf(&path).unwrap();
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    assert_eq!(back.meshes.len(), 2, "the empty mesh is skipped");
    let q = &back.meshes[0];
    assert_eq!(q.name, "quad/primitive#0");
    assert_eq!(q.positions, quad.positions);
    assert_eq!(q.indices, quad.indices);
    assert_eq!(q.uvs, quad.uvs);
    assert_eq!(q.material, Some(1));
    assert!(back.meshes[1].closed);
    let m = &back.materials[1];
    assert_eq!(
        (m.alpha_mode, m.alpha_cutoff, m.base_color_factor),
        (AlphaMode::Mask, 0.25, [1.0, 0.5, 0.25, 1.0])
    );
    assert_eq!(
        m.base_color_texture.as_ref().unwrap().image.as_deref(),
        Some(&img)
    );
}

// ---------------------------------------------------------------------------
// Real models.

fn shared_assets() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "note: {} is absent; real-model tests skipped",
            dir.display()
        );
        None
    }
}

/// Sum over the default scene's mesh nodes of (index count / 3), read from
/// the JSON directly.
fn json_triangle_count(path: &Path) -> usize {
    let js: Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let scene = js["scene"].as_u64().unwrap_or(0) as usize;
    let mut stack: Vec<usize> = js["scenes"][scene]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_u64().unwrap() as usize)
        .collect();
    let mut total = 0;
    while let Some(n) = stack.pop() {
        let node = &js["nodes"][n];
        if let Some(m) = node["mesh"].as_u64() {
            for p in js["meshes"][m as usize]["primitives"].as_array().unwrap() {
                assert!(p["mode"].is_null() || p["mode"] == 4);
                let acc = p["indices"].as_u64().unwrap() as usize;
                total += js["accessors"][acc]["count"].as_u64().unwrap() as usize / 3;
            }
        }
        if let Some(c) = node["children"].as_array() {
            stack.extend(c.iter().map(|c| c.as_u64().unwrap() as usize));
        }
    }
    total
}

fn extent(s: &Scene) -> (DVec3, DVec3) {
    s.bounds().expect("non-empty")
}

#[test]
fn lantern_loads_without_its_base_colour_texture() {
    let Some(dir) = shared_assets() else { return };
    let path = dir.join("Lantern/Lantern.gltf");
    let s = load_gltf(&path).unwrap();
    assert_eq!(s.triangle_count(), json_triangle_count(&path));
    assert_eq!(s.triangle_count(), (2616 + 3744 + 9822) / 3);
    // Three primitives, whose closed parts (chain links, the lantern's
    // solids) cast as closed meshes of their own.
    let primitives = s.meshes.iter().filter(|m| !m.name.contains("/closed#"));
    assert_eq!(primitives.count(), 3);
    assert_eq!(s.meshes.len(), 3 + 14);
    assert!(s
        .meshes
        .iter()
        .all(|m| m.closed == m.name.contains("/closed#")));
    let w = s.warnings.join("\n");
    assert!(
        w.contains("Lantern_baseColor.png") && w.contains("not found"),
        "{w}"
    );
    let tex = s.materials[0].base_color_texture.as_ref().unwrap();
    assert!(tex.image.is_none());
    // Node translations under a 180-degree turn about y, from the JSON's min/max.
    let (lo, hi) = extent(&s);
    assert!((lo.y - (13.01603 - 12.8321095)).abs() < 1e-4, "{lo:?}");
    assert!((hi.y - (13.01603 + 12.8321095)).abs() < 1e-4, "{hi:?}");
    assert!((lo.x - -(-3.82315421 + 7.74559927)).abs() < 1e-4, "{lo:?}");
    assert!((hi.x - (3.82315421 + 7.74559927)).abs() < 1e-4, "{hi:?}");
}

#[test]
fn boombox_loads_at_its_tiny_scale() {
    let Some(dir) = shared_assets() else { return };
    let path = dir.join("BoomBox/BoomBox.gltf");
    let s = load_gltf(&path).unwrap();
    assert_eq!(s.triangle_count(), json_triangle_count(&path));
    assert_eq!(s.triangle_count(), 18108 / 3);
    let w = s.warnings.join("\n");
    assert!(
        w.contains("BoomBox_occlusionRoughnessMetallic.png")
            && w.contains("shadows do not need it"),
        "{w}"
    );
    assert_eq!(
        s.warnings.len(),
        1,
        "one warning for the image used twice: {w}"
    );
    let tex = s.materials[0].base_color_texture.as_ref().unwrap();
    assert!(tex.image.as_ref().is_some_and(|i| i.width() > 0));
    let (lo, hi) = extent(&s);
    let size = hi - lo;
    assert!(
        size.min_element() > 0.015 && size.max_element() < 0.025,
        "about 2 cm: {size:?}"
    );
}

#[test]
fn suzanne_loads_and_is_not_closed() {
    let Some(dir) = shared_assets() else { return };
    let path = dir.join("Suzanne/Suzanne.gltf");
    let s = load_gltf(&path).unwrap();
    assert_eq!(s.triangle_count(), json_triangle_count(&path));
    assert_eq!(s.triangle_count(), 11808 / 3);
    assert!(!s.meshes[0].closed);
    let (lo, hi) = extent(&s);
    assert!(
        (lo.x + 1.336914).abs() < 1e-5 && (hi.x - 1.336914).abs() < 1e-5,
        "{lo:?} {hi:?}"
    );
}

#[test]
fn missing_geometry_buffer_is_an_error_naming_file_mesh_and_buffer() {
    let Some(dir) = shared_assets() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let copy = tmp.path().join("Lantern.gltf");
    std::fs::copy(dir.join("Lantern/Lantern.gltf"), &copy).unwrap();
    let e = load_gltf(&copy).unwrap_err().to_string();
    assert!(e.starts_with(&copy.display().to_string()), "{e}");
    assert!(
        e.contains("LanternPole_Body") && e.contains("Lantern.bin"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------
// Malformed input: errors naming the file (and mesh), never a panic.

fn triangle_doc() -> Doc {
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    let idx = d.indices_u16(&[0, 1, 2]);
    d.mesh(
        "tri",
        json!({"attributes": {"POSITION": pos}, "indices": idx}),
    );
    d.nodes(json!([{"mesh": 0}]), &[0]);
    d
}

#[test]
fn gltf_whose_bin_is_missing_or_short() {
    let dir = tempfile::tempdir().unwrap();
    let d = triangle_doc();
    let path = dir.path().join("lonely.gltf");
    std::fs::write(&path, d.gltf_external("lonely.bin")).unwrap();
    let e = load_gltf(&path).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: ", path.display())), "{e}");
    assert!(
        e.contains("tri/primitive#0") && e.contains("lonely.bin"),
        "{e}"
    );
    // A .bin shorter than its byteLength.
    std::fs::write(dir.path().join("lonely.bin"), &d.bin[..10]).unwrap();
    let e = load_gltf(&path).unwrap_err().to_string();
    assert!(
        e.contains("tri/primitive#0") && e.contains("byteLength"),
        "{e}"
    );
    // In memory there is no folder to look in.
    let e = load_err(&d.gltf_external("lonely.bin"), "memory.gltf");
    assert!(
        e.starts_with("memory.gltf: ") && e.contains("tri/primitive#0"),
        "{e}"
    );
}

#[test]
fn non_finite_vertices_are_errors() {
    for (what, bad) in [
        ("NaN", f32::NAN),
        ("infinite", f32::INFINITY),
        ("-infinite", f32::NEG_INFINITY),
    ] {
        let mut d = Doc::new();
        let pos = d.positions(&[[0., 0., 0.], [1., bad, 0.], [0., 1., 0.]]);
        d.mesh("bad_vertex", json!({"attributes": {"POSITION": pos}}));
        d.nodes(json!([{"mesh": 0}]), &[0]);
        let e = load_err(&d.glb(), "nan.glb");
        assert!(e.starts_with("nan.glb: "), "{what}: {e}");
        assert!(
            e.contains("bad_vertex/primitive#0")
                && e.contains("vertex 1")
                && e.contains("not finite"),
            "{what}: {e}"
        );
    }
}

#[test]
fn vertices_made_infinite_by_the_transform_are_errors() {
    let mut d = triangle_doc();
    // Ten nested scales of 1e38: 1e380 overflows f64.
    let mut nodes: Vec<Value> = (0..10)
        .map(|i| json!({"children": [i + 1], "scale": [1e38, 1e38, 1e38]}))
        .collect();
    nodes.push(json!({"mesh": 0}));
    d.nodes(Value::Array(nodes), &[0]);
    let e = load_err(&d.gltf(), "huge.gltf");
    assert!(
        e.starts_with("huge.gltf: ") && e.contains("not finite"),
        "{e}"
    );
}

#[test]
fn out_of_range_index_is_an_error() {
    let mut d = Doc::new();
    let pos = d.positions(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    let idx = d.indices_u32(&[0, 1, 3]);
    d.mesh(
        "bad_index",
        json!({"attributes": {"POSITION": pos}, "indices": idx}),
    );
    d.nodes(json!([{"mesh": 0}]), &[0]);
    let e = load_err(&d.glb(), "index.glb");
    assert!(e.starts_with("index.glb: "), "{e}");
    assert!(
        e.contains("bad_index/primitive#0") && e.contains("out of range"),
        "{e}"
    );
}

#[test]
fn accessor_past_its_buffer_view_is_an_error() {
    let mut d = triangle_doc();
    d.root["accessors"][0]["count"] = json!(4);
    let e = load_err(&d.gltf(), "long.gltf");
    assert!(
        e.starts_with("long.gltf: ") && e.contains("tri/primitive#0") && e.contains("past the end"),
        "{e}"
    );
    let mut d = triangle_doc();
    d.root["bufferViews"][0]["byteLength"] = json!(1000);
    let e = load_err(&d.gltf(), "view.gltf");
    assert!(
        e.contains("tri/primitive#0") && e.contains("past the end"),
        "{e}"
    );
    let mut d = triangle_doc();
    d.root["accessors"][0]["byteOffset"] = json!(4);
    let e = load_err(&d.glb(), "offset.glb");
    assert!(
        e.contains("tri/primitive#0") && e.contains("past the end"),
        "{e}"
    );
}

#[test]
fn missing_position_and_dangling_references_are_errors() {
    let mut d = triangle_doc();
    d.root["meshes"][0]["primitives"][0]["attributes"] = json!({"NORMAL": 0});
    let e = load_err(&d.gltf(), "nopos.gltf");
    assert!(
        e.starts_with("nopos.gltf: ") && e.contains("tri/primitive#0") && e.contains("POSITION"),
        "{e}"
    );
    // References to objects that do not exist (the gltf crate's own
    // validation indexes some of these unchecked).
    let prim = "/meshes/0/primitives/0";
    let cases: [(&str, &str, Value); 11] = [
        (prim, "attributes", json!({"POSITION": 99})),
        (prim, "indices", json!(99)),
        (prim, "material", json!(5)),
        (prim, "mode", json!(42)),
        ("/nodes/0", "mesh", json!(7)),
        ("/scenes/0", "nodes", json!([3])),
        ("", "scene", json!(4)),
        ("/bufferViews/0", "buffer", json!(2)),
        ("/accessors/0", "bufferView", json!(9)),
        ("/accessors/0", "componentType", json!(1)),
        ("/accessors/0", "type", json!("MAT9")),
    ];
    for (ptr, key, v) in cases {
        let mut d = triangle_doc();
        d.root.pointer_mut(ptr).unwrap_or_else(|| panic!("{ptr}"))[key] = v;
        let e = load_err(&d.gltf(), "dangling.gltf");
        assert!(e.starts_with("dangling.gltf: "), "{ptr}/{key}: {e}");
    }
}

#[test]
fn positions_of_a_wrong_component_type_are_errors() {
    // Three UNSIGNED_SHORT VEC3 vertices, padded to 36 bytes: long enough
    // for three UNSIGNED_INT ones too.
    let q: Vec<u8> = [[0u16, 0, 0], [1, 0, 0], [0, 1, 0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .chain([0; 18])
        .collect();
    let doc = |component_type: u32, extension: bool| {
        let mut d = Doc::new();
        d.accessor(
            &q,
            json!({"componentType": component_type, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}),
        );
        d.mesh("q", json!({"attributes": {"POSITION": 0}}));
        d.nodes(json!([{"mesh": 0}]), &[0]);
        if extension {
            d.root["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
            d.root["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
        }
        d.gltf()
    };
    // Integers without KHR_mesh_quantization, and UNSIGNED_INT even with it.
    for (ct, ext, name) in [
        (5123, false, "UNSIGNED_SHORT"),
        (5121, false, "UNSIGNED_BYTE"),
        (5125, true, "UNSIGNED_INT"),
    ] {
        let e = load_err(&doc(ct, ext), "ints.gltf");
        assert!(
            e.starts_with("ints.gltf: ")
                && e.contains("q/primitive#0")
                && e.contains("POSITION")
                && e.contains(name),
            "{ct}: {e}"
        );
    }
    // Declared, they load.
    let s = load_ok(&doc(5123, true));
    assert_eq!(s.meshes[0].positions[1], DVec3::new(1., 0., 0.));
}

#[test]
fn node_cycles_are_errors() {
    let mut d = triangle_doc();
    d.nodes(
        json!([{"mesh": 0, "children": [1]}, {"children": [0]}]),
        &[0],
    );
    let e = load_err(&d.gltf(), "cycle.gltf");
    assert!(e.contains("not a tree"), "{e}");
}

#[test]
fn unsupported_required_extension_is_named() {
    let mut d = triangle_doc();
    d.root["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    d.root["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let e = load_err(&d.gltf(), "draco.gltf");
    assert!(
        e.starts_with("draco.gltf: ") && e.contains("KHR_draco_mesh_compression"),
        "{e}"
    );
}

#[test]
fn wrong_versions_and_non_gltf_text_are_errors() {
    let e = load_err(br#"{"asset": {"version": "1.0"}}"#, "old.gltf");
    assert!(e.starts_with("old.gltf: ") && e.contains("1.0"), "{e}");
    let e = load_err(b"", "empty.gltf");
    assert!(e.starts_with("empty.gltf: "), "{e}");
    let e = load_err(b"[1, 2, 3]", "array.gltf");
    assert!(e.starts_with("array.gltf: "), "{e}");
}

/// SplitMix64, for deterministic garbage.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.next() as u8).collect()
    }
}

#[test]
fn random_garbage_is_an_error() {
    let mut rng = Rng(1);
    for len in (0..600).chain([4096, 65536]) {
        let mut bytes = rng.bytes(len);
        for prefix in [&b""[..], b"glTF", b"glTF\x02\0\0\0", b"{"] {
            if bytes.len() >= prefix.len() {
                bytes[..prefix.len()].copy_from_slice(prefix);
            }
            let e = load_err(&bytes, "garbage.bin");
            assert!(e.starts_with("garbage.bin: "), "{e}");
        }
    }
}

#[test]
fn truncated_glb_files_are_errors() {
    // The built-in demo scene written by the crate, and a hand-made file.
    let dir = tempfile::tempdir().unwrap();
    let demo_path = dir.path().join("demo.glb");
    write_glb(&builtin("demo").unwrap().scene, &demo_path).unwrap();
    let demo = std::fs::read(&demo_path).unwrap();
    assert!(load_gltf(&demo_path).unwrap().triangle_count() > 0);
    let hand = triangle_doc().glb();
    assert_eq!(load_ok(&hand).triangle_count(), 1);
    for full in [&demo, &hand] {
        let lengths = (0..full.len().min(400))
            .chain((400..full.len()).step_by(997))
            .chain([full.len() - 1]);
        for len in lengths {
            let e = load_err(&full[..len], "cut.glb");
            assert!(e.starts_with("cut.glb: "), "length {len}: {e}");
        }
    }
    // And from disk: the error names the path.
    let cut = dir.path().join("cut.glb");
    std::fs::write(&cut, &demo[..demo.len() / 2]).unwrap();
    let e = load_gltf(&cut).unwrap_err().to_string();
    assert!(
        e.starts_with(&cut.display().to_string()) && e.contains("truncated"),
        "{e}"
    );
}

#[test]
fn truncated_gltf_json_is_an_error() {
    let full = triangle_doc().gltf();
    for len in 0..full.len() {
        // Cutting JSON text leaves it unterminated: always an error.
        let e = load_err(&full[..len], "cut.gltf");
        assert!(e.starts_with("cut.gltf: "), "length {len}: {e}");
    }
}

#[test]
fn mutated_files_never_panic() {
    let mut d = triangle_doc();
    let img = png(&test_image());
    let view = d.view(&img);
    d.root["images"] = json!([{"bufferView": view, "mimeType": "image/png"}]);
    d.root["textures"] = json!([{"source": 0}]);
    d.root["materials"] =
        json!([{"alphaMode": "MASK", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    d.root["meshes"][0]["primitives"][0]["material"] = json!(0);
    d.root["cameras"] =
        json!([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]);
    d.nodes(
        json!([{"mesh": 0, "children": [1]}, {"camera": 0, "translation": [0., 0., 3.]}]),
        &[0],
    );
    let mut rng = Rng(42);
    let mut loaded = 0;
    for source in [d.glb(), d.gltf()] {
        assert!(load(&source, "mutant").is_ok());
        for _ in 0..3000 {
            let mut m = source.clone();
            for _ in 0..1 + rng.next() % 4 {
                let at = (rng.next() as usize) % m.len();
                match rng.next() % 3 {
                    0 => m[at] ^= 1 << (rng.next() % 8),
                    1 => m[at] = b"0123456789-.,:[]{}\"e"[(rng.next() % 20) as usize],
                    _ => m[at] = rng.next() as u8,
                }
            }
            // Either outcome is fine; a panic fails the test.
            if load(&m, "mutant").is_ok() {
                loaded += 1;
            }
        }
    }
    assert!(
        loaded > 0,
        "some mutations (in padding or names) still load"
    );
}
