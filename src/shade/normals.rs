//! Coherent shading (paper §4.3, Figure 8): smooth shading normals that
//! never light a triangle facing away from the light.
//!
//! Per triangle corner: a shading normal (glTF `NORMAL`, else the
//! area-weighted mean of the face normals of its smoothing group) and its
//! smoothing group, the faces that share the corner's position (and, with
//! `NORMAL`, its normal) and, for generated normals, whose normal is
//! within [`CREASE_DEGREES`] of the corner's own face. Per pixel, with `l`
//! the unit vector to the light's centre (or against a directional light):
//!
//! - `l_bend` at each corner: the least `dot(l, n_F)` over its group's
//!   faces `F` (the paper's minimum over the adjacent faces; over the
//!   smoothing group, so that a crease does not darken a lit face);
//! - `lb`, `n`: `l_bend` and the shading normal interpolated with the
//!   point's barycentrics; `l_f = dot(normalize(n), l)` (Phong);
//! - `α = min(1, max(3·lb, 0))` and the Lambert term
//!   `max(0, α·l_f + (1 − α)·lb)`.
//!
//! On a triangle that faces away from the light every corner's `l_bend` is
//! negative (its own face is in every group of its corners), so `lb < 0`,
//! `α = 0` and the term is 0: ambient only. Across an edge shared inside a
//! smoothing group both triangles interpolate the same two corner values,
//! so the term is continuous. Visibility (the shadow) is unchanged: this is
//! shading only.

use glam::DVec3;
use rayon::prelude::*;

use crate::scene::Scene;

/// Largest angle between two faces' normals that are smoothed together
/// where the model has no `NORMAL`.
pub const CREASE_DEGREES: f64 = 60.0;

/// `cos(CREASE_DEGREES)`.
const COS_CREASE: f64 = 0.5;

/// The paper's `c`: how fast the term blends from `l_bend` back to Phong.
pub const BEND_SHARPNESS: f64 = 3.0;

/// Shading normals and smoothing groups of every triangle of a scene, in
/// [`Scene::triangles`] order.
#[derive(Clone, Debug, Default)]
pub struct ShadingNormals {
    /// Per triangle: unit face normal (counter-clockwise front; zero when
    /// degenerate).
    face: Vec<DVec3>,
    /// Per triangle: whether its mesh's normals are generated (its groups
    /// then stop at creases).
    generated: Vec<bool>,
    /// Per corner (3 per triangle): world position.
    position: Vec<DVec3>,
    /// Per corner: unit shading normal.
    normal: Vec<DVec3>,
    /// Per corner: the welded vertex it is (same position, and same normal
    /// where the mesh has normals).
    weld: Vec<u32>,
    /// Per welded vertex `w`: the triangles around it are
    /// `weld_faces[weld_start[w]..weld_start[w + 1]]`.
    weld_start: Vec<u32>,
    weld_faces: Vec<u32>,
}

impl ShadingNormals {
    /// Builds the normals and groups of every mesh of `scene` (groups stay
    /// inside a mesh). Sorting and counting, no hashing: O(n log n).
    pub fn new(scene: &Scene) -> Self {
        let mut out = ShadingNormals::default();
        let mut area = Vec::new();
        let mut welds = 0u32;
        for mesh in &scene.meshes {
            // Welded vertices: sort the vertices by (position, normal) bits.
            let keys: Vec<([u64; 3], [u64; 3])> = (0..mesh.positions.len())
                .map(|v| {
                    let p = mesh.positions[v].to_array().map(f64::to_bits);
                    let n = mesh
                        .normals
                        .as_ref()
                        .map_or([0; 3], |n| n[v].to_array().map(f64::to_bits));
                    (p, n)
                })
                .collect();
            let mut order: Vec<u32> = (0..mesh.positions.len() as u32).collect();
            order.par_sort_unstable_by_key(|&v| keys[v as usize]);
            let mut weld_of = vec![0u32; mesh.positions.len()];
            for (k, &v) in order.iter().enumerate() {
                if k > 0 && keys[v as usize] != keys[order[k - 1] as usize] {
                    welds += 1;
                }
                weld_of[v as usize] = welds;
            }
            if !order.is_empty() {
                welds += 1;
            }
            for t in 0..mesh.indices.len() {
                let [a, b, c] = mesh.triangle(t);
                let cross = (b - a).cross(c - a);
                area.push(cross);
                out.face.push(cross.normalize_or_zero());
                out.generated.push(mesh.normals.is_none());
                for &v in &mesh.indices[t] {
                    out.position.push(mesh.positions[v as usize]);
                    out.weld.push(weld_of[v as usize]);
                    out.normal.push(
                        mesh.normals
                            .as_ref()
                            .map_or(DVec3::ZERO, |n| n[v as usize].normalize_or_zero()),
                    );
                }
            }
        }
        // The triangles around each welded vertex (a counting sort).
        out.weld_start = vec![0; welds as usize + 1];
        for &w in &out.weld {
            out.weld_start[w as usize + 1] += 1;
        }
        for w in 0..welds as usize {
            out.weld_start[w + 1] += out.weld_start[w];
        }
        let mut fill = out.weld_start.clone();
        out.weld_faces = vec![0; out.weld.len()];
        for (c, &w) in out.weld.iter().enumerate() {
            out.weld_faces[fill[w as usize] as usize] = (c / 3) as u32;
            fill[w as usize] += 1;
        }
        // Generated normals: the area-weighted face normals of the group.
        let generated: Vec<DVec3> = (0..out.normal.len())
            .into_par_iter()
            .map(|c| {
                if out.normal[c] != DVec3::ZERO {
                    return out.normal[c];
                }
                let n = out
                    .group(c)
                    .map(|g| area[g])
                    .sum::<DVec3>()
                    .normalize_or_zero();
                if n == DVec3::ZERO {
                    out.face[c / 3]
                } else {
                    n
                }
            })
            .collect();
        out.normal = generated;
        out
    }

