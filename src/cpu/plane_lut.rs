//! CPU twin of the plane look-up texture (`plane_lut_build.comp`, the
//! look-up arithmetic of `soft_common.glsl`, paper §4.2).
//!
//! A plane is (n, d) in the light's normalized frame y = (l − origin) / R,
//! where (origin, R) bound the samples ([`crate::gpu::SoftLight::bounds`]);
//! a light sample is *behind* the plane when n·y < d. LUT texel (i, j, k)
//! holds the plane whose normal has octahedral coordinates at the centre of
//! cell (i, j) of [−1, 1]² and whose d is the centre of cell k of [−1, 1];
//! its value is one `[u32; 4]` per 128-sample block, the blocks of a texel
//! side by side.

use glam::{Vec2, Vec3};

/// Bits of one 128-sample block.
pub type BlockBits = [u32; 4];

/// The light samples in the light's normalized frame: (s − centre) / radius,
/// rounded from f64 (what `plane_lut_build` reads).
pub fn normalized_samples(samples: &[Vec3], centre: Vec3, radius: f32) -> Vec<Vec3> {
    let c = centre.as_dvec3();
    let r = radius as f64;
    samples
        .iter()
        .map(|s| ((s.as_dvec3() - c) / r).as_vec3())
        .collect()
}

