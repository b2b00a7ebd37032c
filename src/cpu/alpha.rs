//! Alpha-tested casters (glTF `MASK`, and `BLEND` cast as `MASK` at 0.5):
//! the coverage arithmetic in `f32`, twin of `shaders/alpha_common.glsl`,
//! and the tables the shaders read it from.
//!
//! # Coverage
//!
//! A point of an alpha-tested triangle with barycentrics `(1 − b1 − b2, b1,
//! b2)` has texture coordinates `uv = uv0 (1 − b1 − b2) + uv1 b1 + uv2 b2`
//! (`TEXCOORD_0`; glTF's origin is the image's top-left corner, so `v`
//! grows downwards and row 0 is the image's first row). On a `W × H` image
//! of 8-bit alphas `A[j][i]` (column `i`, row `j`):
//!
//! - `NEAREST`: `x = u W`, `y = v H`; the texel `(⌊x⌋, ⌊y⌋)`, wrapped;
//!   `alpha = A`.
//! - `LINEAR` (glTF's default): `x = u W − ½`, `y = v H − ½`; `i = ⌊x⌋`,
//!   `fx = x − i` (likewise `j`, `fy`); the texels `(i, j)`, `(i + 1, j)`,
//!   `(i, j + 1)`, `(i + 1, j + 1)`, each wrapped; `alpha = (A00 (1 − fx) +
//!   A10 fx) (1 − fy) + (A01 (1 − fx) + A11 fx) fy`, in `f32` in that order.
//! - Wrapping a texel index `i` of a side of `n` texels: `REPEAT` (glTF's
//!   default) `i mod n` (non-negative), `CLAMP_TO_EDGE` `clamp(i, 0, n −
//!   1)`, `MIRRORED_REPEAT` `m = i mod 2n`, then `m` if `m < n`, else `2n −
//!   1 − m`. `x` and `y` are clamped to `±2²⁴` first (past that an `f32`
//!   has no fraction left, and the index stays an `i32`).
//!
//! The point is opaque where `factor × alpha ≥ cutoff × 255`
//! (`baseColorFactor`'s alpha, `alphaCutoff`); without a texture, where
//! `factor ≥ cutoff`. The oracle computes the same in `f64` on its own
//! (`oracle::coverage`); the two may disagree only where a point within
//! the conformance band of the crossing point straddles a texel edge or
//! the cutoff.
//!
//! # Where the barycentrics come from
//!
//! - A shadow segment from `x` along `d` (to a light sample or towards a
//!   directional light) crossing triangle `(a, b, c)`: Möller–Trumbore,
//!   `p = d × (c − a)`, `det = (b − a) · p`, `t = x − a`, `b1 = t · p /
//!   det`, `q = t × (b − a)`, `b2 = d · q / det` ([`segment_barycentrics`]).
//! - A view sample `s` on its triangle: `v0 = b − a`, `v1 = c − a`, `v2 = s
//!   − a`, `d00 = v0·v0`, `d01 = v0·v1`, `d11 = v1·v1`, `d20 = v2·v0`,
//!   `d21 = v2·v1`, `den = d00 d11 − d01²`, `b1 = (d11 d20 − d01 d21) /
//!   den`, `b2 = (d00 d21 − d01 d20) / den` ([`point_barycentrics`]).

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::scene::{AlphaTest, MagFilter, Scene, Wrap};

/// `ALPHA_NONE`: the record index of an opaque triangle.
pub const ALPHA_NONE: u32 = u32::MAX;
/// Textures' flags: `LINEAR` filtering (else `NEAREST`).
pub const ALPHA_LINEAR: u32 = 1;

/// A coverage texture as the shaders read it.
#[derive(Clone, Debug, PartialEq)]
pub struct AlphaTexture {
    /// Width and height in texels (1 × 1 of 255 without an image).
    pub size: [u32; 2],
    /// Row-major alphas, row 0 the image's first (top) row.
    pub alphas: Vec<u8>,
    /// `MagFilter::Linear`.
    pub linear: bool,
    /// Wrap modes along u and v.
    pub wrap: [Wrap; 2],
    /// `alphaCutoff`.
    pub cutoff: f32,
    /// `baseColorFactor`'s alpha.
    pub factor: f32,
}