    /// Corner `c`'s smoothing group: the non-degenerate triangles around
    /// its welded vertex (its own always), within [`CREASE_DEGREES`] of its
    /// own face where the normals are generated.
    fn group(&self, c: usize) -> impl Iterator<Item = usize> + '_ {
        let t = c / 3;
        let w = self.weld[c] as usize;
        let own = self.face[t];
        let cos_crease = COS_CREASE;
        let generated = self.generated[t];
        self.weld_faces[self.weld_start[w] as usize..self.weld_start[w + 1] as usize]
            .iter()
            .map(|&g| g as usize)
            .filter(move |&g| {
                let n = self.face[g];
                g == t || (n != DVec3::ZERO && (!generated || n.dot(own) >= cos_crease))
            })
    }

    /// Triangles covered.
    pub fn triangle_count(&self) -> usize {
        self.face.len()
    }

    /// Unit face normal of triangle `t` (zero when degenerate).
    pub fn face_normal(&self, t: usize) -> DVec3 {
        self.face[t]
    }

    /// Unit shading normal of corner `i` (0 to 2) of triangle `t`.
    pub fn corner_normal(&self, t: usize, i: usize) -> DVec3 {
        self.normal[3 * t + i]
    }

    /// Barycentrics of `p` (projected onto triangle `t`'s plane, clamped
    /// to the triangle).
    pub fn barycentrics(&self, t: usize, p: DVec3) -> DVec3 {
        let [a, b, c] = [0, 1, 2].map(|i| self.position[3 * t + i]);
        let (e0, e1, e2) = (b - a, c - a, p - a);
        let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
        let (d20, d21) = (e2.dot(e0), e2.dot(e1));
        let den = d00 * d11 - d01 * d01;
        if den == 0.0 || !den.is_finite() {
            return DVec3::splat(1.0 / 3.0);
        }
        let v = (d11 * d20 - d01 * d21) / den;
        let w = (d00 * d21 - d01 * d20) / den;
        let b = DVec3::new(1.0 - v - w, v, w).max(DVec3::ZERO);
        b / (b.x + b.y + b.z)
    }

    /// The coherent Lambert term (module docs) at the point with
    /// barycentrics `bary` on triangle `t`, seen from the side of
    /// `view_normal` (the geometric normal facing the camera), for the unit
    /// direction to the light `to_light(point)`.
    pub fn lambert(
        &self,
        t: usize,
        bary: DVec3,
        view_normal: DVec3,
        to_light: impl Fn(DVec3) -> DVec3,
    ) -> f64 {
        let bends = self.corner_bends(t, &to_light);
        self.lambert_bent(t, bary, view_normal, &bends, to_light)
    }

    /// Per corner of triangle `t`, the least and the greatest `dot(l, n_F)`
    /// over the faces `F` of its smoothing group, `l = to_light(corner)`:
    /// its `l_bend` is the least seen from the front and minus the greatest
    /// from the back. They depend on the triangle and the light only, so a
    /// frame computes them once per visible triangle, not per pixel.
    pub fn corner_bends(&self, t: usize, to_light: impl Fn(DVec3) -> DVec3) -> [[f64; 2]; 3] {
        std::array::from_fn(|i| {
            let c = 3 * t + i;
            let l = to_light(self.position[c]);
            self.group(c)
                .map(|g| l.dot(self.face[g]))
                .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], d| {
                    [lo.min(d), hi.max(d)]
                })
        })
    }

    /// [`ShadingNormals::lambert`] with the triangle's
    /// [`ShadingNormals::corner_bends`] given.
    pub fn lambert_bent(
        &self,
        t: usize,
        bary: DVec3,
        view_normal: DVec3,
        bends: &[[f64; 2]; 3],
        to_light: impl Fn(DVec3) -> DVec3,
    ) -> f64 {
        let face = self.face[t];
        if face == DVec3::ZERO {
            let p: DVec3 = (0..3).map(|i| bary[i] * self.position[3 * t + i]).sum();
            return view_normal.dot(to_light(p)).max(0.0);
        }
        // Seen from the back (a double-sided surface): every normal flips,
        // and the least of the flipped dots is minus the greatest.
        let side = if view_normal.dot(face) < 0.0 {
            -1.0
        } else {
            1.0
        };
        let (mut lb, mut n, mut p) = (0.0, DVec3::ZERO, DVec3::ZERO);
        for (i, [least, greatest]) in bends.iter().enumerate() {
            let c = 3 * t + i;
            let bend = if side > 0.0 { *least } else { -greatest };
            lb += bary[i] * bend;
            n += bary[i] * side * self.normal[c];
            p += bary[i] * self.position[c];
        }
        let lf = n.normalize_or(side * face).dot(to_light(p));
        let alpha = (BEND_SHARPNESS * lb).clamp(0.0, 1.0);
        (alpha * lf + (1.0 - alpha) * lb).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn cos_crease_is_the_cosine_of_the_crease_angle() {
        let c = super::CREASE_DEGREES.to_radians().cos();
        assert!((c - super::COS_CREASE).abs() < 1e-12, "{c}");
    }
}
