//! The CPU oracle: an independent, double-precision ray-casting reference
//! that every GPU pass is tested against.
//!
//! It shares no code with the GPU passes or their CPU twins; it only reads
//! the [`scene`](crate::scene) and [`light`](crate::light) types. Triangles
//! are cast against with a watertight ray/triangle test (Woop, Benthin and
//! Wald 2013) in `f64`, accelerated by a binned-SAH BVH built here, and work
//! is spread over pixels with `rayon`.
//!
//! # Coordinates
//!
//! Everything is computed relative to the `origin` given to
//! [`Oracle::new`] (normally the camera eye): triangle vertices are stored as
//! `vertex − origin`, and view-sample and light-sample positions are
//! converted the same way before any arithmetic, so a scene 10⁴ units from
//! the world origin is as exact as one at the origin.
//!
//! # The definition of visibility
//!
//! Every conformance test uses exactly this definition. For a view sample
//! `p` with unit geometric normal `n` lying on triangle `k`, and a light
//! with samples `s₀ … s_{N−1}`:
//!
//! > **V(p)** is the fraction of the light's samples `s` for which
//! > `dot(n, s − p) > 0` **and** the open segment `(p, s)` meets no triangle
//! > other than `p`'s own triangle `k`.
//!
//! - *Open* means that only hits at parameter `0 < t < 1` along
//!   `p + t (s − p)` count; a hit exactly at `p` or exactly at `s` does not.
//! - Triangles whose global id equals the view sample's
//!   [`triangle`](ViewSample::triangle) are ignored; when it is
//!   [`NO_TRIANGLE`] nothing is ignored.
//! - For a directional light ([`LightSamples::Direction`]) `s − p` is
//!   replaced by `−direction` and the segment by the open ray from `p`
//!   towards `−direction` (hits at `t > 0` count, unbounded).
//! - Every triangle is tested from both sides: closed-mesh back-face rules
//!   are no part of the oracle. Triangles with zero area or non-finite
//!   vertices never block (they are left out of the BVH; ids stay stable).
//! - With zero light samples V is 0.
//!
//! **Numerical tolerance at the endpoints.** View samples found by casting
//! rays lie on their triangle's plane only to within rounding, so a
//! neighbouring triangle that shares an edge or vertex with `p`'s triangle
//! can be "hit" a rounding error away from `p` (`t ≈ 1e−16`). To keep such
//! hits from deciding visibility, a hit closer than
//! `ENDPOINT_EPSILON · (D + |x − origin|)` to an endpoint `x` (`x = p` or
//! `x = s`) is taken to be at that endpoint and does not count, where `D`
//! is the diagonal of the bounding box of the scene's triangles (a few
//! 10⁻⁹ of the scene's size for samples inside it); directional shadow rays
//! start at that distance from `p`. See [`ENDPOINT_EPSILON`].
//!
//! Shadow rays use any-hit traversal (they stop at the first occluder
//! found, trying the previous pixel's occluder first).

mod bvh;
mod coverage;
mod intersect;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::light::LightSamples;
use crate::scene::{Camera, SceneTriangle};
use bvh::Bvh;
use coverage::Coverage;
use intersect::{Hit, Ray};

/// The `triangle` of a view sample that lies on no scene triangle (a
/// user-supplied sample): no triangle is ignored for it.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Relative tolerance at the ends of a shadow segment: a hit closer than
/// `ENDPOINT_EPSILON · (D + |x − origin|)` to an endpoint `x` of the segment
/// (the view sample or the light sample), with `D` the diagonal of the
/// scene's bounding box, is treated as a hit exactly at `x`, which does not
/// block (see the [module documentation](self)).
pub const ENDPOINT_EPSILON: f64 = 1e-9;

/// A point whose visibility is computed: where a primary ray first met the
/// scene, or a user-supplied point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewSample {
    /// World-space position.
    pub position: DVec3,
    /// Unit geometric normal of the hit triangle, flipped to face the camera.
    pub normal: DVec3,
    /// Global id of the triangle the sample lies on (the index into
    /// [`Scene::triangles`](crate::scene::Scene::triangles)), or
    /// [`NO_TRIANGLE`] for user-supplied samples.
    pub triangle: u32,
}