impl AlphaTexture {
    /// The texture of an alpha test.
    pub fn new(t: &AlphaTest) -> Self {
        let (size, alphas) = match &t.image {
            Some(img) => (
                [img.width(), img.height()],
                img.pixels().map(|p| p.0[3]).collect(),
            ),
            None => ([1, 1], vec![255]),
        };
        AlphaTexture {
            size,
            alphas,
            linear: t.sampler.mag_filter == MagFilter::Linear,
            wrap: [t.sampler.wrap_s, t.sampler.wrap_t],
            cutoff: t.cutoff,
            factor: t.factor,
        }
    }

    fn alpha(&self, i: i32, j: i32) -> f32 {
        let [w, h] = self.size;
        let x = wrap(i, w as i32, self.wrap[0]);
        let y = wrap(j, h as i32, self.wrap[1]);
        self.alphas[(y * w as i32 + x) as usize] as f32
    }

    /// Whether the point with texture coordinates `uv` is opaque.
    pub fn opaque(&self, uv: Vec2) -> bool {
        let [w, h] = self.size;
        let alpha = if self.linear {
            let x = clamp_coordinate(uv.x * w as f32 - 0.5);
            let y = clamp_coordinate(uv.y * h as f32 - 0.5);
            let (fi, fj) = (x.floor(), y.floor());
            let (fx, fy) = (x - fi, y - fj);
            let (i, j) = (fi as i32, fj as i32);
            let top = self.alpha(i, j) * (1.0 - fx) + self.alpha(i + 1, j) * fx;
            let bottom = self.alpha(i, j + 1) * (1.0 - fx) + self.alpha(i + 1, j + 1) * fx;
            top * (1.0 - fy) + bottom * fy
        } else {
            let x = clamp_coordinate(uv.x * w as f32);
            let y = clamp_coordinate(uv.y * h as f32);
            self.alpha(x.floor() as i32, y.floor() as i32)
        };
        self.factor * alpha >= self.cutoff * 255.0
    }
}

/// `±2²⁴`: texel coordinates past it have no fraction left in `f32`.
fn clamp_coordinate(x: f32) -> f32 {
    x.clamp(-16_777_216.0, 16_777_216.0)
}

/// Texel index `i` of a side of `n` wrapped by `mode`.
pub fn wrap(i: i32, n: i32, mode: Wrap) -> i32 {
    match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::MirroredRepeat => {
            let m = i.rem_euclid(2 * n);
            if m < n {
                m
            } else {
                2 * n - 1 - m
            }
        }
    }
}

/// Barycentrics `(b1, b2)` where the line from `x` along `d` meets the
/// plane of `(a, b, c)` (Möller–Trumbore, as `alpha_common.glsl`).
pub fn segment_barycentrics(x: Vec3, d: Vec3, v: [Vec3; 3]) -> Vec2 {
    let [a, b, c] = v;
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    let t = x - a;
    let q = t.cross(e1);
    Vec2::new(t.dot(p) / det, d.dot(q) / det)
}

/// Barycentrics `(b1, b2)` of the point `s` of the plane of `(a, b, c)`
/// (Ericson's, as `alpha_common.glsl`).
pub fn point_barycentrics(s: Vec3, v: [Vec3; 3]) -> Vec2 {
    let [a, b, c] = v;
    let (v0, v1, v2) = (b - a, c - a, s - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let den = d00 * d11 - d01 * d01;
    Vec2::new((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den)
}

/// One alpha-tested triangle's record: its corners' texture coordinates
/// and its texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaRecord {
    /// `TEXCOORD_0` of corners 0, 1, 2.
    pub uvs: [Vec2; 3],
    /// Index into [`AlphaTables::textures`].
    pub texture: u32,
    /// Every texel its coverage can read is transparent: it casts nothing
    /// and is never seen (`TRIANGLE_INVISIBLE`).
    pub invisible: bool,
}

/// What every texel that a triangle's coverage can read says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Footprint {
    /// Opaque everywhere: the triangle casts as an opaque one.
    Opaque,
    /// Transparent everywhere: it casts nothing and is never seen.
    Transparent,
    /// Some of each (or too many texels to look at): tested per point.
    Mixed,
}

