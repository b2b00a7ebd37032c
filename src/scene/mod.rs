//! Scene input: triangle meshes in world space, their materials and cameras.
//!
//! A [`Scene`] comes from a glTF file ([`gltf_load`]), a built-in generator
//! ([`builtin`]) or a TOML scene file ([`file`](mod@file)) that names one of those and
//! adds a ground plane, a camera and lights.
//!
//! World-space vertex positions are kept in `f64` so that a model far from
//! the origin loses no precision before the camera-relative conversion that
//! both the oracle and the GPU passes make.

pub mod builtin;
pub mod containment;
pub mod file;
pub mod gltf_load;
pub mod gltf_write;

use glam::{DVec2, DVec3};
use std::collections::HashMap;

/// How a material's alpha is interpreted (glTF `alphaMode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum AlphaMode {
    /// `OPAQUE`: alpha is ignored and the surface is solid (the default).
    #[default]
    Opaque,
    /// `MASK`: the surface is solid where alpha ≥
    /// [`Material::alpha_cutoff`] and absent elsewhere.
    Mask,
    /// `BLEND`: alpha is a coverage to blend with what is behind.
    Blend,
}

/// A base-colour texture: the picture's colour and alpha-masked casters'
/// coverage.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Where the image came from (a file path, or "embedded").
    pub source: String,
    /// The decoded image; `None` when it could not be loaded (a warning was logged).
    pub image: Option<std::sync::Arc<image::RgbaImage>>,
    /// How the texture is sampled (glTF `sampler`).
    pub sampler: Sampler,
}

/// glTF `magFilter`: how a texture is read between texel centres.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MagFilter {
    /// `NEAREST` (9728): the texel the point falls in.
    Nearest,
    /// `LINEAR` (9729, and when absent): bilinear between the four nearest
    /// texel centres.
    #[default]
    Linear,
}

/// glTF `wrapS` / `wrapT`: texture coordinates outside [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Wrap {
    /// `REPEAT` (10497, and when absent).
    #[default]
    Repeat,
    /// `CLAMP_TO_EDGE` (33071).
    ClampToEdge,
    /// `MIRRORED_REPEAT` (33648).
    MirroredRepeat,
}

/// A glTF sampler as alpha masks use it (`minFilter` is not: coverage is
/// read at one point, never averaged over a footprint).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Sampler {
    /// `magFilter`.
    pub mag_filter: MagFilter,
    /// `wrapS` (along u).
    pub wrap_s: Wrap,
    /// `wrapT` (along v).
    pub wrap_t: Wrap,
}

/// A glTF material, reduced to what shadows need.
#[derive(Clone, Debug)]
pub struct Material {
    /// The glTF material name, or a generated one (`default` for
    /// [`Material::default`]).
    pub name: String,
    /// How the base colour's alpha is interpreted.
    pub alpha_mode: AlphaMode,
    /// glTF `alphaCutoff` (0.5 when absent); used with [`AlphaMode::Mask`].
    pub alpha_cutoff: f32,
    /// glTF `baseColorFactor`: linear RGBA that multiplies the texture
    /// (alpha included); `[1.0; 4]` when absent.
    pub base_color_factor: [f32; 4],
    /// The glTF `baseColorTexture`; `None` when the material has none.
    pub base_color_texture: Option<Texture>,
}

/// What an alpha-tested triangle needs to decide where it is opaque: the
/// coverage at texture coordinates (u, v) is `factor ×` the texture's
/// alpha there (`crate::cpu::alpha` gives the arithmetic), opaque where at
/// least `cutoff`.
#[derive(Clone, Debug)]
pub struct AlphaTest {
    /// The material's name, for messages.
    pub material: String,
    /// The base-colour texture's image; `None`: the coverage is `factor`
    /// everywhere.
    pub image: Option<std::sync::Arc<image::RgbaImage>>,
    /// How it is sampled.
    pub sampler: Sampler,
    /// `alphaCutoff` (0.5 for BLEND materials, cast as MASK).
    pub cutoff: f32,
    /// `baseColorFactor`'s alpha.
    pub factor: f32,
}