impl ViewSample {
    /// A user-supplied sample at `position` with normal `normal` (normalised
    /// here), lying on no scene triangle.
    pub fn user(position: DVec3, normal: DVec3) -> ViewSample {
        ViewSample {
            position,
            normal: normal.normalize(),
            triangle: NO_TRIANGLE,
        }
    }
}

/// One optional view sample per pixel.
#[derive(Clone, Debug)]
pub struct ViewSamples {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// World-space camera eye the samples were seen from.
    pub eye: DVec3,
    /// Row-major samples, `y = 0` is the top row, `len == width * height`;
    /// `None` where the pixel's ray met nothing.
    pub samples: Vec<Option<ViewSample>>,
}

impl ViewSamples {
    /// Wraps user-supplied samples (row-major, `y = 0` on top).
    ///
    /// Fails when `samples.len() != width * height`.
    pub fn from_user(
        width: u32,
        height: u32,
        eye: DVec3,
        samples: Vec<Option<ViewSample>>,
    ) -> crate::Result<ViewSamples> {
        if samples.len() as u64 != width as u64 * height as u64 {
            return Err(crate::Error::InvalidInput(format!(
                "view samples: {} samples for a {width}x{height} image",
                samples.len()
            )));
        }
        Ok(ViewSamples {
            width,
            height,
            eye,
            samples,
        })
    }

    /// The sample of pixel (x, y), if any (`None` outside the image).
    pub fn get(&self, x: u32, y: u32) -> Option<&ViewSample> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.samples
            .get(y as usize * self.width as usize + x as usize)?
            .as_ref()
    }
}

/// One light sample for a single [`Oracle::sample_visible`] query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightTarget {
    /// A world-space light-sample position.
    Point(DVec3),
    /// A directional light: the direction light travels; the shadow ray goes
    /// towards `−direction`, unbounded.
    Direction(DVec3),
}

/// A light target in origin-relative coordinates.
#[derive(Clone, Copy, Debug)]
enum RelTarget {
    /// Relative sample position and the endpoint tolerance there (a distance).
    Point(DVec3, f64),
    /// Unit direction from the view sample towards the light.
    Toward(DVec3),
    /// A non-finite or zero sample: never visible.
    Invalid,
}

/// The reference ray caster. Build it once per scene with [`Oracle::new`];
/// all queries take `&self` and may run concurrently.
pub struct Oracle {
    origin: DVec3,
    bvh: Bvh,
    triangle_count: usize,
    /// Diagonal of the bounding box of the usable triangles.
    extent: f64,
    shadow_rays: AtomicU64,
    /// Per global id: the alpha test of an alpha-tested triangle (a hit
    /// where it is not opaque is no hit), `None` for opaque ones.
    coverage: Vec<Option<Coverage>>,
}

impl std::fmt::Debug for Oracle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Oracle")
            .field("origin", &self.origin)
            .field("triangle_count", &self.triangle_count)
            .field("bvh_depth", &self.bvh.depth())
            .field("shadow_rays", &self.shadow_rays_cast())
            .finish_non_exhaustive()
    }
}