fn sign_not_zero(v: f32) -> f32 {
    if v >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

/// Unit vector → octahedral coordinates in [−1, 1]².
pub fn oct_encode(n: Vec3) -> Vec2 {
    let p = n / (n.x.abs() + n.y.abs() + n.z.abs());
    if p.z < 0.0 {
        Vec2::new(
            (1.0 - p.y.abs()) * sign_not_zero(p.x),
            (1.0 - p.x.abs()) * sign_not_zero(p.y),
        )
    } else {
        Vec2::new(p.x, p.y)
    }
}

/// Octahedral coordinates → unit vector.
pub fn oct_decode(e: Vec2) -> Vec3 {
    let mut n = Vec3::new(e.x, e.y, 1.0 - e.x.abs() - e.y.abs());
    if n.z < 0.0 {
        let (x, y) = (n.x, n.y);
        n.x = (1.0 - y.abs()) * sign_not_zero(x);
        n.y = (1.0 - x.abs()) * sign_not_zero(y);
    }
    n.normalize()
}

/// The plane (n, d) at the centre of texel (i, j, k) of a res³ table.
pub fn lut_texel_plane(i: u32, j: u32, k: u32, res: u32) -> (Vec3, f32) {
    let step = 2.0 / res as f32;
    let c = |v: u32| -1.0 + (v as f32 + 0.5) * step;
    (oct_decode(Vec2::new(c(i), c(j))), c(k))
}

/// The texel (linear, without the block) nearest to plane (n, d), n unit.
pub fn lut_index(n: Vec3, d: f32, res: u32) -> u32 {
    let r = res as f32;
    let e = oct_encode(n);
    let cell = |v: f32| ((v + 1.0) * (0.5 * r)).floor().clamp(0.0, r - 1.0) as u32;
    (cell(d) * res + cell(e.y)) * res + cell(e.x)
}

/// Number of 128-sample blocks for `samples` light samples.
pub fn blocks(samples: usize) -> usize {
    samples.div_ceil(128)
}

/// The plane look-up texture: for each texel, then each block, the bits of
/// the normalized samples behind the texel's plane.
pub fn build_lut(normalized: &[Vec3], res: u32) -> Vec<BlockBits> {
    let nb = blocks(normalized.len());
    let mut lut = vec![[0u32; 4]; (res as usize).pow(3) * nb];
    for k in 0..res {
        for j in 0..res {
            for i in 0..res {
                let (n, d) = lut_texel_plane(i, j, k, res);
                let t = ((k * res + j) * res + i) as usize;
                for (s, y) in normalized.iter().enumerate() {
                    if n.dot(*y) < d {
                        lut[t * nb + s / 128][(s % 128) / 32] |= 1 << (s % 32);
                    }
                }
            }
        }
    }
    lut
}

/// The largest rounding allowance the look-up mode uses, in light radii.
/// Each pair's allowance is its own rounding bound (64 f32 ulps of the
/// magnitudes of the per-sample test, per light radius: larger for a light
/// that is small for its distance); a pair past this one (or whose bound is
/// not a number) has all its bits tested exactly instead
/// (`soft_occlusion.comp`, `rounding_too_large`).
pub const LUT_ALLOWANCE_CAP: f32 = 1.0;

/// Slack of the look-up mode's table beyond the rounding allowance, in light
/// radii: the f32 rounding of the build's comparisons and planes (~1e-7),
/// of the shader's choice of a plane (its floor and ceil, ~1e-6), and the
/// difference between the host's and a device's decode of a cell's centre
/// normal (a few f32 ulps of a unit vector), with room to spare.
pub const SURE_SLACK: f32 = 3e-5;

/// The d of the look-up mode table's plane `k` (0..res) in each normal
/// cell: −1 + k · 2 / res, in f32 as the build compares with it.
pub fn sure_plane_d(k: u32, res: u32) -> f32 {
    -1.0 + k as f32 * (2.0 / res as f32)
}

/// The centre normal of octahedral cell `cell` (j · res + i).
pub fn cell_normal(cell: u32, res: u32) -> Vec3 {
    lut_texel_plane(cell % res, cell / res, 0, res).0
}

/// The look-up mode's table: per normal cell (j · res + i), per plane k
/// (d = [`sure_plane_d`]), per 128-sample block, the normalized samples y
/// with n_t·y < d (in f32; n_t the cell's centre normal), at index
/// `(cell · res + k) · blocks + block`. Planes of one cell lie side by
/// side, so that the two a caster's plane reads (below and above it,
/// [`sure_texels`]) are a few texels apart.
///
/// The masks grow with k, so each (normal cell, sample) has a first plane
/// (from the f32 comparison, found in a step or two): samples go into
/// buckets by it, and a running OR over k gives the masks, O(cells ·
/// samples + texels) rather than O(texels · samples). Rows of normal cells
/// (fixed j) run in parallel, each writing its own texels.
pub fn build_sure_lut(normalized: &[Vec3], res: u32) -> Vec<BlockBits> {
    let texels = (res as usize).pow(3) * blocks(normalized.len());
    let mut lut = vec![[0u32; 4]; texels];
    build_sure_lut_into(normalized, res, &mut lut);
    lut
}

/// [`build_sure_lut`] into `lut` (the GPU buffer's mapped memory, or a
/// host vector), which must hold exactly its texels: every one is written,
/// so `lut` need not start zeroed.
pub fn build_sure_lut_into(normalized: &[Vec3], res: u32, lut: &mut [BlockBits]) {
    use rayon::prelude::*;
    let nb = blocks(normalized.len());
    let r = res as usize;
    let step = 2.0 / res as f32;
    // The first plane k in 0..=res with t < d_k (res: none): the
    // real-valued solution, then the f32 comparison itself decides.
    let first = |t: f32| -> usize {
        let below = |k: u32| t < sure_plane_d(k, res);
        let mut k = ((t + 1.0) / step).floor().clamp(0.0, res as f32) as u32;
        while k > 0 && below(k - 1) {
            k -= 1;
        }
        while k < res && !below(k) {
            k += 1;
        }
        k as usize
    };
    assert_eq!(lut.len(), r * r * r * nb, "the table's size");
    lut.par_chunks_mut(r * r * nb)
        .enumerate()
        .for_each(|(j, row)| {
            // buckets[k · nb + block] for one cell at a time.
            let mut buckets = vec![[0u32; 4]; (r + 1) * nb];
            let mut acc = vec![[0u32; 4]; nb];
            for i in 0..r {
                buckets.fill([0; 4]);
                acc.fill([0; 4]);
                let n = cell_normal((j * r + i) as u32, res);
                for (s, y) in normalized.iter().enumerate() {
                    let (b, word, bit) = (s / 128, (s % 128) / 32, 1u32 << (s % 32));
                    buckets[first(n.dot(*y)) * nb + b][word] |= bit;
                }
                let cell = &mut row[i * r * nb..(i + 1) * r * nb];
                for k in 0..r {
                    for b in 0..nb {
                        for word in 0..4 {
                            acc[b][word] |= buckets[k * nb + b][word];
                        }
                        cell[k * nb + b] = acc[b];
                    }
                }
            }
        });
}

/// What the look-up mode reads for a caster's plane (u, d) (|u| ≈ 1, in
/// the light's normalized frame): the table's plane `every` at or below
/// d − δ and `some` at or above d + δ in u's normal cell, as texel indices
/// (without the block), where δ bounds |(u − n_t)·y| for |y| ≤ 1 plus
/// the rounding `allowance` and [`SURE_SLACK`]. So the samples of `every`
/// are behind (u, d) by more than the allowance and those outside
/// `some` are in front by as much; `flags` say where no plane of the
/// table does: SURE_ALL (every sample behind), SURE_NONE (none certainly
/// behind), MAYBE_ALL (every sample possibly behind). Twin of
/// `sure_texels` in `shaders/soft_occlusion.comp`.
pub fn sure_texels(u: Vec3, d: f32, res: u32, allowance: f32) -> SureTexels {
    let cell = lut_index(u, -1.0, res); // k = 0: the normal's cell
    let delta = (u - cell_normal(cell, res)).length() * (1.0 + 1e-5) + allowance + SURE_SLACK;
    let (lo, hi) = (d - delta, d + delta);
    let half = 0.5 * res as f32;
    let ke = ((lo + 1.0) * half).floor();
    let ks = ((hi + 1.0) * half).ceil();
    let last = res as f32 - 1.0;
    let texel = |k: f32| cell * res + k.clamp(0.0, last) as u32;
    SureTexels {
        every: texel(ke),
        some: texel(ks),
        sure_all: lo >= 1.0 + 1e-6,
        sure_none: ke < 0.0,
        maybe_all: ks >= res as f32,
    }
}

/// [`sure_texels`]' answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SureTexels {
    /// The texel of the plane at or below d − δ.
    pub every: u32,
    /// The texel of the plane at or above d + δ.
    pub some: u32,
    /// d − δ is past every sample: all of them are behind.
    pub sure_all: bool,
    /// d − δ is below the table's first plane: none certainly behind.
    pub sure_none: bool,
    /// d + δ is past the table's last plane: all possibly behind.
    pub maybe_all: bool,
}