impl Material {
    /// The alpha test its triangles cast and are seen with, `None` for an
    /// opaque surface: MASK materials with their `alphaCutoff`; BLEND
    /// materials as MASK at 0.5 (the loader warns); OPAQUE, and a MASK or
    /// BLEND material whose texture could not be loaded (the loader warns:
    /// such a caster is opaque), none.
    pub fn alpha_test(&self) -> Option<AlphaTest> {
        let cutoff = match self.alpha_mode {
            AlphaMode::Opaque => return None,
            AlphaMode::Mask => self.alpha_cutoff,
            AlphaMode::Blend => 0.5,
        };
        let (image, sampler) = match &self.base_color_texture {
            Some(t) => (Some(t.image.clone()?), t.sampler),
            None => (None, Sampler::default()),
        };
        Some(AlphaTest {
            material: self.name.clone(),
            image,
            sampler,
            cutoff,
            factor: self.base_color_factor[3],
        })
    }
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: "default".into(),
            alpha_mode: AlphaMode::Opaque,
            alpha_cutoff: 0.5,
            base_color_factor: [1.0; 4],
            base_color_texture: None,
        }
    }
}

/// A triangle mesh in world space (one glTF primitive, or a generated object).
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Name for messages: the glTF mesh name (with primitive index) or the generator's name.
    pub name: String,
    /// World-space vertex positions.
    pub positions: Vec<DVec3>,
    /// Texture coordinates, one per position, when the source has them.
    pub uvs: Option<Vec<DVec2>>,
    /// World-space unit vertex normals, one per position, when the source
    /// has them (glTF `NORMAL`); for shading only ([`crate::shade`]).
    pub normals: Option<Vec<DVec3>>,
    /// Triangles as indices into `positions`, counter-clockwise = front.
    pub indices: Vec<[u32; 3]>,
    /// Index into [`Scene::materials`].
    pub material: Option<usize>,
    /// Every edge is shared by exactly two consistently oriented triangles
    /// (see [`is_closed`]); closed meshes cast only from their light back faces.
    pub closed: bool,
}

impl Mesh {
    /// Whether `p` lies inside this mesh (closed meshes only; an open one
    /// contains nothing). Ray parity in f64 along a fixed oblique
    /// direction, which a closed surface crosses an odd number of times
    /// from an inside point. O(triangles).
    pub fn contains(&self, p: DVec3) -> bool {
        self.closed
            && (0..self.indices.len())
                .filter(|&t| ray_crosses(p, CONTAINMENT_RAY, self.triangle(t)))
                .count()
                % 2
                == 1
    }

    /// Builds a mesh and computes [`Mesh::closed`].
    pub fn new(name: impl Into<String>, positions: Vec<DVec3>, indices: Vec<[u32; 3]>) -> Self {
        let closed = is_closed(&indices);
        Mesh {
            name: name.into(),
            positions,
            uvs: None,
            normals: None,
            indices,
            material: None,
            closed,
        }
    }

