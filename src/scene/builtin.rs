//! Built-in scenes generated in code: deterministic (fixed seeds, a small
//! hand-written PRNG), in `f64`, with closed meshes really closed (welded and
//! consistently oriented counter-clockwise seen from outside).
//!
//! A spec is the part after `builtin:`: a name from [`NAMES`], and for
//! `torus_knot` an optional approximate triangle count (`torus_knot:20000`).
//! Every built-in comes with a ground plane, a camera and one light. The same
//! scenes (default parameters, without camera and light) are committed as
//! `assets/<name>.glb`; [`write_assets`] regenerates them.

use std::f64::consts::{PI, TAU};
use std::path::Path;

use glam::{DMat4, DVec2, DVec3};

use super::{AlphaMode, Camera, MagFilter, Material, Mesh, Sampler, Scene, Texture, Wrap};
use crate::light::{Distribution, Light, LightShape};
use crate::{Error, Result};

/// A generated scene with its camera and lights.
#[derive(Clone, Debug)]
pub struct Builtin {
    /// The meshes (ground included) and materials.
    pub scene: Scene,
    /// A camera looking at the objects, 512 x 512.
    pub camera: Camera,
    /// The scene's light (one).
    pub lights: Vec<Light>,
}

/// Names of the built-in scenes; `demo` is the default scene.
pub const NAMES: &[&str] = &[
    "demo",
    "plane_sphere",
    "torus_knot",
    "columns",
    "hairball",
    "fence",
    "stairs",
];

/// Default approximate triangle count of `torus_knot`.
pub const TORUS_KNOT_DEFAULT_TRIANGLES: usize = 10_000;
/// Smallest triangle count accepted by `torus_knot:<count>`.
pub const TORUS_KNOT_MIN_TRIANGLES: usize = 100;
/// Largest triangle count accepted by `torus_knot:<count>`.
pub const TORUS_KNOT_MAX_TRIANGLES: usize = 2_000_000;

/// Builds the built-in scene named by `spec` (`"demo"`, `"torus_knot:20000"`, ...).
///
/// Errors ([`Error::InvalidInput`]): an unknown name (the message lists
/// [`NAMES`]), a parameter on a scene that takes none, or a `torus_knot`
/// triangle count that is not an integer in 100..=2,000,000.
pub fn builtin(spec: &str) -> Result<Builtin> {
    let (name, param) = match spec.split_once(':') {
        Some((n, p)) => (n.trim(), Some(p.trim())),
        None => (spec.trim(), None),
    };
    if name == "torus_knot" {
        let triangles = match param {
            None => TORUS_KNOT_DEFAULT_TRIANGLES,
            Some(p) => {
                let n: usize = p.replace('_', "").parse().map_err(|_| {
                    Error::InvalidInput(format!(
                        "builtin:torus_knot: the parameter must be a triangle count, got {p:?}"
                    ))
                })?;
                if !(TORUS_KNOT_MIN_TRIANGLES..=TORUS_KNOT_MAX_TRIANGLES).contains(&n) {
                    return Err(Error::InvalidInput(format!(
                        "builtin:torus_knot: the triangle count must be in \
                         {TORUS_KNOT_MIN_TRIANGLES}..={TORUS_KNOT_MAX_TRIANGLES}, got {n}"
                    )));
                }
                n
            }
        };
        return Ok(torus_knot_scene(triangles));
    }
    if !NAMES.contains(&name) {
        return Err(Error::InvalidInput(format!(
            "unknown built-in scene {name:?}; available: {}",
            NAMES.join(", ")
        )));
    }
    if let Some(p) = param {
        return Err(Error::InvalidInput(format!(
            "built-in scene {name:?} takes no parameter (got {p:?})"
        )));
    }
    Ok(match name {
        "demo" => demo(),
        "plane_sphere" => plane_sphere(),
        "columns" => columns(),
        "hairball" => hairball(),
        "fence" => fence(),
        "stairs" => stairs(),
        _ => unreachable!("every name in NAMES is handled"),
    })
}

