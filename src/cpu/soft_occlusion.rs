//! CPU twin of soft-shadow occlusion (`soft_occlusion.comp`, paper §4.2):
//! the light samples one triangle hides from one view sample, in look-up
//! and exact modes.

use glam::Vec3;

use super::clusters::{
    beyond_reach, caster_ball, caster_sphere, outside_hull, HULL_MARGIN, REACH_MARGIN,
};
use super::plane_lut::{blocks, lut_index, BlockBits};

/// How the bits of a plane are found.
pub enum PlaneBits<'a> {
    /// Looked up in a table from [`build_lut`](crate::cpu::plane_lut::build_lut).
    Lut {
        /// The table: for each of the `res`³ texels ([`lut_index`]), one
        /// [`BlockBits`] per 128-sample block.
        lut: &'a [BlockBits],
        /// The table's resolution per axis.
        res: u32,
    },
    /// Every light sample tested.
    Exact {
        /// The light samples, camera-relative.
        samples: &'a [Vec3],
    },
}

/// The light samples (one [`BlockBits`] per block) that triangle (a, b, c)
/// hides from view sample x, all camera-relative, for a light bounded by
/// (origin, radius); `closed` triangles block only light samples behind
/// their oriented plane. `None` when the pair is not tested (x on the
/// plane, behind a closed triangle, the triangle beyond the reach of x
/// and the light, [`beyond_reach`], or outside their hull,
/// [`outside_hull`]). The same arithmetic as
/// `soft_occlusion.comp`, sphere rejection included. An alpha-tested
/// triangle blocks a light sample `l` only where `opaque(l)` (its alpha
/// test where the segment from x to l crosses it: [`crate::cpu::alpha`]);
/// the GPU tests those per light sample in every mode, so they take
/// [`PlaneBits::Exact`].
#[allow(clippy::too_many_arguments)]
pub fn blocked_bits(
    x: Vec3,
    [a, b, c]: [Vec3; 3],
    closed: bool,
    origin: Vec3,
    radius: f32,
    light_samples: usize,
    bits: &PlaneBits,
    opaque: Option<&dyn Fn(Vec3) -> bool>,
) -> Option<Vec<BlockBits>> {
    let nb = blocks(light_samples);
    let none = vec![[0u32; 4]; nb];
    let n = (b - a).cross(c - a);
    let sx = n.dot(x - a);
    if sx == 0.0 || sx.is_nan() || (closed && sx < 0.0) {
        return None;
    }
    // The reach rule: the caster lies farther from the light's centre than
    // x and the light reach; not a test.
    let reach = (x - origin).length().max(radius);
    let ball = caster_ball([a, b, c]);
    if beyond_reach(caster_sphere(origin, ball), reach, REACH_MARGIN) {
        return None;
    }
    // The hull rule: the caster's ball outside the hull of x and the light.
    if outside_hull(ball, x, 0.0, origin, radius, HULL_MARGIN) {
        return None;
    }
    let exact = matches!(bits, PlaneBits::Exact { .. });
    let inv_r = 1.0 / radius;
    let sigma = if sx > 0.0 { 1.0 } else { -1.0 };
    let ns = n * (sigma / n.dot(n).sqrt());
    let ao = a - origin;
    let ox = x - origin;
    let lo = |dist: f32| {
        if exact {
            -1.0 - 1e-5 * (1.0 + dist * inv_r)
        } else {
            -1.0
        }
    };
    let d0 = ns.dot(ao) * inv_r;
    // NaN (a degenerate plane) rejects too.
    let outside = |d: f32, lo: f32| d.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater);
    if outside(d0, lo(ao.length())) {
        return Some(none);
    }
    let (m, se) = edge_normals(x, [a, b, c]);
    let mut planes = vec![(ns, d0)];
    for (u, d) in edge_planes(x, [a, b, c], origin, radius) {
        if outside(d, lo(ox.length())) {
            return Some(none);
        }
        planes.push((u, d));
    }
    Some(match bits {
        PlaneBits::Lut { lut, res } => (0..nb)
            .map(|blk| {
                planes.iter().fold([u32::MAX; 4], |acc, &(u, d)| {
                    let p = if d >= 1.0 {
                        [u32::MAX; 4]
                    } else {
                        lut[lut_index(u, d, *res) as usize * nb + blk]
                    };
                    std::array::from_fn(|w| acc[w] & p[w])
                })
            })
            .collect(),
        PlaneBits::Exact { samples } => {
            let mut out = none;
            for (j, &l) in samples.iter().enumerate() {
                if sigma * n.dot(l - a) < 0.0
                    && se * m[0].dot(l - x) > 0.0
                    && se * m[1].dot(l - x) > 0.0
                    && se * m[2].dot(l - x) > 0.0
                    && opaque.is_none_or(|o| o(l))
                {
                    out[j / 128][(j % 128) / 32] |= 1 << (j % 32);
                }
            }
            out
        }
    })
}