    /// World-space bounding box of its positions (min, max); `None` when it
    /// has none.
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        let mut it = self.positions.iter();
        let first = *it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
    }

    /// The three world-space corners of triangle `i`.
    pub fn triangle(&self, i: usize) -> [DVec3; 3] {
        let [a, b, c] = self.indices[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The triangles `tris` of this mesh as a mesh of their own (only the
    /// vertices they use), named `name`, closed or not as `closed` says.
    fn subset(&self, name: String, tris: &[usize], closed: bool) -> Mesh {
        let mut new_index = vec![u32::MAX; self.positions.len()];
        let mut used: Vec<u32> = Vec::new();
        let indices = tris
            .iter()
            .map(|&ti| {
                self.indices[ti].map(|i| {
                    let slot = &mut new_index[i as usize];
                    if *slot == u32::MAX {
                        *slot = used.len() as u32;
                        used.push(i);
                    }
                    *slot
                })
            })
            .collect();
        let pick = |i: &u32| *i as usize;
        Mesh {
            name,
            positions: used.iter().map(|i| self.positions[pick(i)]).collect(),
            uvs: self
                .uvs
                .as_ref()
                .map(|u| used.iter().map(|i| u[pick(i)]).collect()),
            normals: self
                .normals
                .as_ref()
                .map(|n| used.iter().map(|i| n[pick(i)]).collect()),
            indices,
            material: self.material,
            closed,
        }
    }

    /// Applies an affine transform to every vertex (and keeps orientation
    /// counter-clockwise when the transform mirrors).
    pub fn transform(&mut self, m: &glam::DMat4) {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        if let Some(normals) = &mut self.normals {
            // Normals go with the inverse transpose (zero where singular).
            let inverse_transpose = glam::DMat3::from_mat4(*m).inverse().transpose();
            for n in normals {
                *n = (inverse_transpose * *n).normalize_or_zero();
            }
        }
        if m.determinant() < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
    }
}

/// Whether every edge of `indices` is shared by exactly two triangles that
/// traverse it in opposite directions (a closed, consistently oriented
/// two-manifold). Positions are compared by index, so a mesh must be welded.
pub fn is_closed(indices: &[[u32; 3]]) -> bool {
    if indices.is_empty() {
        return false;
    }
    // Directed edge -> count. Closed and consistent: each directed edge once,
    // and its reverse once.
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(indices.len() * 3);
    for t in indices {
        for k in 0..3 {
            let e = (t[k], t[(k + 1) % 3]);
            if e.0 == e.1 {
                return false;
            }
            *directed.entry(e).or_insert(0) += 1;
        }
    }
    directed
        .iter()
        .all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
}

/// Per vertex, the first vertex with a bit-identical position (glTF
/// models duplicate vertices along UV and normal seams); -0 and +0 weld.
pub(crate) fn weld(positions: &[DVec3]) -> Vec<u32> {
    let key = |p: &DVec3| {
        [
            (p.x + 0.0).to_bits(),
            (p.y + 0.0).to_bits(),
            (p.z + 0.0).to_bits(),
        ]
    };
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(positions.len());
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| *first.entry(key(p)).or_insert(i as u32))
        .collect()
}

/// `indices` through `remap` ([`weld`]), without the triangles that
/// collapse (two corners at one position: no area, nothing to close).
pub(crate) fn welded_triangles(remap: &[u32], indices: &[[u32; 3]]) -> Vec<[u32; 3]> {
    indices
        .iter()
        .filter_map(|t| {
            let w = [
                *remap.get(t[0] as usize)?,
                *remap.get(t[1] as usize)?,
                *remap.get(t[2] as usize)?,
            ];
            (w[0] != w[1] && w[1] != w[2] && w[0] != w[2]).then_some(w)
        })
        .collect()
}

/// At most this many closed parts become meshes of their own per mesh;
/// past it they cast as one closed mesh (their union is closed too), so
/// that a mesh of many small closed parts does not multiply the per-mesh
/// work (the containment tests of a frame's inputs).
const MOST_CLOSED_PARTS: usize = 64;

/// An open mesh split into its closed parts (connected components, over
/// welded positions, that are closed by [`is_closed`]) and the rest, so
/// that the closed parts cast as closed meshes: only from their faces
/// that face away from the light (paper §3.3), which spares the tests of
/// their other faces. glTF models often put closed solids (wheels, bolts,
/// beads) in one primitive with open surfaces. A closed mesh, or one
/// without a closed part, comes back whole. Triangle order: the open rest
/// first (under the mesh's name), then the closed parts.
pub fn split_closed_parts(mesh: Mesh) -> Vec<Mesh> {
    if mesh.closed || mesh.indices.is_empty() {
        return vec![mesh];
    }
    let remap = weld(&mesh.positions);
    // Connected components over welded vertices (union-find).
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let up = parent[parent[v as usize] as usize];
            parent[v as usize] = up;
            v = up;
        }
        v
    }
    for t in &mesh.indices {
        let r0 = root(&mut parent, remap[t[0] as usize]);
        for &i in &t[1..] {
            let r = root(&mut parent, remap[i as usize]);
            if r != r0 {
                parent[r as usize] = r0;
            }
        }
    }
    let mut parts: HashMap<u32, Vec<usize>> = HashMap::new();
    for (ti, t) in mesh.indices.iter().enumerate() {
        let r = root(&mut parent, remap[t[0] as usize]);
        parts.entry(r).or_default().push(ti);
    }
    let mut closed: Vec<Vec<usize>> = parts
        .into_values()
        .filter(|tris| {
            let own: Vec<[u32; 3]> = tris.iter().map(|&ti| mesh.indices[ti]).collect();
            is_closed(&welded_triangles(&remap, &own))
        })
        .collect();
    if closed.is_empty() {
        return vec![mesh];
    }
    // In the order of their first triangle (HashMap order is not stable).
    closed.sort_unstable_by_key(|tris| tris[0]);
    if closed.len() > MOST_CLOSED_PARTS {
        let mut all: Vec<usize> = closed.concat();
        all.sort_unstable();
        closed = vec![all];
    }
    let mut in_closed = vec![false; mesh.indices.len()];
    for &ti in closed.iter().flatten() {
        in_closed[ti] = true;
    }
    let rest: Vec<usize> = (0..mesh.indices.len())
        .filter(|&ti| !in_closed[ti])
        .collect();
    let mut out = Vec::with_capacity(closed.len() + 1);
    if !rest.is_empty() {
        out.push(mesh.subset(mesh.name.clone(), &rest, false));
    }
    for (k, tris) in closed.iter().enumerate() {
        out.push(mesh.subset(format!("{}/closed#{k}", mesh.name), tris, true));
    }
    out
}