/// Texels a footprint may visit before it is called [`Footprint::Mixed`].
const FOOTPRINT_TEXELS: i64 = 4096;

impl AlphaTexture {
    /// The footprint of a triangle with texture coordinates `uvs`: every
    /// texel its coverage can read at any point of it, or a little outside
    /// it (a crossing computed in f32 may land a rounding error past an
    /// edge): its texture-space box grown by one texel and a thousandth of
    /// its size, the filter's reach included. Opaque (transparent) only
    /// where `factor × alpha` passes (misses) the cutoff by a relative
    /// 1e-5, beyond the rounding of the f32 interpolation.
    pub fn footprint(&self, uvs: [Vec2; 3]) -> Footprint {
        let [w, h] = self.size.map(|s| s as f64);
        let (lo, hi) = uvs.iter().fold(
            (glam::DVec2::INFINITY, glam::DVec2::NEG_INFINITY),
            |(lo, hi), uv| {
                let t = uv.as_dvec2() * glam::DVec2::new(w, h);
                (lo.min(t), hi.max(t))
            },
        );
        let grow = glam::DVec2::splat(1.0) + (hi - lo) * 1e-3;
        let shift = if self.linear { 0.5 } else { 0.0 };
        let (lo, hi) = (lo - grow - shift, hi + grow - shift);
        // Past ±2²⁴ texels the reads clamp (clamp_coordinate): such a
        // triangle is tested per point (and its box's integer corners
        // would overflow).
        let limit = 16_777_216.0;
        if !lo.is_finite()
            || !hi.is_finite()
            || lo.min_element() < -limit
            || hi.max_element() > limit
        {
            return Footprint::Mixed;
        }
        let (x0, y0) = (lo.x.floor() as i64, lo.y.floor() as i64);
        let (x1, y1) = (hi.x.floor() as i64 + 1, hi.y.floor() as i64 + 1);
        if (x1 - x0 + 1).saturating_mul(y1 - y0 + 1) > FOOTPRINT_TEXELS {
            return Footprint::Mixed;
        }
        let threshold = self.cutoff as f64 * 255.0;
        let (mut opaque, mut clear) = (true, true);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let a = self.factor as f64 * self.alpha(x as i32, y as i32) as f64;
                opaque &= a >= threshold * (1.0 + 1e-5);
                clear &= a < threshold * (1.0 - 1e-5);
            }
        }
        match (opaque, clear) {
            (true, _) => Footprint::Opaque,
            (_, true) => Footprint::Transparent,
            _ => Footprint::Mixed,
        }
    }
}

impl AlphaRecord {
    /// The texture coordinates at barycentrics `(b1, b2)`.
    pub fn uv(&self, b: Vec2) -> Vec2 {
        self.uvs[0] * (1.0 - b.x - b.y) + self.uvs[1] * b.x + self.uvs[2] * b.y
    }
}

/// The scene's alpha tests as the shaders read them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AlphaTables {
    /// Per global triangle: its record, or [`ALPHA_NONE`].
    pub triangle_records: Vec<u32>,
    /// Per alpha-tested triangle.
    pub records: Vec<AlphaRecord>,
    /// One per alpha-tested material.
    pub textures: Vec<AlphaTexture>,
}

