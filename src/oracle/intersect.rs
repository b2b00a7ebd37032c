//! Double-precision watertight ray/triangle intersection (Woop, Benthin and
//! Wald, *Watertight Ray/Triangle Intersection*, JCGT 2013) and the robust
//! ray/box slab test (Ize, *Robust BVH Ray Traversal*, JCGT 2013).
//!
//! Both work on coordinates relative to the oracle's origin.

use glam::DVec3;

/// A ray with everything the triangle and box tests precompute per ray.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ray {
    /// Origin (origin-relative coordinates).
    pub org: [f64; 3],
    /// Dimension along which the direction is largest in magnitude.
    kz: usize,
    /// The two other dimensions, ordered to keep the winding.
    kx: usize,
    ky: usize,
    /// Shear constants.
    sx: f64,
    sy: f64,
    sz: f64,
    /// Component-wise reciprocal of the direction (±inf for zero components).
    pub inv: [f64; 3],
    /// 1 where the direction component is negative (the sign bit of `inv`).
    pub neg: [usize; 3],
}

/// Where a ray meets a triangle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hit {
    /// Ray parameter of the hit point.
    pub t: f64,
    /// Barycentric weight of the second vertex.
    pub b1: f64,
    /// Barycentric weight of the third vertex.
    pub b2: f64,
}

impl Ray {
    /// Sets up a ray; `dir` must be finite and non-zero (it need not be unit).
    #[inline]
    pub fn new(org: DVec3, dir: DVec3) -> Ray {
        let d = dir.to_array();
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let inv = [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]];
        Ray {
            org: org.to_array(),
            kz,
            kx,
            ky,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
            inv,
            neg: [
                inv[0].is_sign_negative() as usize,
                inv[1].is_sign_negative() as usize,
                inv[2].is_sign_negative() as usize,
            ],
        }
    }

    /// The watertight test against triangle `v`, accepting only hits with
    /// `t_min < t < t_max`. A ray through a shared edge or vertex hits at
    /// least one of the triangles sharing it; both sides count.
    #[inline(always)]
    pub fn intersect(&self, v: &[[f64; 3]; 3], t_min: f64, t_max: f64) -> Option<Hit> {
        let o = &self.org;
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let a = [v[0][0] - o[0], v[0][1] - o[1], v[0][2] - o[2]];
        let b = [v[1][0] - o[0], v[1][1] - o[1], v[1][2] - o[2]];
        let c = [v[2][0] - o[0], v[2][1] - o[1], v[2][2] - o[2]];
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        // Scaled barycentrics. Each edge function depends only on its edge's
        // two (per-vertex transformed) endpoints and flips sign exactly when
        // the edge is traversed the other way, which makes the test watertight.
        let u = cx * by - cy * bx;
        let vv = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        if (u < 0.0 || vv < 0.0 || w < 0.0) && (u > 0.0 || vv > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + vv + w;
        if det == 0.0 {
            return None;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let inv_det = 1.0 / det;
        let t = (u * az + vv * bz + w * cz) * inv_det;
        // NaN fails both comparisons.
        if t > t_min && t < t_max {
            Some(Hit {
                t,
                b1: vv * inv_det,
                b2: w * inv_det,
            })
        } else {
            None
        }
    }

    /// Conservative slab test against the box `b = [min, max]`: the entry
    /// parameter when the ray's `[t_min, t_max]` range may overlap the box.
    /// The exit parameter is enlarged by a few ulps (Ize 2013) so that
    /// rounding never culls a box holding a hit; a zero direction
    /// component whose slab computation gives NaN imposes no constraint.
    #[inline(always)]
    pub fn hit_box(&self, b: &[[f32; 3]; 2], t_min: f64, t_max: f64) -> Option<f64> {
        let o = &self.org;
        let n = &self.neg;
        let i = &self.inv;
        let x0 = (b[n[0]][0] as f64 - o[0]) * i[0];
        let x1 = (b[1 - n[0]][0] as f64 - o[0]) * i[0];
        let y0 = (b[n[1]][1] as f64 - o[1]) * i[1];
        let y1 = (b[1 - n[1]][1] as f64 - o[1]) * i[1];
        let z0 = (b[n[2]][2] as f64 - o[2]) * i[2];
        let z1 = (b[1 - n[2]][2] as f64 - o[2]) * i[2];
        // f64::max / f64::min return the non-NaN operand.
        let near = x0.max(y0).max(z0).max(t_min);
        let far = x1.min(y1).min(z1);
        let far = (far
            * if far > 0.0 {
                1.0 + ROBUST_FAR
            } else {
                1.0 - ROBUST_FAR
            })
        .min(t_max);
        if near <= far {
            Some(near)
        } else {
            None
        }
    }
}

/// Relative enlargement of a box's exit distance: more than 2·γ₃ for `f64`.
const ROBUST_FAR: f64 = 4.0 * f64::EPSILON;