/// A pinhole camera. `fov_y_deg` is the full vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// World-space position of the pinhole; the origin of every
    /// camera-relative coordinate.
    pub eye: DVec3,
    /// World-space point the camera looks at (distinct from `eye`).
    pub target: DVec3,
    /// World-space up hint; need not be unit or orthogonal to the view
    /// direction, but must not be parallel to it.
    pub up: DVec3,
    /// Full vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f64,
    /// Image width in pixels (1 to 16384).
    pub width: u32,
    /// Image height in pixels (1 to 16384).
    pub height: u32,
}

impl Camera {
    /// Checks that every field is finite and usable; the error names the field.
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |what: &str| Err(crate::Error::InvalidInput(format!("camera: {what}")));
        for (name, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            if !v.is_finite() {
                return bad(&format!("`{name}` is not finite: {v:?}"));
            }
        }
        if !(self.fov_y_deg.is_finite() && self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return bad(&format!(
                "`fov_y_deg` must be in (0, 180), got {}",
                self.fov_y_deg
            ));
        }
        if self.width == 0 || self.height == 0 {
            return bad(&format!(
                "image size must be non-zero, got {}x{}",
                self.width, self.height
            ));
        }
        if self.width > 16384 || self.height > 16384 {
            return bad(&format!(
                "image size at most 16384x16384, got {}x{}",
                self.width, self.height
            ));
        }
        let fwd = self.target - self.eye;
        if fwd.length_squared() == 0.0 {
            return bad("`eye` and `target` coincide");
        }
        if fwd.cross(self.up).length_squared() == 0.0 {
            return bad("`up` is parallel to the view direction");
        }
        // Finite inputs can still overflow: a target 1e300 away along two
        // axes has an infinite distance, and its direction becomes NaN.
        let (r, u, f) = self.basis();
        if !(r.is_finite() && u.is_finite() && f.is_finite()) {
            return bad(&format!(
                "`eye`, `target` and `up` give no finite view direction \
                 (target - eye = {fwd:?}, up = {:?})",
                self.up
            ));
        }
        Ok(())
    }

    /// Orthonormal camera basis (right, up, forward), forward pointing at the target.
    pub fn basis(&self) -> (DVec3, DVec3, DVec3) {
        let f = (self.target - self.eye).normalize();
        let r = f.cross(self.up).normalize();
        let u = r.cross(f);
        (r, u, f)
    }

    /// Unit direction of the primary ray through the centre of pixel (x, y);
    /// y = 0 is the top row.
    pub fn ray_direction(&self, x: u32, y: u32) -> DVec3 {
        let (r, u, f) = self.basis();
        let tan_half = (self.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = self.width as f64 / self.height as f64;
        let sx = ((x as f64 + 0.5) / self.width as f64 * 2.0 - 1.0) * tan_half * aspect;
        let sy = (1.0 - (y as f64 + 0.5) / self.height as f64 * 2.0) * tan_half;
        (f + r * sx + u * sy).normalize()
    }
}