/// Writes every built-in scene (default parameters) as `<dir>/<name>.glb`.
pub fn write_assets(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for name in NAMES {
        let b = builtin(name)?;
        super::gltf_write::write_glb(&b.scene, &dir.join(format!("{name}.glb")))?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// Small helpers.

/// SplitMix64: a tiny deterministic PRNG.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub(crate) fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }

    /// Uniform in the unit ball.
    fn in_ball(&mut self) -> DVec3 {
        loop {
            let p = DVec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            if p.length_squared() <= 1.0 {
                return p;
            }
        }
    }

    /// Uniform on the unit sphere.
    fn unit(&mut self) -> DVec3 {
        loop {
            let p = self.in_ball();
            let l = p.length();
            if l > 1e-3 {
                return p / l;
            }
        }
    }
}

/// Triangles under construction.
#[derive(Default)]
struct Builder {
    positions: Vec<DVec3>,
    indices: Vec<[u32; 3]>,
}

impl Builder {
    fn vertex(&mut self, p: DVec3) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }

    /// Adds triangle (a, b, c), swapped if needed so that it faces `outward`.
    fn tri_facing(&mut self, a: u32, b: u32, c: u32, outward: DVec3) {
        let [pa, pb, pc] = [a, b, c].map(|i| self.positions[i as usize]);
        if (pb - pa).cross(pc - pa).dot(outward) >= 0.0 {
            self.indices.push([a, b, c]);
        } else {
            self.indices.push([a, c, b]);
        }
    }

    /// Adds quad a-b-c-d (in order around it) as two triangles facing `outward`.
    fn quad_facing(&mut self, q: [u32; 4], outward: DVec3) {
        self.tri_facing(q[0], q[1], q[2], outward);
        self.tri_facing(q[0], q[2], q[3], outward);
    }

    /// Appends another builder's triangles (a separate component).
    fn append(&mut self, other: Builder) {
        let base = self.positions.len() as u32;
        self.positions.extend(other.positions);
        self.indices
            .extend(other.indices.into_iter().map(|t| t.map(|i| i + base)));
    }

    fn transform(&mut self, m: &DMat4) {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        if m.determinant() < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
    }

    /// Six times the signed volume enclosed (positive when facing outward).
    fn signed_volume6(&self) -> f64 {
        self.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                a.dot(b.cross(c))
            })
            .sum()
    }

    /// Flips every triangle if the surface faces inward.
    fn orient_outward(&mut self) {
        if self.signed_volume6() < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
    }

    fn into_mesh(self, name: &str) -> Mesh {
        Mesh::new(name, self.positions, self.indices)
    }
}

/// A UV sphere: `segments` around, `rings` bands from pole to pole, welded at
/// the poles and the seam (2 * segments * (rings - 1) triangles).
fn uv_sphere(center: DVec3, radius: f64, segments: u32, rings: u32) -> Builder {
    let mut b = Builder::default();
    let north = b.vertex(center + DVec3::Y * radius);
    let mut ring_start = Vec::new();
    for i in 1..rings {
        let theta = PI * i as f64 / rings as f64;
        ring_start.push(b.positions.len() as u32);
        for j in 0..segments {
            let phi = TAU * j as f64 / segments as f64;
            let d = DVec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            b.vertex(center + d * radius);
        }
    }
    let south = b.vertex(center - DVec3::Y * radius);
    let at = |ring: usize, j: u32| ring_start[ring] + j % segments;
    let out = |b: &Builder, ids: &[u32]| {
        ids.iter().map(|&i| b.positions[i as usize]).sum::<DVec3>() / ids.len() as f64 - center
    };
    for j in 0..segments {
        let t = [north, at(0, j), at(0, j + 1)];
        let o = out(&b, &t);
        b.tri_facing(t[0], t[1], t[2], o);
        let last = ring_start.len() - 1;
        let t = [south, at(last, j), at(last, j + 1)];
        let o = out(&b, &t);
        b.tri_facing(t[0], t[1], t[2], o);
        for r in 0..last {
            let q = [at(r, j), at(r + 1, j), at(r + 1, j + 1), at(r, j + 1)];
            let o = out(&b, &q);
            b.quad_facing(q, o);
        }
    }
    b
}