impl SureTexels {
    /// Block `block`'s bits certainly behind the plane and possibly behind
    /// it, from `lut` ([`build_sure_lut`], `nb` blocks).
    pub fn bounds(&self, lut: &[BlockBits], nb: usize, block: usize) -> (BlockBits, BlockBits) {
        let sure = if self.sure_all {
            [u32::MAX; 4]
        } else if self.sure_none {
            [0; 4]
        } else {
            lut[self.every as usize * nb + block]
        };
        let maybe = if self.maybe_all {
            [u32::MAX; 4]
        } else {
            lut[self.some as usize * nb + block]
        };
        (sure, maybe)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sure_table_is_its_definition_and_brackets_every_plane() {
        let ys: Vec<Vec3> = (0..200)
            .map(|k| {
                let t = k as f32;
                Vec3::new((t * 0.37).sin(), (t * 0.91).cos(), (t * 0.13).sin()) * 0.55
            })
            .collect();
        let res = 12;
        let nb = 2;
        let lut = build_sure_lut(&ys, res);
        assert_eq!(lut.len(), 12 * 12 * 12 * nb);
        // Every bit is the f32 comparison that defines it.
        for cell in 0..res * res {
            let n = cell_normal(cell, res);
            for k in 0..res {
                let texel = (cell * res + k) as usize;
                for (s, y) in ys.iter().enumerate() {
                    let bit = lut[texel * nb + s / 128][(s % 128) / 32] >> (s % 32) & 1;
                    assert_eq!(
                        bit == 1,
                        n.dot(*y) < sure_plane_d(k, res),
                        "cell {cell}, plane {k}, sample {s}"
                    );
                }
            }
        }
        // For planes anywhere, "every" is behind and outside "some" is
        // not, by more than the rounding allowance (none, a common pair's,
        // the old fixed one, a small light's); each flag occurs.
        let (mut checked, mut flags) = (0, [0; 3]);
        for k in 0..6000 {
            let t = k as f32 * 0.754_877;
            let u = Vec3::new((t * 2.3).sin(), (t * 1.1).cos(), (t * 0.71).sin() - 0.1).normalize();
            let d = (t * 0.37).sin() * 1.08;
            let allowance = [0.0, 3e-4, 1e-3, 2e-2][k % 4];
            let st = sure_texels(u, d, res, allowance);
            flags[0] += st.sure_all as usize;
            flags[1] += st.sure_none as usize;
            flags[2] += st.maybe_all as usize;
            for (s, y) in ys.iter().enumerate() {
                let (sure, maybe) = st.bounds(&lut, nb, s / 128);
                let at = |m: BlockBits| m[(s % 128) / 32] >> (s % 32) & 1;
                let v = u.dot(*y) - d;
                if at(sure) == 1 {
                    assert!(
                        v < -allowance,
                        "plane {u} {d}, sample {s}: every, u.y - d = {v}"
                    );
                }
                if at(maybe) == 0 {
                    assert!(
                        v >= allowance,
                        "plane {u} {d}, sample {s}: not some, u.y - d = {v}"
                    );
                }
                assert_eq!(at(sure) & !at(maybe) & 1, 0, "every within some");
                checked += 1;
            }
        }
        assert_eq!(checked, 6000 * 200);
        assert!(flags.iter().all(|&f| f > 0), "flags seen: {flags:?}");
    }

    #[test]
    fn sure_table_brackets_planes_near_its_own() {
        // Planes at a table plane's d and within rounding of it, with
        // normals at and near cell centres: the cases where floor and ceil
        // and the comparisons are closest to their edges.
        let ys: Vec<Vec3> = (0..256)
            .map(|k| {
                let t = k as f32 * 1.618;
                Vec3::new(t.sin(), (t * 0.77).cos(), (t * 0.29).sin()).normalize_or_zero()
                    * (0.2 + 0.8 * ((t * 3.3).sin() * 0.5 + 0.5))
            })
            .collect();
        let res = 16;
        let lut = build_sure_lut(&ys, res);
        let mut checked = 0;
        for cell in (0..res * res).step_by(7) {
            let n = cell_normal(cell, res);
            for nudge in [
                Vec3::ZERO,
                Vec3::new(1e-3, -2e-3, 5e-4),
                Vec3::new(-0.03, 0.02, 0.01),
            ] {
                let u = (n + nudge).normalize();
                for k in 0..=res {
                    for (e, allowance) in [-1e-3f32, -3e-5, -1e-7, 0.0, 1e-7, 3e-5, 1e-3]
                        .into_iter()
                        .flat_map(|e| [(e, 0.0), (e, 1e-3)])
                    {
                        let d = sure_plane_d(k, res) + e;
                        let st = sure_texels(u, d, res, allowance);
                        for (s, y) in ys.iter().enumerate() {
                            let (sure, maybe) = st.bounds(&lut, 2, s / 128);
                            let at = |m: BlockBits| m[(s % 128) / 32] >> (s % 32) & 1;
                            let v = u.dot(*y) - d;
                            assert!(at(sure) == 0 || v < -allowance, "every: {v}");
                            assert!(at(maybe) == 1 || v >= allowance, "some: {v}");
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 100_000);
    }

    #[test]
    fn octahedral_round_trip_and_index() {
        for k in 0..200 {
            let t = k as f32 * 0.731;
            let n =
                Vec3::new(t.cos() * (1.3 * t).sin(), t.sin(), (0.7 * t).cos() - 0.2).normalize();
            let back = oct_decode(oct_encode(n));
            assert!(back.distance(n) < 1e-5, "{n} -> {back}");
        }
        // A texel's own plane looks itself up.
        let res = 16;
        for t in [0u32, 5, 100, 1000, 4095] {
            let (i, j, k) = (t % res, (t / res) % res, t / (res * res));
            let (n, d) = lut_texel_plane(i, j, k, res);
            assert_eq!(lut_index(n, d, res), t);
        }
    }

    #[test]
    fn lut_bits_are_the_samples_behind_the_plane() {
        let ys: Vec<Vec3> = (0..200)
            .map(|k| {
                let t = k as f32;
                Vec3::new((t * 0.37).sin(), (t * 0.91).cos(), (t * 0.13).sin()) * 0.5
            })
            .collect();
        let res = 8;
        let lut = build_lut(&ys, res);
        assert_eq!(lut.len(), 512 * 2);
        let (n, d) = lut_texel_plane(3, 4, 5, res);
        let t = lut_index(n, d, res) as usize;
        for (s, y) in ys.iter().enumerate() {
            let bit = lut[t * 2 + s / 128][(s % 128) / 32] >> (s % 32) & 1;
            assert_eq!(bit == 1, n.dot(*y) < d);
        }
    }
}