/// `soft_occlusion.comp`'s margin of the wedge rule for planes through
/// view sample `x` (light radii; light bounded by (origin, radius)): twice
/// the per-sample test's rounding bound (`rounding_bound`, 64 f32 ulps of
/// the magnitudes involved) and the whole-light rejection's allowance
/// (`sphere_allowance`, 1e-5 of the distance).
pub fn wedge_margin(x: Vec3, origin: Vec3, radius: f32) -> f32 {
    let inv_r = 1.0 / radius;
    let rounding = 64.0
        * f32::EPSILON
        * (origin.length() + radius + x.length() + (x - origin).length())
        * inv_r;
    let allowance = 1e-5 * (1.0 + (x - origin).length() * inv_r);
    2.0 * (rounding + allowance)
}

/// The wedge rule for two planes (u, d) (unit u, light radii from the
/// light's centre): whether no y with |y| <= 1 lies behind both by less
/// than margin `m` (u.y < d + m), shown by the separating plane of the
/// weights of the planes' common edge's point nearest the light's centre.
/// Twin of `edge_misses_light` in `soft_occlusion.comp`.
pub fn edge_misses_light((ui, di): (Vec3, f32), (uj, dj): (Vec3, f32), m: f32) -> bool {
    let g = ui.dot(uj);
    let li = (g * dj - di).max(0.0);
    let lj = (g * di - dj).max(0.0);
    li * (di + m) + lj * (dj + m) + (1.0 + 1e-5) * (li * ui + lj * uj).length() < 0.0
}

/// The wedge rule over a caster's three edge planes through the view
/// sample (`u`, `d` as [`blocked_bits`] computes them): true when the
/// caster's cone from the sample passes the light's bounding sphere
/// (margin `m`: [`wedge_margin`]), so that it blocks no light sample.
/// Twin of `wedges_miss_light` in `soft_occlusion.comp` (which skips such
/// pairs; [`blocked_bits`] does not, so that it stays the brute force the
/// rule is checked against).
pub fn wedges_miss_light(planes: &[(Vec3, f32); 3], m: f32) -> bool {
    (0..3).any(|i| edge_misses_light(planes[i], planes[(i + 1) % 3], m))
}

/// The planes through view sample x and each edge of (a, b, c), facing out
/// of the triangle's cone from x, as (unit normal, distance of x's plane
/// from the light's centre in light radii): those of [`blocked_bits`].
pub fn edge_planes(x: Vec3, tri: [Vec3; 3], origin: Vec3, radius: f32) -> [(Vec3, f32); 3] {
    let (m, se) = edge_normals(x, tri);
    m.map(|mi| {
        let u = mi * (-se / mi.dot(mi).sqrt());
        (u, u.dot(x - origin) * (1.0 / radius))
    })
}