/// The largest distance, along each axis, from the camera eye that a vertex,
/// a view sample or a light (its position, and its extent) may have. The
/// GPU passes work in `f32` relative to the eye and square such
/// coordinates: 1e18² = 1e36 stays below `f32::MAX` (about 3.4e38).
pub const MAX_RELATIVE_COORDINATE: f64 = 1e18;

/// Whether `v` (relative to the camera eye) is finite and within
/// [`MAX_RELATIVE_COORDINATE`] along every axis.
pub fn within_range(v: DVec3) -> bool {
    v.is_finite() && v.abs().max_element() <= MAX_RELATIVE_COORDINATE
}

/// A loaded scene: world-space meshes, materials and any cameras and lights
/// the source defined.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Every mesh; each of their triangles casts and receives shadows.
    pub meshes: Vec<Mesh>,
    /// Materials that [`Mesh::material`] indexes into.
    pub materials: Vec<Material>,
    /// Cameras the source defined (glTF perspective cameras); the first
    /// one is the frame's camera unless a scene file's `[camera]` replaces
    /// it.
    pub cameras: Vec<Camera>,
    /// Lights the source defined (glTF `KHR_lights_punctual`: point and
    /// directional; spot lights as point lights).
    pub lights: Vec<crate::light::Light>,
    /// Non-fatal problems met while loading (also logged with `log::warn!`),
    /// for example a missing texture that shadows do not need.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Total number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.indices.len()).sum()
    }

    /// Where each global triangle id ([`Scene::triangles`] order) lies,
    /// without building the triangles.
    pub fn triangle_ids(&self) -> TriangleIds {
        let first = self
            .meshes
            .iter()
            .scan(0, |next, m| {
                let here = *next;
                *next += m.indices.len();
                Some(here)
            })
            .collect();
        TriangleIds {
            first,
            count: self.triangle_count(),
        }
    }

    /// Checks what the shadow passes and [`Scene::triangles`] rely on:
    /// every vertex is finite and within [`MAX_RELATIVE_COORDINATE`] of
    /// `eye` (the camera) along each axis, and every triangle's indices name
    /// vertices of its mesh. The error names the mesh and the vertex or
    /// triangle. The loaders check their input; this catches scenes built
    /// or changed in code.
    pub fn validate(&self, eye: DVec3) -> crate::Result<()> {
        if !eye.is_finite() {
            return Err(crate::Error::InvalidInput(format!(
                "camera: `eye` is not finite: {eye:?}"
            )));
        }
        for m in &self.meshes {
            let bad = |what: String| {
                Err(crate::Error::InvalidInput(format!(
                    "mesh {:?}: {what}",
                    m.name
                )))
            };
            for (k, p) in m.positions.iter().enumerate() {
                if !p.is_finite() {
                    return bad(format!("vertex {k} is not finite: {p:?}"));
                }
                if !within_range(*p - eye) {
                    return bad(format!(
                        "vertex {k} at {p:?} is more than {MAX_RELATIVE_COORDINATE:e} from the camera eye \
                         {eye:?} along an axis (the GPU passes work in f32 relative to the eye)"
                    ));
                }
            }
            let n = m.positions.len();
            for (t, tri) in m.indices.iter().enumerate() {
                if let Some(i) = tri.iter().find(|&&i| i as usize >= n) {
                    return bad(format!(
                        "triangle {t} has vertex index {i}, but the mesh has {n} vertices"
                    ));
                }
            }
        }
        Ok(())
    }

    /// World-space bounding box (min, max); `None` for an empty scene.
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        self.meshes
            .iter()
            .filter_map(Mesh::bounds)
            .reduce(|(lo, hi), (l, h)| (lo.min(l), hi.max(h)))
    }

    /// Every triangle of the scene flattened, in mesh order: the global
    /// triangle id used by view samples is the index into this list.
    pub fn triangles(&self) -> Vec<SceneTriangle> {
        let mut out = Vec::with_capacity(self.triangle_count());
        let tests = self.alpha_tests();
        for (mi, m) in self.meshes.iter().enumerate() {
            for (ti, &[a, b, c]) in m.indices.iter().enumerate() {
                let alpha = tests[mi].as_ref().map(|t| {
                    let uv = |i: u32| {
                        m.uvs
                            .as_ref()
                            .and_then(|u| u.get(i as usize).copied())
                            .unwrap_or(DVec2::ZERO)
                    };
                    (t.clone(), [a, b, c].map(uv))
                });
                out.push(SceneTriangle {
                    alpha,
                    vertices: m.triangle(ti),
                    mesh: mi as u32,
                    closed: casts_closed(m, &tests[mi]),
                });
            }
        }
        out
    }

    /// Per mesh, the alpha test its triangles cast with ([`Material::alpha_test`]),
    /// `None` for opaque meshes: also a mesh without texture coordinates
    /// whose material would need them (opaque, with a warning at load).
    pub fn alpha_tests(&self) -> Vec<Option<std::sync::Arc<AlphaTest>>> {
        let tests: Vec<Option<std::sync::Arc<AlphaTest>>> = self
            .materials
            .iter()
            .map(|m| m.alpha_test().map(std::sync::Arc::new))
            .collect();
        self.meshes
            .iter()
            .map(|m| {
                let t = tests.get(m.material?)?.clone()?;
                // A texture needs coordinates; a constant coverage does not.
                let uvs_ok = m.uvs.as_ref().is_some_and(|u| u.len() == m.positions.len());
                (uvs_ok || t.image.is_none()).then_some(t)
            })
            .collect()
    }

    /// Per mesh: whether `p` lies inside it (closed meshes only; open ones
    /// are never "inside"). Ray parity in f64 along a fixed oblique
    /// direction, which a closed mesh's surface crosses an odd number of
    /// times from an inside point.
    pub fn closed_meshes_containing(&self, p: DVec3) -> Vec<bool> {
        self.meshes.iter().map(|m| m.contains(p)).collect()
    }

    /// Adds a square ground plane of two triangles at height `y`, normal +y.
    pub fn add_ground(&mut self, y: f64, half_size: f64) {
        let h = half_size;
        let positions = vec![
            DVec3::new(-h, y, -h),
            DVec3::new(h, y, -h),
            DVec3::new(h, y, h),
            DVec3::new(-h, y, h),
        ];
        // Counter-clockwise seen from above (+y).
        let indices = vec![[0, 3, 2], [0, 2, 1]];
        let mut m = Mesh::new("ground", positions, indices);
        m.closed = false;
        self.meshes.push(m);
    }
}