impl Oracle {
    /// Builds the oracle for `triangles` (global ids are indices into this
    /// slice), with every coordinate taken relative to `origin`, normally
    /// the camera eye. Triangles with zero area or non-finite vertices are
    /// left out of the hierarchy (they can never be hit) but keep their ids.
    ///
    /// # Panics
    /// If `origin` is not finite or there are more than `u32::MAX - 1` triangles.
    pub fn new(triangles: &[SceneTriangle], origin: DVec3) -> Oracle {
        assert!(
            origin.is_finite(),
            "oracle origin must be finite, got {origin:?}"
        );
        assert!(
            triangles.len() < NO_TRIANGLE as usize,
            "too many triangles for the oracle: {}",
            triangles.len()
        );
        let mut tris = Vec::with_capacity(triangles.len());
        let mut ids = Vec::with_capacity(triangles.len());
        let coverage = triangles
            .iter()
            .map(|t| {
                t.alpha.as_ref().map(|(test, uvs)| Coverage {
                    test: test.clone(),
                    uvs: *uvs,
                    vertices: t.vertices.map(|v| v - origin),
                })
            })
            .collect();
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for (id, t) in triangles.iter().enumerate() {
            let v = t.vertices.map(|p| p - origin);
            if !v.iter().all(|p| p.is_finite()) {
                continue;
            }
            let cross = (v[1] - v[0]).cross(v[2] - v[0]);
            if !cross.is_finite() || cross == DVec3::ZERO {
                continue;
            }
            for p in &v {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            tris.push(v.map(|p| p.to_array()));
            ids.push(id as u32);
        }
        let extent = if tris.is_empty() {
            0.0
        } else {
            (hi - lo).length()
        };
        Oracle {
            origin,
            bvh: Bvh::build(tris, ids),
            triangle_count: triangles.len(),
            extent,
            shadow_rays: AtomicU64::new(0),
            coverage,
        }
    }

    /// Whether alpha-tested triangle `triangle`'s opacity at world point
    /// `p` of its plane differs somewhere within `radius` of `p` in that
    /// plane (at the eight points of a circle of that radius): the
    /// conformance tests' band for a point whose f32 computation may land
    /// on the other side of a texel edge or of the cutoff. False for
    /// opaque triangles.
    pub fn alpha_flips_near(&self, triangle: u32, p: DVec3, radius: f64) -> bool {
        let Some(Some(c)) = self.coverage.get(triangle as usize) else {
            return false;
        };
        let [a, b, v2] = c.vertices;
        let u = (b - a).normalize_or_zero();
        let n = (b - a).cross(v2 - a);
        let w = n.cross(u).normalize_or_zero();
        let q = p - self.origin;
        let at = |x: DVec3| {
            let (b1, b2) = c.barycentrics(x);
            c.opaque(b1, b2)
        };
        let here = at(q);
        (0..8).any(|k| {
            let angle = k as f64 * std::f64::consts::FRAC_PI_4;
            at(q + (u * angle.cos() + w * angle.sin()) * radius) != here
        })
    }

    /// Whether a hit of leaf-ordered triangle `index` counts: everywhere
    /// on opaque triangles, where the alpha test passes on the others.
    fn opaque_hit(&self, index: u32, hit: &Hit) -> bool {
        match self.coverage.get(self.bvh.id(index) as usize) {
            Some(Some(c)) => c.opaque(hit.b1, hit.b2),
            _ => true,
        }
    }

    /// The origin all coordinates are taken relative to.
    pub fn origin(&self) -> DVec3 {
        self.origin
    }

    /// Number of triangles given to [`Oracle::new`], degenerate ones included.
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Casts one ray per pixel centre along `camera.ray_direction(x, y)`
    /// from `camera.eye` and keeps the nearest hit (`t > 0`; equal distances
    /// go to the smaller triangle id). The position is interpolated from the
    /// hit triangle's vertices with the hit's barycentric coordinates.
    pub fn primary_view_samples(&self, camera: &Camera) -> ViewSamples {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let mut samples = vec![None; w * h];
        let eye = camera.eye - self.origin;
        if w > 0 {
            samples.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                for (x, out) in row.iter_mut().enumerate() {
                    let dir = camera.ray_direction(x as u32, y as u32);
                    *out = self.primary_sample(eye, dir);
                }
            });
        }
        ViewSamples {
            width: camera.width,
            height: camera.height,
            eye: camera.eye,
            samples,
        }
    }

    /// The view sample seen along `dir` from the relative eye position `eye`.
    fn primary_sample(&self, eye: DVec3, dir: DVec3) -> Option<ViewSample> {
        if !dir.is_finite() || dir == DVec3::ZERO || !eye.is_finite() {
            return None;
        }
        let ray = Ray::new(eye, dir);
        let accept = |i: u32, h: &Hit| self.opaque_hit(i, h);
        let hit = self.bvh.nearest(&ray, 0.0, f64::INFINITY, &accept)?;
        let v = self.bvh.triangle(hit.index).map(DVec3::from_array);
        let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
        let p = v[0] + e1 * hit.hit.b1 + e2 * hit.hit.b2;
        let mut n = e1.cross(e2).normalize();
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        Some(ViewSample {
            position: p + self.origin,
            normal: n,
            triangle: self.bvh.id(hit.index),
        })
    }

    /// V(p) (see the [module documentation](self)) for every pixel: the
    /// fraction of `light`'s samples visible from the pixel's view sample, and
    /// 0.0 where the pixel has no view sample. One value per entry of
    /// `view.samples`. `progress`, when given, is advanced by one per image
    /// row (its length is left to the caller, normally `view.height`).
    pub fn visibility(
        &self,
        view: &ViewSamples,
        light: &LightSamples,
        progress: Option<&indicatif::ProgressBar>,
    ) -> Vec<f32> {
        let targets = self.rel_targets(light);
        self.visible_fractions(view, targets.len(), progress, |rs, _, hint, traced| {
            let visible = |t: &&RelTarget| self.shadow_query(rs, t, hint, traced);
            targets.iter().filter(visible).count()
        })
    }

    /// [`Oracle::visibility`] with a per-pixel rotation: the pixel at
    /// index `i` of `view.samples` sees each of `light`'s samples turned
    /// by [`PixelRotation::turn`](crate::light::PixelRotation::turn)`(l, i)`
    /// (the GPU's angles, in f64).
    pub fn visibility_rotated(
        &self,
        view: &ViewSamples,
        light: &[DVec3],
        rotation: &crate::light::PixelRotation,
        progress: Option<&indicatif::ProgressBar>,
    ) -> Vec<f32> {
        let table = crate::light::pixel_rotation_table();
        self.visible_fractions(view, light.len(), progress, |rs, pixel, hint, traced| {
            let turned = light
                .iter()
                .map(|&l| self.rel_point(rotation.turn(l, pixel, &table)));
            turned
                .filter(|t| self.shadow_query(rs, t, hint, traced))
                .count()
        })
    }

    /// Per pixel, `visible(sample, pixel, hint, traced)` (the count of its
    /// `count` light samples it sees) over `count`, in parallel rows; 0.0
    /// where there is no view sample.
    fn visible_fractions(
        &self,
        view: &ViewSamples,
        count: usize,
        progress: Option<&indicatif::ProgressBar>,
        visible: impl Fn(&RelSample, u32, &mut u32, &mut u64) -> usize + Sync,
    ) -> Vec<f32> {
        let mut out = vec![0f32; view.samples.len()];
        let w = (view.width as usize).max(1);
        out.par_chunks_mut(w)
            .zip(view.samples.par_chunks(w))
            .enumerate()
            .for_each(|(row, (row_out, row_in))| {
                let mut hint = u32::MAX;
                let mut traced = 0;
                for (col, (o, s)) in row_out.iter_mut().zip(row_in).enumerate() {
                    let Some(s) = s else { continue };
                    let Some(rs) = self.rel_sample(s) else {
                        continue;
                    };
                    let seen = visible(&rs, (row * w + col) as u32, &mut hint, &mut traced);
                    if count > 0 {
                        *o = (seen as f64 / count as f64) as f32;
                    }
                }
                self.shadow_rays.fetch_add(traced, Ordering::Relaxed);
                if let Some(pb) = progress {
                    pb.inc(1);
                }
            });
        out
    }

    /// Per pixel, one bit per light sample: bit `s % 64` of word `s / 64` is
    /// set when light sample `s` is visible from the pixel's view sample
    /// (see the [module documentation](self)). Each mask has
    /// `ceil(light.len() / 64)` words; pixels without a view sample get an
    /// empty vector.
    pub fn visibility_masks(&self, view: &ViewSamples, light: &LightSamples) -> Vec<Vec<u64>> {
        let targets = self.rel_targets(light);
        let words = targets.len().div_ceil(64);
        let mut out = vec![Vec::new(); view.samples.len()];
        let w = (view.width as usize).max(1);
        out.par_chunks_mut(w)
            .zip(view.samples.par_chunks(w))
            .for_each(|(row_out, row_in)| {
                let mut hint = u32::MAX;
                let mut traced = 0;
                for (o, s) in row_out.iter_mut().zip(row_in) {
                    let Some(s) = s else { continue };
                    let mut mask = vec![0u64; words];
                    if let Some(rs) = self.rel_sample(s) {
                        for (i, t) in targets.iter().enumerate() {
                            if self.shadow_query(&rs, t, &mut hint, &mut traced) {
                                mask[i / 64] |= 1 << (i % 64);
                            }
                        }
                    }
                    *o = mask;
                }
                self.shadow_rays.fetch_add(traced, Ordering::Relaxed);
            });
        out
    }

    /// Whether the single light sample `light_sample` is visible from `sample`
    /// (see the [module documentation](self)).
    pub fn sample_visible(&self, sample: &ViewSample, light_sample: LightTarget) -> bool {
        let Some(rs) = self.rel_sample(sample) else {
            return false;
        };
        let target = match light_sample {
            LightTarget::Point(s) => self.rel_point(s),
            LightTarget::Direction(d) => rel_direction(d),
        };
        let mut hint = u32::MAX;
        let mut traced = 0;
        let v = self.shadow_query(&rs, &target, &mut hint, &mut traced);
        self.shadow_rays.fetch_add(traced, Ordering::Relaxed);
        v
    }

    /// Total number of shadow rays traced by this oracle so far (samples
    /// rejected by the normal rule are not traced and not counted).
    pub fn shadow_rays_cast(&self) -> u64 {
        self.shadow_rays.load(Ordering::Relaxed)
    }

    fn rel_point(&self, s: DVec3) -> RelTarget {
        let r = s - self.origin;
        if r.is_finite() {
            RelTarget::Point(r, self.tolerance(r))
        } else {
            RelTarget::Invalid
        }
    }

    fn rel_targets(&self, light: &LightSamples) -> Vec<RelTarget> {
        match light {
            LightSamples::Positions(ps) => ps.iter().map(|&s| self.rel_point(s)).collect(),
            LightSamples::Direction(d) => vec![rel_direction(*d)],
        }
    }

    /// The endpoint tolerance (a distance) at relative position `r`.
    fn tolerance(&self, r: DVec3) -> f64 {
        ENDPOINT_EPSILON * (self.extent + r.length())
    }

    /// A view sample in relative coordinates, if its position and normal are finite.
    fn rel_sample(&self, s: &ViewSample) -> Option<RelSample> {
        let p = s.position - self.origin;
        (p.is_finite() && s.normal.is_finite()).then(|| RelSample {
            p,
            n: s.normal,
            tolerance: self.tolerance(p),
            ignore: s.triangle,
        })
    }

    /// The visibility of one light target from a view sample; counts traced
    /// rays in `traced`.
    #[inline]
    fn shadow_query(
        &self,
        v: &RelSample,
        target: &RelTarget,
        hint: &mut u32,
        traced: &mut u64,
    ) -> bool {
        let d = match *target {
            RelTarget::Point(s, _) => s - v.p,
            RelTarget::Toward(d) => d,
            RelTarget::Invalid => return false,
        };
        // `facing` is false for a zero `d` and for NaN.
        let facing = v.n.dot(d) > 0.0;
        if !facing || !d.is_finite() {
            return false;
        }
        let (t_min, t_max) = match *target {
            RelTarget::Point(_, tol) => {
                let len = d.length();
                (v.tolerance / len, 1.0 - tol / len)
            }
            _ => (v.tolerance, f64::INFINITY),
        };
        if t_min >= t_max {
            // The whole segment lies within the endpoint tolerances.
            return true;
        }
        *traced += 1;
        let ray = Ray::new(v.p, d);
        let accept = |i: u32, h: &Hit| self.opaque_hit(i, h);
        !self
            .bvh
            .any_hit(&ray, t_min, t_max, v.ignore, hint, &accept)
    }
}