/// What a mesh's alpha tables are made of: its alpha test (the image by
/// identity, held so that its address stays its own), its count of
/// triangles, and for an alpha-tested mesh its texture coordinates and
/// triangles.
#[derive(Clone, Debug)]
struct MeshAlphaKey {
    test: Option<Arc<AlphaTest>>,
    triangles: usize,
    uvs: Option<Vec<glam::DVec2>>,
    indices: Vec<[u32; 3]>,
}

impl MeshAlphaKey {
    fn matches(&self, test: &Option<Arc<AlphaTest>>, m: &crate::scene::Mesh) -> bool {
        let same_test = match (&self.test, test) {
            (None, None) => true,
            (Some(a), Some(b)) => {
                let same_image = match (&a.image, &b.image) {
                    (None, None) => true,
                    (Some(x), Some(y)) => Arc::ptr_eq(x, y),
                    _ => false,
                };
                same_image
                    && a.sampler == b.sampler
                    && a.cutoff.to_bits() == b.cutoff.to_bits()
                    && a.factor.to_bits() == b.factor.to_bits()
            }
            _ => false,
        };
        // An opaque mesh's coordinates and triangles make no table entry
        // beyond its count of triangles.
        same_test
            && self.triangles == m.indices.len()
            && (test.is_none() || (self.uvs == m.uvs && self.indices == m.indices))
    }
}

/// The last scene's [`AlphaTables`], kept across frames: a scene whose
/// alpha tests (images by identity), texture coordinates and triangles
/// are the same gets them again without their per-triangle footprints
/// (TransmissionTest: 7.5–8.4 ms a frame on two cores).
#[derive(Debug, Default)]
pub struct AlphaTablesCache {
    key: Vec<MeshAlphaKey>,
    tables: AlphaTables,
}

impl AlphaTablesCache {
    /// The alpha tables of `scene`, and whether they were reused.
    pub fn get(&mut self, scene: &Scene) -> (&AlphaTables, bool) {
        let tests = scene.alpha_tests();
        let same = self.key.len() == scene.meshes.len()
            && self
                .key
                .iter()
                .zip(tests.iter().zip(&scene.meshes))
                .all(|(k, (t, m))| k.matches(t, m));
        if !same {
            self.tables = AlphaTables::new(scene);
            self.key = tests
                .into_iter()
                .zip(&scene.meshes)
                .map(|(test, m)| MeshAlphaKey {
                    triangles: m.indices.len(),
                    uvs: test.as_ref().and(m.uvs.clone()),
                    indices: match test {
                        Some(_) => m.indices.clone(),
                        None => Vec::new(),
                    },
                    test,
                })
                .collect();
        }
        (&self.tables, same)
    }
}