/// Whether mesh `m`, with its alpha test `test` ([`Scene::alpha_tests`]),
/// casts as a closed mesh: an alpha-tested surface has holes, never closed.
pub(crate) fn casts_closed(m: &Mesh, test: &Option<std::sync::Arc<AlphaTest>>) -> bool {
    m.closed && test.is_none()
}

/// Whether the ray p + t·dir, t > 0, crosses triangle `v` (Möller–Trumbore).
/// The direction of [`Mesh::contains`]'s parity ray: oblique, so that few
/// surfaces lie along it.
pub(crate) const CONTAINMENT_RAY: DVec3 = DVec3::new(
    0.577_350_3 + 1.3e-3,
    0.577_350_2 - 0.7e-3,
    0.577_350_4 + 0.2e-3,
);

pub(crate) fn ray_crosses(p: DVec3, dir: DVec3, v: [DVec3; 3]) -> bool {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let h = dir.cross(e2);
    let det = e1.dot(h);
    if det.abs() < 1e-300 {
        return false;
    }
    let f = 1.0 / det;
    let s = p - v[0];
    let u = f * s.dot(h);
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = s.cross(e1);
    let w = f * dir.dot(q);
    if w < 0.0 || u + w > 1.0 {
        return false;
    }
    f * e2.dot(q) > 0.0
}

/// A scene's global triangle ids mapped to their meshes
/// ([`Scene::triangle_ids`]).
pub struct TriangleIds {
    /// Global id of each mesh's first triangle.
    first: Vec<usize>,
    /// Triangles in all.
    count: usize,
}