/// The (unnormalised) normals of the planes through x and each edge of
/// (a, b, c), and the sign that turns them out of the triangle's cone.
fn edge_normals(x: Vec3, [a, b, c]: [Vec3; 3]) -> ([Vec3; 3], f32) {
    let m = [
        (a - x).cross(b - x),
        (b - x).cross(c - x),
        (c - x).cross(a - x),
    ];
    let se = if m[0].dot(c - x) < 0.0 { -1.0 } else { 1.0 };
    (m, se)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::plane_lut::{build_lut, normalized_samples};

    /// Random numbers for the cases.
    struct Cases(crate::light::SplitMix64);

    impl Cases {
        /// Uniform in [0, 1).
        fn unit(&mut self) -> f32 {
            self.0.next_f64() as f32
        }

        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.unit()
        }

        /// A random direction.
        fn dir(&mut self) -> Vec3 {
            Vec3::new(self.unit() - 0.5, self.unit() - 0.5, self.unit() - 0.5).normalize_or(Vec3::X)
        }
    }

    /// The wedge rule skips only casters that block no light sample: cones
    /// from view samples (inside the light's sphere too) aimed from the
    /// light's centre to 2.5 radii off, small, large and sliver triangles,
    /// light samples in the sphere and on it nearest each cone edge's
    /// line; the pairs that the four planes' sphere tests let through,
    /// against every light sample's exact test. And it does skip the cones
    /// that clearly pass the light.
    #[test]
    fn wedge_rule_skips_only_casters_that_block_nothing() {
        let mut rng = Cases(crate::light::SplitMix64(0x5eed_0f7e57));
        let (mut fired, mut passed, mut blocking, mut rejected_by_a_plane) = (0, 0, 0, 0);
        let mut clear_misses = 0;
        for case in 0..60_000 {
            let radius = 10f32.powf(rng.range(-2.0, 1.0));
            // Odd cases: a cone from 3 to 20 radii away aimed 1.3 to 2.5
            // radii off the centre (square to the way to x), through a
            // triangle facing x, 3e-3 to 2e-2 of its distance across, near
            // the camera's origin; even ones: a light up to 50 units away,
            // x 0.3 to 300 radii from it, the cone aimed anywhere near the
            // light through any triangle 1e-5 to 0.5 of its distance
            // across, every fourth a sliver.
            let far_off = case % 2 == 1;
            let to_x = rng.dir();
            let (origin, x, tri, size);
            if far_off {
                origin = rng.dir() * radius * rng.range(0.0, 5.0);
                x = origin + to_x * radius * 10f32.powf(rng.range(0.5, 1.3));
                let side = rng.dir().cross(to_x).normalize_or(Vec3::Y);
                let aim = origin + side * radius * rng.range(1.3, 2.5);
                let centre = x + (aim - x) * rng.range(0.3, 0.95);
                size = (centre - x).length() * 10f32.powf(rng.range(-2.5, -1.7));
                let axis = (centre - x).normalize();
                let e1 = axis.any_orthonormal_vector();
                let e2 = axis.cross(e1);
                let turn = rng.range(0.0, 6.3);
                tri = [0.0f32, 2.1, 4.2].map(|t| {
                    let t = t + turn + rng.range(-0.3, 0.3);
                    centre + (e1 * t.cos() + e2 * t.sin()) * size * 0.5
                });
            } else {
                origin = rng.dir() * rng.range(0.0, 50.0);
                x = origin + to_x * radius * 10f32.powf(rng.range(-0.5, 2.5));
                let aim = origin + rng.dir() * radius * rng.range(0.0, 2.5);
                let centre = x + (aim - x) * rng.range(0.05, 0.95);
                size = (centre - x).length() * 10f32.powf(rng.range(-5.0, -0.3));
                let mut t = [0; 3].map(|_| centre + rng.dir() * size);
                if case % 4 == 0 {
                    // A sliver: the third vertex next to the first edge.
                    t[2] = t[0].lerp(t[1], rng.unit()) + rng.dir() * size * 1e-4;
                }
                tri = t;
            }
            let [a, b, c] = tri;
            let n = (b - a).cross(c - a);
            let sx = n.dot(x - a);
            if sx == 0.0 || sx.is_nan() {
                continue;
            }
            let inv_r = 1.0 / radius;
            let lo = |v: Vec3| -1.0 - 1e-5 * (1.0 + v.length() * inv_r);
            let d0 = (n * (sx.signum() / n.length())).dot(a - origin) * inv_r;
            let planes = edge_planes(x, tri, origin, radius);
            // NaN rejects too, as in blocked_bits.
            let passes = |d: f32, lo: f32| d.partial_cmp(&lo) == Some(std::cmp::Ordering::Greater);
            if !passes(d0, lo(a - origin))
                || planes.iter().any(|&(_, d)| !passes(d, lo(x - origin)))
            {
                rejected_by_a_plane += 1;
                continue;
            }
            passed += 1;
            // Light samples in the sphere, and on it (just inside) where it
            // comes nearest the line of each cone edge and of the cone's
            // axis.
            let centroid = (a + b + c) / 3.0;
            let mut samples: Vec<Vec3> = (0..200)
                .map(|_| origin + rng.dir() * radius * rng.unit().cbrt())
                .collect();
            for v in [a, b, c, centroid] {
                let e = (v - x).normalize_or(Vec3::X);
                let q = x + e * (origin - x).dot(e);
                let towards = (q - origin).normalize_or(Vec3::Y);
                for f in [1.0 - 1e-6, 0.999, 0.99] {
                    samples.push(origin + towards * radius * f);
                }
            }
            let bits = blocked_bits(
                x,
                tri,
                false,
                origin,
                radius,
                samples.len(),
                &PlaneBits::Exact { samples: &samples },
                None,
            )
            // (None: beyond the reach rule, blocking nothing.)
            .unwrap_or_default();
            let blocks_any = bits.iter().flatten().any(|&w| w != 0);
            blocking += blocks_any as u32;
            // Whether the cone from x clearly passes the light: its axis
            // (ahead of x) more than 1.2 radii off the centre past the
            // cone's own half-width there. Not asked of flat cones, from
            // slivers or seen edge-on (two of their planes are nearly
            // opposite, which multiplies the rounding margin by the
            // weights that combine them; asked where every dihedral angle
            // is above 37 degrees: u_i.u_j = -cos(angle) > -0.8), nor of
            // triangles too small for f32 to place their planes (the
            // planes, the exact test's too, turn by the vertices'
            // rounding, which moves them at the light by about distance /
            // size ulps of the coordinates).
            let axis = (centroid - x).normalize();
            let to_light = origin - x;
            let along = to_light.dot(axis);
            let off = (to_light - axis * along).length() / radius;
            let half_width = 2.0 * size / (centroid - x).length() * to_light.length() / radius;
            let open = (0..3).all(|i| planes[i].0.dot(planes[(i + 1) % 3].0) > -0.8);
            let scale = [x, a, b, c]
                .map(|v| v.abs().max_element())
                .into_iter()
                .fold(0.0, f32::max);
            let resolved = size > 1e-4 * scale * to_light.length() / radius;
            let clear = open && resolved && along > 0.0 && off - half_width > 1.2;
            clear_misses += clear as u32;
            if wedges_miss_light(&planes, wedge_margin(x, origin, radius)) {
                fired += 1;
                assert!(
                    !blocks_any,
                    "case {case}: the rule skipped a caster that blocks {bits:?} (x {x}, triangle {tri:?}, light {origin} r {radius})"
                );
            } else {
                assert!(
                    !clear,
                    "case {case}: a cone that clearly passes the light was kept (x {x}, triangle {tri:?}, light {origin} r {radius})"
                );
            }
        }
        eprintln!(
            "{passed} pairs past the plane tests ({rejected_by_a_plane} rejected by one), {fired} skipped by the wedge rule ({clear_misses} clear misses), {blocking} blocking"
        );
        // The cases hold casters that block and clear misses that the
        // plane tests let through (each of which the rule skipped).
        assert!(
            blocking > 1000 && clear_misses > 1000,
            "{blocking} {clear_misses}"
        );
    }

    #[test]
    fn exact_bits_block_what_the_triangle_hides() {
        // A big triangle at z = 1 between x at the origin and light samples
        // at z = 2 (inside its shadow) and z = 0.5 (in front of it).
        let tri = [
            Vec3::new(-10.0, -10.0, 1.0),
            Vec3::new(10.0, -10.0, 1.0),
            Vec3::new(0.0, 10.0, 1.0),
        ];
        let samples = vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.0, 0.0, 0.5)];
        let (o, r) = (Vec3::new(0.0, 0.0, 1.25), 0.8);
        let exact = blocked_bits(
            Vec3::ZERO,
            tri,
            false,
            o,
            r,
            2,
            &PlaneBits::Exact { samples: &samples },
            None,
        )
        .unwrap();
        assert_eq!(exact, vec![[1, 0, 0, 0]]);
        let ys = normalized_samples(&samples, o, r);
        let lut = build_lut(&ys, 64);
        let looked_up = blocked_bits(
            Vec3::ZERO,
            tri,
            false,
            o,
            r,
            2,
            &PlaneBits::Lut { lut: &lut, res: 64 },
            None,
        )
        .unwrap();
        assert_eq!(looked_up, exact);
    }
}