impl AlphaTables {
    /// The tables of `scene`'s alpha-tested triangles ([`Scene::triangles`]
    /// order); empty when it has none.
    pub fn new(scene: &Scene) -> Self {
        let tests = scene.alpha_tests();
        // Most scenes have no alpha test: skip building every triangle.
        if tests.iter().all(Option::is_none) {
            return AlphaTables::default();
        }
        let mut tables = AlphaTables::default();
        // Textures by their test's address (one test per material), in the
        // order of their first triangle.
        let mut texture_of: HashMap<*const AlphaTest, u32> = HashMap::new();
        let mesh_texture: Vec<Option<u32>> = scene
            .meshes
            .iter()
            .zip(&tests)
            .map(|(m, test)| {
                let test = test.as_ref().filter(|_| !m.indices.is_empty())?;
                Some(*texture_of.entry(Arc::as_ptr(test)).or_insert_with(|| {
                    tables.textures.push(AlphaTexture::new(test));
                    (tables.textures.len() - 1) as u32
                }))
            })
            .collect();
        // Per triangle (global order), in parallel: its texture coordinates
        // and footprint, None for an opaque mesh's.
        let per_triangle: Vec<Option<([Vec2; 3], u32, Footprint)>> = scene
            .meshes
            .iter()
            .zip(&mesh_texture)
            .flat_map(|(m, &texture)| m.indices.iter().map(move |tri| (m, texture, tri)))
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(m, texture, tri)| {
                let texture = texture?;
                // As Scene::triangles reads them: (0, 0) where missing.
                let uvs = tri.map(|i| {
                    m.uvs
                        .as_ref()
                        .and_then(|u| u.get(i as usize).copied())
                        .unwrap_or(glam::DVec2::ZERO)
                        .as_vec2()
                });
                let footprint = tables.textures[texture as usize].footprint(uvs);
                Some((uvs, texture, footprint))
            })
            .collect();
        tables.triangle_records.reserve(per_triangle.len());
        for t in per_triangle {
            // A triangle opaque wherever its coverage can be read is an
            // opaque caster: the alpha round is for the others.
            match t {
                Some((uvs, texture, footprint)) if footprint != Footprint::Opaque => {
                    tables.triangle_records.push(tables.records.len() as u32);
                    tables.records.push(AlphaRecord {
                        uvs,
                        texture,
                        invisible: footprint == Footprint::Transparent,
                    });
                }
                _ => tables.triangle_records.push(ALPHA_NONE),
            }
        }
        if tables.records.is_empty() {
            return AlphaTables::default();
        }
        tables
    }

    /// Whether no triangle is alpha-tested.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Whether global triangle `t` is alpha-tested (and not opaque
    /// wherever it can be read: [`AlphaTexture::footprint`]).
    pub fn is_tested(&self, t: u32) -> bool {
        self.triangle_records
            .get(t as usize)
            .is_some_and(|&r| r != ALPHA_NONE)
    }

    /// Whether global triangle `t`, whose corners are `v`, is opaque where
    /// the line from `x` along `d` crosses its plane (opaque triangles
    /// everywhere).
    pub fn segment_opaque(&self, t: u32, v: [Vec3; 3], x: Vec3, d: Vec3) -> bool {
        match self.triangle_records.get(t as usize) {
            Some(&r) if r != ALPHA_NONE => {
                let rec = &self.records[r as usize];
                let uv = rec.uv(segment_barycentrics(x, d, v));
                self.textures[rec.texture as usize].opaque(uv)
            }
            _ => true,
        }
    }

    /// The shaders' tables: records (two `uvec4` each: u0, v0, u1, v1 as
    /// float bits; u2, v2, texture, 0), textures (two `uvec4` each: first
    /// alpha, width, height, flags; cutoff and factor as float bits, 0, 0)
    /// and the alphas (bytes, every texture's rows one after another).
    pub fn gpu(&self) -> (Vec<[u32; 4]>, Vec<[u32; 4]>, Vec<u8>) {
        let mut records = Vec::with_capacity(2 * self.records.len());
        for r in &self.records {
            let [a, b, c] = r.uvs;
            records.push([a.x, a.y, b.x, b.y].map(f32::to_bits));
            records.push([c.x.to_bits(), c.y.to_bits(), r.texture, 0]);
        }
        let mut textures = Vec::with_capacity(2 * self.textures.len());
        let mut alphas = Vec::new();
        for t in &self.textures {
            let flags = if t.linear { ALPHA_LINEAR } else { 0 }
                | wrap_code(t.wrap[0]) << 1
                | wrap_code(t.wrap[1]) << 3;
            textures.push([alphas.len() as u32, t.size[0], t.size[1], flags]);
            textures.push([t.cutoff.to_bits(), t.factor.to_bits(), 0, 0]);
            alphas.extend_from_slice(&t.alphas);
        }
        (records, textures, alphas)
    }
}