impl TriangleIds {
    /// The mesh of global triangle `t` and `t`'s index in it (`None` past
    /// the last triangle). Empty meshes share the next one's first id and
    /// are never the answer.
    pub fn locate(&self, t: usize) -> Option<(usize, usize)> {
        if t >= self.count {
            return None;
        }
        let m = self.first.partition_point(|&f| f <= t) - 1;
        Some((m, t - self.first[m]))
    }
}

/// One triangle of a flattened scene, with the facts the shadow passes need.
#[derive(Clone, Debug)]
pub struct SceneTriangle {
    /// World-space corners, counter-clockwise = front.
    pub vertices: [DVec3; 3],
    /// Alpha-tested triangles: their test and the texture coordinates of
    /// their corners (`TEXCOORD_0`); `None`: opaque.
    pub alpha: Option<(std::sync::Arc<AlphaTest>, [DVec2; 3])>,
    /// Index of the mesh it came from.
    pub mesh: u32,
    /// Whether that mesh is closed (and opaque: an alpha-tested mesh never is).
    pub closed: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` disjoint outward tetrahedra (unwelded: each triangle has its own
    /// three vertices, as a glTF with per-face normals stores them), then
    /// one open triangle.
    fn tetrahedra_and_a_triangle(n: usize) -> Mesh {
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for k in 0..n {
            let o = DVec3::new(3.0 * k as f64, 0.0, 0.0);
            let v = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z].map(|p| p + o);
            for [a, b, c] in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
                let base = positions.len() as u32;
                positions.extend([v[a], v[b], v[c]]);
                indices.push([base, base + 1, base + 2]);
            }
        }
        let base = positions.len() as u32;
        positions.extend([
            DVec3::new(0.0, -5.0, 0.0),
            DVec3::new(1.0, -5.0, 0.0),
            DVec3::new(0.0, -5.0, 1.0),
        ]);
        indices.push([base, base + 1, base + 2]);
        Mesh::new("m", positions, indices)
    }

    /// Global ids name the triangles in `Scene::triangles` order, empty
    /// meshes (first, between, last) skipped, nothing past the end.
    #[test]
    fn triangle_ids_locate_each_mesh_triangle() {
        let empty = || Mesh::new("empty", Vec::new(), Vec::new());
        let scene = Scene {
            meshes: vec![
                empty(),
                tetrahedra_and_a_triangle(1),
                empty(),
                tetrahedra_and_a_triangle(2),
                empty(),
            ],
            ..Default::default()
        };
        let ids = scene.triangle_ids();
        let triangles = scene.triangles();
        assert_eq!(triangles.len(), 5 + 9);
        for (t, tri) in triangles.iter().enumerate() {
            let (m, local) = ids.locate(t).unwrap();
            assert_eq!(m, tri.mesh as usize, "triangle {t}");
            assert_eq!(
                scene.meshes[m].triangle(local),
                tri.vertices,
                "triangle {t}"
            );
        }
        assert_eq!(ids.locate(triangles.len()), None);
    }

    #[test]
    fn closed_parts_split_off_and_many_stay_together() {
        let few = split_closed_parts(tetrahedra_and_a_triangle(3));
        let shape: Vec<(String, usize, bool)> = few
            .iter()
            .map(|m| (m.name.clone(), m.indices.len(), m.closed))
            .collect();
        assert_eq!(
            shape,
            [
                ("m".to_string(), 1, false),
                ("m/closed#0".to_string(), 4, true),
                ("m/closed#1".to_string(), 4, true),
                ("m/closed#2".to_string(), 4, true),
            ]
        );
        // Each part keeps its corners: the second tetrahedron starts at x = 3.
        assert_eq!(few[2].triangle(0)[0], DVec3::new(3.0, 0.0, 0.0));
        // Past MOST_CLOSED_PARTS the closed parts cast as one closed mesh.
        let many = split_closed_parts(tetrahedra_and_a_triangle(MOST_CLOSED_PARTS + 1));
        assert_eq!(many.len(), 2);
        assert_eq!(many[1].indices.len(), 4 * (MOST_CLOSED_PARTS + 1));
        assert!(many[1].closed && !many[0].closed);
        // A mesh without a closed part comes back whole.
        let open = split_closed_parts(tetrahedra_and_a_triangle(0));
        assert_eq!((open.len(), open[0].indices.len()), (1, 1));
    }
}