/// A view sample in origin-relative coordinates.
#[derive(Clone, Copy, Debug)]
struct RelSample {
    p: DVec3,
    n: DVec3,
    /// Endpoint tolerance at `p` (a distance).
    tolerance: f64,
    /// Triangle id to ignore.
    ignore: u32,
}

/// The unit direction towards a directional light travelling along `d`.
fn rel_direction(d: DVec3) -> RelTarget {
    let t = -d.normalize_or_zero();
    if t == DVec3::ZERO {
        RelTarget::Invalid
    } else {
        RelTarget::Toward(t)
    }
}

#[cfg(test)]
mod tests {
    use super::bvh::Bvh;
    use super::intersect::Ray;
    use glam::DVec3;

    /// splitmix64 in [0, 1).
    fn rng(state: &mut u64) -> f64 {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    fn random_tris(n: usize, seed: u64) -> Vec<[[f64; 3]; 3]> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                let c = [
                    rng(&mut s) * 20.0 - 10.0,
                    rng(&mut s) * 20.0 - 10.0,
                    rng(&mut s) * 20.0 - 10.0,
                ];
                let mut t = [[0.0; 3]; 3];
                for v in &mut t {
                    for k in 0..3 {
                        v[k] = c[k] + rng(&mut s) * 2.0 - 1.0;
                    }
                }
                t
            })
            .collect()
    }

    /// The BVH's nearest and any-hit queries agree with testing every triangle.
    #[test]
    fn bvh_matches_brute_force() {
        let tris = random_tris(3000, 7);
        let ids: Vec<u32> = (0..tris.len() as u32).collect();
        let bvh = Bvh::build(tris.clone(), ids);
        assert!(bvh.depth() < 60);
        let mut s = 99;
        let mut hits = 0;
        for _ in 0..4000 {
            let o = DVec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 30.0 - 15.0;
            let e = DVec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 30.0 - 15.0;
            let ray = Ray::new(o, e - o);
            let ignore = (rng(&mut s) * 3000.0) as u32;
            // Brute force.
            let mut best: Option<(f64, u32)> = None;
            let mut any = false;
            for (i, t) in tris.iter().enumerate() {
                if let Some(h) = ray.intersect(t, 0.0, f64::INFINITY) {
                    if best.is_none_or(|(bt, bi)| h.t < bt || (h.t == bt && (i as u32) < bi)) {
                        best = Some((h.t, i as u32));
                    }
                }
                if i as u32 != ignore && ray.intersect(t, 1e-9, 1.0 - 1e-9).is_some() {
                    any = true;
                }
            }
            let got = bvh.nearest(&ray, 0.0, f64::INFINITY, &|_, _| true);
            assert_eq!(got.map(|h| (h.hit.t, bvh.id(h.index))), best);
            let mut hint = u32::MAX;
            assert_eq!(
                bvh.any_hit(&ray, 1e-9, 1.0 - 1e-9, ignore, &mut hint, &|_, _| true),
                any
            );
            hits += any as usize;
        }
        assert!(hits > 200 && hits < 3800, "{hits}");
    }

    /// Rays through a shared edge or vertex of a fan never slip through.
    #[test]
    fn watertight_on_shared_edges() {
        let n = 7;
        let c = [0.3, 0.1, 0.2];
        let rim = |k: usize| {
            let a = k as f64 / n as f64 * std::f64::consts::TAU;
            [c[0] + a.cos(), c[1] + 0.37 * a.sin(), c[2] + a.sin()]
        };
        let tris: Vec<[[f64; 3]; 3]> = (0..n).map(|k| [c, rim(k), rim((k + 1) % n)]).collect();
        let mut s = 5;
        for k in 0..n {
            for _ in 0..200 {
                // A point on the shared edge from the centre to rim(k).
                let f = rng(&mut s);
                let r = rim(k);
                let q = DVec3::new(
                    c[0] + f * (r[0] - c[0]),
                    c[1] + f * (r[1] - c[1]),
                    c[2] + f * (r[2] - c[2]),
                );
                let o = DVec3::new(rng(&mut s) - 0.5, 3.0, rng(&mut s) - 0.5);
                let ray = Ray::new(o, q - o);
                assert!(
                    tris.iter().any(|t| ray.intersect(t, 0.0, 2.0).is_some()),
                    "ray slipped through edge {k}"
                );
            }
            // Through the centre vertex.
            let o = DVec3::new(rng(&mut s), 2.0, rng(&mut s));
            let ray = Ray::new(o, DVec3::from_array(c) - o);
            assert!(tris.iter().any(|t| ray.intersect(t, 0.0, 2.0).is_some()));
        }
    }
}