/// An axis-aligned box from `lo` to `hi` (8 vertices, 12 triangles).
fn cuboid(lo: DVec3, hi: DVec3) -> Builder {
    let mut b = Builder::default();
    for k in 0..8 {
        b.vertex(DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        ));
    }
    // Faces as vertex quads (corner bit patterns) with their outward normals.
    let faces: [([u32; 4], DVec3); 6] = [
        ([0, 2, 6, 4], DVec3::NEG_X),
        ([1, 3, 7, 5], DVec3::X),
        ([0, 1, 5, 4], DVec3::NEG_Y),
        ([2, 3, 7, 6], DVec3::Y),
        ([0, 1, 3, 2], DVec3::NEG_Z),
        ([4, 5, 7, 6], DVec3::Z),
    ];
    for (q, n) in faces {
        b.quad_facing(q, n);
    }
    b
}

/// A vertical cylinder standing on `base` (4 * segments triangles).
fn cylinder(base: DVec3, radius: f64, height: f64, segments: u32) -> Builder {
    let mut b = Builder::default();
    let bottom = b.vertex(base);
    let top = b.vertex(base + DVec3::Y * height);
    let ring = |b: &mut Builder, y: f64| {
        let start = b.positions.len() as u32;
        for j in 0..segments {
            let a = TAU * j as f64 / segments as f64;
            b.vertex(base + DVec3::new(radius * a.cos(), y, radius * a.sin()));
        }
        start
    };
    let r0 = ring(&mut b, 0.0);
    let r1 = ring(&mut b, height);
    for j in 0..segments {
        let k = (j + 1) % segments;
        let mid = TAU * (j as f64 + 0.5) / segments as f64;
        let radial = DVec3::new(mid.cos(), 0.0, mid.sin());
        b.quad_facing([r0 + j, r0 + k, r1 + k, r1 + j], radial);
        b.tri_facing(bottom, r0 + j, r0 + k, DVec3::NEG_Y);
        b.tri_facing(top, r1 + j, r1 + k, DVec3::Y);
    }
    b
}