/// `WRAP_*` in `alpha_common.glsl`.
fn wrap_code(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => 0,
        Wrap::ClampToEdge => 1,
        Wrap::MirroredRepeat => 2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tables as the per-triangle loop over `Scene::triangles` built
    /// them (before the per-mesh, parallel build): the same records.
    fn tables_one_by_one(scene: &Scene) -> AlphaTables {
        let mut tables = AlphaTables::default();
        let mut texture_of: HashMap<*const AlphaTest, u32> = HashMap::new();
        for t in &scene.triangles() {
            let Some((test, uvs)) = &t.alpha else {
                tables.triangle_records.push(ALPHA_NONE);
                continue;
            };
            let texture = *texture_of.entry(Arc::as_ptr(test)).or_insert_with(|| {
                tables.textures.push(AlphaTexture::new(test));
                (tables.textures.len() - 1) as u32
            });
            let uvs = uvs.map(|uv| uv.as_vec2());
            let footprint = tables.textures[texture as usize].footprint(uvs);
            if footprint == Footprint::Opaque {
                tables.triangle_records.push(ALPHA_NONE);
                continue;
            }
            tables.triangle_records.push(tables.records.len() as u32);
            tables.records.push(AlphaRecord {
                uvs,
                texture,
                invisible: footprint == Footprint::Transparent,
            });
        }
        if tables.records.is_empty() {
            return AlphaTables::default();
        }
        tables
    }

    fn texture(size: [u32; 2], alphas: Vec<u8>, linear: bool, wrap: [Wrap; 2]) -> AlphaTexture {
        AlphaTexture {
            size,
            alphas,
            linear,
            wrap,
            cutoff: 0.5,
            factor: 1.0,
        }
    }

    #[test]
    fn footprints_far_out_are_mixed() {
        // Found by fuzzing: coordinates near f32::MAX overflowed the box's
        // integer corners.
        let t = texture([2, 2], vec![255; 4], false, [Wrap::Repeat; 2]);
        assert_eq!(
            t.footprint([Vec2::ZERO, Vec2::X, Vec2::Y]),
            Footprint::Opaque
        );
        for far in [1e7, 1e12, f32::MAX, -f32::MAX] {
            let uvs = [
                Vec2::splat(far),
                Vec2::splat(far) + Vec2::X,
                Vec2::splat(far) + Vec2::Y,
            ];
            assert_eq!(t.footprint(uvs), Footprint::Mixed, "{far}");
        }
    }

    /// The index of the fence's alpha-tested mesh.
    fn alpha_tested_mesh(scene: &crate::scene::Scene) -> usize {
        scene
            .meshes
            .iter()
            .position(|m| {
                m.material
                    .is_some_and(|k| scene.materials[k].alpha_test().is_some())
            })
            .expect("the fence is alpha-tested")
    }

    #[test]
    fn tables_equal_the_per_triangle_build() {
        let mut scene = crate::scene::builtin::builtin("fence").unwrap().scene;
        let demo = crate::scene::builtin::builtin("demo").unwrap().scene;
        let fence = scene.meshes[alpha_tested_mesh(&scene)].clone();
        // Opaque meshes between alpha-tested ones; a tested mesh without
        // triangles; one whose coordinates miss a corner (opaque: the test
        // needs them); copies whose coordinates read a few texels at spots
        // all over the texture (opaque, clear or mixed footprints).
        let materials = scene.materials.len();
        scene.materials.extend(demo.materials.iter().cloned());
        for m in &demo.meshes {
            let mut m = m.clone();
            m.material = m.material.map(|i| i + materials);
            scene.meshes.push(m);
        }
        let mut empty = fence.clone();
        empty.indices.clear();
        let mut short = fence.clone();
        short.uvs.as_mut().unwrap().pop();
        scene.meshes.extend([empty, short]);
        // The lattice's holes are centred where x + y and x - y are 8
        // modulo 16 (in texels of 64): (16.5, 24.5) is clear all round.
        let hole = glam::DVec2::new(16.5, 24.5) / 64.0;
        for k in 0..65 {
            let mut spot = fence.clone();
            let grid = glam::DVec2::new((k % 8) as f64 + 0.3, (k / 8) as f64 + 0.6) / 8.0;
            let at = if k == 64 { hole } else { grid };
            let scale = [1e-3, 2e-2][k % 2];
            for uv in spot.uvs.as_mut().unwrap() {
                *uv = at + *uv * scale;
            }
            scene.meshes.push(spot);
        }
        let tables = AlphaTables::new(&scene);
        assert_eq!(tables.triangle_records.len(), scene.triangle_count());
        assert_eq!(tables, tables_one_by_one(&scene));
        // Every kind of footprint was built.
        let opaque_tested = scene
            .meshes
            .iter()
            .filter(|m| m.material == fence.material)
            .map(|m| m.indices.len())
            .sum::<usize>()
            - tables.records.len();
        assert!(
            opaque_tested > 0,
            "some tested triangles read only opaque texels"
        );
        assert!(tables.records.iter().any(|r| r.invisible));
        assert!(tables.records.iter().any(|r| !r.invisible));
    }

    #[test]
    fn the_cache_rebuilds_exactly_when_an_input_changes() {
        let scene = crate::scene::builtin::builtin("fence").unwrap().scene;
        let tested = alpha_tested_mesh(&scene);
        let mut cache = AlphaTablesCache::default();
        let check = |cache: &mut AlphaTablesCache, scene: &Scene, reused: bool, what: &str| {
            let (tables, same) = cache.get(scene);
            assert_eq!(same, reused, "{what}: reused");
            assert_eq!(*tables, AlphaTables::new(scene), "{what}: tables");
        };
        check(&mut cache, &scene, false, "first");
        check(&mut cache, &scene, true, "unchanged");
        let mut moved = scene.clone();
        moved.meshes[tested].uvs.as_mut().unwrap()[0] += glam::DVec2::new(0.25, 0.0);
        check(&mut cache, &moved, false, "a texture coordinate");
        check(&mut cache, &scene, false, "back");
        let mut turned = scene.clone();
        turned.meshes[tested].indices[0].swap(0, 1);
        check(&mut cache, &turned, false, "a triangle");
        let mut cut = scene.clone();
        let k = cut.meshes[tested].material.unwrap();
        cut.materials[k].alpha_cutoff += 0.25;
        check(&mut cache, &cut, false, "the cutoff");
        // An equal image, but another one: compared by identity.
        let mut copied = scene.clone();
        let texture = copied.materials[k].base_color_texture.as_mut().unwrap();
        let image = texture.image.as_ref().unwrap().as_ref().clone();
        texture.image = Some(Arc::new(image));
        check(&mut cache, &copied, false, "an image");
        check(&mut cache, &copied, true, "the same image");
        let mut fewer = copied.clone();
        fewer.meshes.pop();
        check(&mut cache, &fewer, false, "a mesh fewer");
    }

    #[test]
    fn wrap_modes_follow_gltf() {
        assert_eq!(
            (-1..5)
                .map(|i| wrap(i, 2, Wrap::Repeat))
                .collect::<Vec<_>>(),
            [1, 0, 1, 0, 1, 0]
        );
        assert_eq!(
            (-1..5)
                .map(|i| wrap(i, 2, Wrap::ClampToEdge))
                .collect::<Vec<_>>(),
            [0, 0, 1, 1, 1, 1]
        );
        assert_eq!(
            (-2..6)
                .map(|i| wrap(i, 2, Wrap::MirroredRepeat))
                .collect::<Vec<_>>(),
            [1, 0, 0, 1, 1, 0, 0, 1]
        );
    }

    #[test]
    fn nearest_reads_the_texel_the_point_falls_in() {
        // 2 x 1: left opaque, right clear; v is irrelevant.
        let t = texture([2, 1], vec![255, 0], false, [Wrap::Repeat; 2]);
        assert!(t.opaque(Vec2::new(0.25, 0.5)));
        assert!(!t.opaque(Vec2::new(0.75, 0.5)));
        assert!(!t.opaque(Vec2::new(0.5, 0.5)), "x = 1 is the second texel");
        assert!(t.opaque(Vec2::new(1.25, 0.5)), "repeat");
        let c = texture([2, 1], vec![255, 0], false, [Wrap::ClampToEdge; 2]);
        assert!(!c.opaque(Vec2::new(1.25, 0.5)), "clamped to the last texel");
        assert!(c.opaque(Vec2::new(-3.0, 0.5)));
    }

    #[test]
    fn linear_blends_between_texel_centres() {
        let t = texture([2, 1], vec![255, 0], true, [Wrap::ClampToEdge; 2]);
        // Centres at u = 0.25 (255) and 0.75 (0): 0.5 of the way at u = 0.5.
        assert!(t.opaque(Vec2::new(0.49, 0.5)));
        assert!(t.opaque(Vec2::new(0.5, 0.5)), "127.5 >= 127.5");
        assert!(!t.opaque(Vec2::new(0.51, 0.5)));
        // At u = 1, half way from the last texel's centre to the next: the
        // first texel again when repeating, the last one when clamped.
        let r = texture([2, 1], vec![255, 0], true, [Wrap::Repeat; 2]);
        assert!(r.opaque(Vec2::new(1.0, 0.5)));
        assert!(!t.opaque(Vec2::new(1.0, 0.5)));
        for k in 0..40 {
            let u = k as f32 * 0.05 - 1.0;
            assert_eq!(
                r.opaque(Vec2::new(u, 0.5)),
                r.opaque(Vec2::new(u + 2.0, 0.5)),
                "u {u}"
            );
        }
    }

    #[test]
    fn barycentrics_agree_on_a_crossing() {
        let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let b = segment_barycentrics(Vec3::new(0.25, 0.5, 1.0), Vec3::new(0.0, 0.0, -2.0), v);
        assert!((b - Vec2::new(0.25, 0.5)).length() < 1e-6);
        let p = point_barycentrics(Vec3::new(0.25, 0.5, 0.0), v);
        assert!((p - Vec2::new(0.25, 0.5)).length() < 1e-6);
    }

    #[test]
    fn footprints_claim_only_what_every_point_says() {
        // Random textures and UV triangles: where a footprint says opaque
        // (transparent), every point of the triangle and a little outside
        // it must be; and some must say so, or this proves nothing.
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        let (mut sure, mut cases) = (0, 0);
        for _ in 0..3000 {
            let (w, h) = (1 + (rnd() * 6.0) as u32, 1 + (rnd() * 6.0) as u32);
            let alphas = (0..w * h)
                .map(|_| {
                    if rnd() < 0.7 {
                        255
                    } else {
                        (rnd() * 255.0) as u8
                    }
                })
                .collect();
            let wraps = [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat];
            let t = AlphaTexture {
                size: [w, h],
                alphas,
                linear: rnd() < 0.5,
                wrap: [
                    wraps[(rnd() * 3.0) as usize % 3],
                    wraps[(rnd() * 3.0) as usize % 3],
                ],
                cutoff: 0.2 + 0.6 * rnd(),
                factor: 0.8 + 0.2 * rnd(),
            };
            let c = Vec2::new(rnd() * 3.0 - 1.0, rnd() * 3.0 - 1.0);
            let s = 0.02 + 0.3 * rnd();
            let uvs = [c, c + Vec2::new(s, 0.0), c + Vec2::new(0.0, s)];
            let f = t.footprint(uvs);
            cases += 1;
            if f == Footprint::Mixed {
                continue;
            }
            sure += 1;
            let rec = AlphaRecord {
                uvs,
                texture: 0,
                invisible: false,
            };
            for k in 0..200 {
                let b = Vec2::new(rnd() * 1.02 - 0.01, rnd() * 1.02 - 0.01);
                let opaque = t.opaque(rec.uv(b));
                assert_eq!(
                    opaque,
                    f == Footprint::Opaque,
                    "case {cases} point {k}: {f:?}"
                );
            }
        }
        assert!(sure * 5 > cases, "{sure} of {cases} footprints sure");
    }
}
