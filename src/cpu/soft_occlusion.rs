//! CPU twin of soft-shadow occlusion (`soft_occlusion.comp`, paper §4.2):
//! the light samples one triangle hides from one view sample, in look-up
//! and exact modes.

use glam::Vec3;

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
/// plane, or behind a closed triangle). The same arithmetic as
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
    let m = [
        (a - x).cross(b - x),
        (b - x).cross(c - x),
        (c - x).cross(a - x),
    ];
    let se = if m[0].dot(c - x) < 0.0 { -1.0 } else { 1.0 };
    let mut planes = vec![(ns, d0)];
    for mi in m {
        let u = mi * (-se / mi.dot(mi).sqrt());
        let d = u.dot(ox) * inv_r;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::plane_lut::{build_lut, normalized_samples};

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