/// A (2,3) torus knot tube of about `triangles` triangles, centred on the
/// origin, lying in the xz plane: the curve spans about ±3.4 in x and z and
/// ±1.4 in y (tube radius 0.4).
fn torus_knot(triangles: usize) -> Builder {
    let around = ((triangles as f64 / 16.0).sqrt().round() as u32).max(3);
    let along = ((triangles as f64 / (2.0 * around as f64)).round() as u32).max(8);
    let tube = 0.4;
    let curve = |u: f64| {
        let r = 2.0 + (3.0 * u).cos();
        // (x, y, z) of the usual knot, with its axis turned to world y.
        DVec3::new(r * (2.0 * u).cos(), -(3.0 * u).sin(), r * (2.0 * u).sin())
    };
    let mut b = Builder::default();
    for i in 0..along {
        let u = TAU * i as f64 / along as f64;
        let p1 = curve(u);
        let p2 = curve(u + 0.01);
        let t = p2 - p1;
        let n0 = p2 + p1;
        let bn = t.cross(n0).normalize();
        let n = bn.cross(t).normalize();
        for j in 0..around {
            let v = TAU * j as f64 / around as f64;
            b.vertex(p1 + (n * v.cos() + bn * v.sin()) * tube);
        }
    }
    let at = |i: u32, j: u32| (i % along) * around + j % around;
    for i in 0..along {
        for j in 0..around {
            let (a, b1, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            b.indices.push([a, b1, c]);
            b.indices.push([a, c, d]);
        }
    }
    b.orient_outward();
    b
}

/// A 512 x 512 camera with a 45-degree field of view looking at `target`
/// from `distance` away, from the azimuth (degrees from +z towards +x) and
/// elevation (degrees above the ground plane) given.
fn orbit(target: DVec3, distance: f64, azimuth_deg: f64, elevation_deg: f64) -> Camera {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    let dir = DVec3::new(a.sin() * e.cos(), e.sin(), a.cos() * e.cos());
    Camera {
        eye: target + dir * distance,
        target,
        up: DVec3::Y,
        fov_y_deg: 45.0,
        width: 512,
        height: 512,
    }
}

fn point_light(position: DVec3) -> Light {
    Light {
        shape: LightShape::Point { position },
        samples: 1,
        distribution: Distribution::Poisson,
        seed: 7,
        color: [1.0; 3],
        intensity: 1.0,
        emission: None,
        per_pixel_rotation: false,
    }
}

fn with_ground(meshes: Vec<Mesh>, materials: Vec<Material>, half_size: f64) -> Scene {
    let mut scene = Scene {
        meshes,
        materials,
        ..Scene::default()
    };
    scene.add_ground(0.0, half_size);
    scene
}

/// Half the side of every built-in's square ground plane.
const GROUND: f64 = 12.0;

/// Closed objects sink this far into the ground so that no face is coplanar with it.
const SINK: f64 = 0.01;

// ---------------------------------------------------------------------------
// The scenes.

/// The default scene: a sphere, a box and a torus knot under a sphere light.
fn demo() -> Builtin {
    let sphere = uv_sphere(DVec3::new(-1.6, 0.9 - SINK, 0.9), 0.9, 32, 16).into_mesh("sphere");
    let mut cube = cuboid(DVec3::splat(-0.55), DVec3::splat(0.55));
    cube.transform(
        &(DMat4::from_translation(DVec3::new(1.6, 0.55 - SINK, 1.0))
            * DMat4::from_rotation_y(30f64.to_radians())),
    );
    let cube = cube.into_mesh("box");
    let mut knot = torus_knot(4000);
    knot.transform(
        &(DMat4::from_translation(DVec3::new(0.0, 1.6, -1.5))
            * DMat4::from_scale(DVec3::splat(0.42))),
    );
    let knot = knot.into_mesh("torus_knot");
    Builtin {
        scene: with_ground(vec![sphere, cube, knot], Vec::new(), GROUND),
        camera: orbit(DVec3::new(0.0, 0.6, 0.0), 9.0, 40.0, 45.0),
        lights: vec![Light {
            shape: LightShape::Sphere {
                position: DVec3::new(-4.5, 5.5, -1.0),
                radius: 0.6,
            },
            samples: 128,
            ..point_light(DVec3::ZERO)
        }],
    }
}

/// A UV sphere above a ground plane, lit by a point light.
fn plane_sphere() -> Builtin {
    let sphere = uv_sphere(DVec3::new(0.0, 1.5, 0.0), 1.0, 32, 16).into_mesh("sphere");
    Builtin {
        scene: with_ground(vec![sphere], Vec::new(), GROUND),
        camera: orbit(DVec3::new(0.0, 0.8, 0.0), 7.0, 40.0, 45.0),
        lights: vec![point_light(DVec3::new(-3.0, 5.0, 1.0))],
    }
}

/// A (2,3) torus knot of about `triangles` triangles above a ground plane.
fn torus_knot_scene(triangles: usize) -> Builtin {
    let mut knot = torus_knot(triangles);
    knot.transform(
        &(DMat4::from_translation(DVec3::new(0.0, 1.6, 0.0))
            * DMat4::from_scale(DVec3::splat(0.5))),
    );
    Builtin {
        scene: with_ground(vec![knot.into_mesh("torus_knot")], Vec::new(), GROUND),
        camera: orbit(DVec3::new(0.0, 0.8, 0.0), 8.0, 40.0, 45.0),
        lights: vec![point_light(DVec3::new(-2.0, 6.0, -1.0))],
    }
}

/// A row of seven columns (box base, 24-sided shaft, box capital; 840 triangles).
fn columns() -> Builtin {
    let mut meshes = Vec::new();
    for k in 0..7 {
        let x = -3.0 + k as f64;
        let mut c = cuboid(
            DVec3::new(x - 0.3, -SINK, -0.3),
            DVec3::new(x + 0.3, 0.25, 0.3),
        );
        c.append(cylinder(DVec3::new(x, 0.24, 0.0), 0.2, 2.52, 24));
        c.append(cuboid(
            DVec3::new(x - 0.3, 2.75, -0.3),
            DVec3::new(x + 0.3, 3.0, 0.3),
        ));
        meshes.push(c.into_mesh(&format!("column#{k}")));
    }
    Builtin {
        scene: with_ground(meshes, Vec::new(), GROUND),
        camera: orbit(DVec3::new(0.0, 1.0, 0.0), 9.0, 20.0, 45.0),
        lights: vec![point_light(DVec3::new(-4.0, 5.0, -3.0))],
    }
}

/// About 5000 thin random triangles in a ball (open) above a ground.
fn hairball() -> Builtin {
    let mut rng = Rng(0x4841_4952_4241_4C4C);
    let center = DVec3::new(0.0, 1.7, 0.0);
    let mut b = Builder::default();
    for _ in 0..5000 {
        let p = center + rng.in_ball() * 1.2;
        let d = rng.unit();
        let side = d.cross(rng.unit()).normalize_or(d.any_orthonormal_vector());
        let len = rng.range(0.25, 0.5);
        let half_width = 0.01;
        let a = b.vertex(p - side * half_width);
        let c = b.vertex(p + side * half_width);
        let tip = b.vertex(p + d * len);
        b.indices.push([a, c, tip]);
    }
    Builtin {
        scene: with_ground(vec![b.into_mesh("hairball")], Vec::new(), GROUND),
        camera: orbit(DVec3::new(0.0, 1.0, 0.0), 7.0, 40.0, 45.0),
        lights: vec![point_light(DVec3::new(-2.0, 6.0, -1.0))],
    }
}

/// The fence texture: a 64 x 64 RGBA diagonal lattice with a frame; alpha is
/// 255 on the bars and 0 in the holes.
fn fence_texture() -> image::RgbaImage {
    image::RgbaImage::from_fn(64, 64, |x, y| {
        let frame = !(4..60).contains(&x) || !(4..60).contains(&y);
        let bar = (x + y) % 16 < 3 || (x + 64 - y) % 16 < 3;
        if frame || bar {
            image::Rgba([150, 105, 60, 255])
        } else {
            image::Rgba([0, 0, 0, 0])
        }
    })
}

/// A vertical alpha-masked quad (a lattice fence) standing on a ground.
fn fence() -> Builtin {
    let (w, y0, y1) = (1.5, 0.02, 2.02);
    let mut quad = Mesh::new(
        "fence",
        vec![
            DVec3::new(-w, y0, 0.0),
            DVec3::new(w, y0, 0.0),
            DVec3::new(w, y1, 0.0),
            DVec3::new(-w, y1, 0.0),
        ],
        // Counter-clockwise seen from +z.
        vec![[0, 1, 2], [0, 2, 3]],
    );
    quad.uvs = Some(vec![
        DVec2::new(0.0, 1.0),
        DVec2::new(1.0, 1.0),
        DVec2::new(1.0, 0.0),
        DVec2::new(0.0, 0.0),
    ]);
    quad.material = Some(0);
    let material = Material {
        name: "fence".into(),
        alpha_mode: AlphaMode::Mask,
        alpha_cutoff: 0.5,
        base_color_factor: [1.0; 4],
        base_color_texture: Some(Texture {
            source: "generated lattice".into(),
            image: Some(std::sync::Arc::new(fence_texture())),
            // A lattice: texels are bars or holes, nothing in between.
            sampler: Sampler {
                mag_filter: MagFilter::Nearest,
                wrap_s: Wrap::ClampToEdge,
                wrap_t: Wrap::ClampToEdge,
            },
        }),
    };
    Builtin {
        scene: with_ground(vec![quad], vec![material], GROUND),
        camera: orbit(DVec3::new(0.0, 0.6, -1.0), 7.0, 25.0, 45.0),
        lights: vec![point_light(DVec3::new(-1.5, 3.5, 2.5))],
    }
}

/// A closed staircase of eight steps (one welded solid) on a ground.
fn stairs() -> Builtin {
    let (steps, depth, rise, half_w) = (8u32, 0.4, 0.25, 1.0);
    let z0 = -(steps as f64) * depth / 2.0;
    let y0 = -SINK;
    let z = |k: u32| z0 + k as f64 * depth;
    let h = |k: u32| k as f64 * rise;
    let mut b = Builder::default();
    // Side profile in (z, y): column k spans z(k)..z(k+1), height h(k+1).
    // Per side: bottom[k] = (z(k), y0) for k in 0..=steps; low[k] =
    // (z(k), h(k)) for k in 1..=steps (a riser's foot; low[steps] is the top
    // back corner); high[k] = (z(k), h(k+1)) for k in 0..steps (a riser's top).
    // Faces are split at every one of these so that the solid is welded
    // without T-junctions.
    let mut sides = Vec::new();
    for &x in &[-half_w, half_w] {
        let bottom: Vec<u32> = (0..=steps)
            .map(|k| b.vertex(DVec3::new(x, y0, z(k))))
            .collect();
        let low: Vec<u32> = (0..=steps)
            .map(|k| {
                if k == 0 {
                    u32::MAX
                } else {
                    b.vertex(DVec3::new(x, h(k), z(k)))
                }
            })
            .collect();
        let high: Vec<u32> = (0..steps)
            .map(|k| b.vertex(DVec3::new(x, h(k + 1), z(k))))
            .collect();
        sides.push((x, bottom, low, high));
    }
    for (x, bottom, low, high) in &sides {
        let out = DVec3::X * x.signum();
        for k in 0..steps as usize {
            // Column k is the convex polygon bottom[k], bottom[k+1],
            // low[k+1] (top right), high[k] (top left) and, for k > 0,
            // low[k] on its left edge; fan it from the bottom right corner.
            let br = bottom[k + 1];
            b.tri_facing(br, low[k + 1], high[k], out);
            if k == 0 {
                b.tri_facing(br, high[k], bottom[k], out);
            } else {
                b.tri_facing(br, high[k], low[k], out);
                b.tri_facing(br, low[k], bottom[k], out);
            }
        }
    }
    let (l, r) = (&sides[0], &sides[1]);
    for k in 0..steps as usize {
        // Bottom strip, tread and riser of step k.
        b.quad_facing([l.1[k], l.1[k + 1], r.1[k + 1], r.1[k]], DVec3::NEG_Y);
        b.quad_facing([l.3[k], l.2[k + 1], r.2[k + 1], r.3[k]], DVec3::Y);
        let foot = |s: &(f64, Vec<u32>, Vec<u32>, Vec<u32>)| if k == 0 { s.1[0] } else { s.2[k] };
        b.quad_facing([foot(l), l.3[k], r.3[k], foot(r)], DVec3::NEG_Z);
    }
    // Back face.
    let n = steps as usize;
    b.quad_facing([l.1[n], l.2[n], r.2[n], r.1[n]], DVec3::Z);
    Builtin {
        scene: with_ground(vec![b.into_mesh("stairs")], Vec::new(), GROUND),
        camera: orbit(DVec3::new(0.0, 0.8, 0.0), 8.0, 140.0, 45.0),
        lights: vec![point_light(DVec3::new(-4.0, 4.0, 3.0))],
    }
}
