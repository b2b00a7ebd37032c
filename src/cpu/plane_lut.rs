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

/// Per octahedral cell (index j · res + i) of a `res`³ table, an upper
/// bound of the distance between any unit normal in the cell (as
/// [`lut_index`] assigns it) and the cell's centre normal: for a plane
/// (u, d) looked up at its cell's centre plane (n_t, d_t),
/// |n_t·y − u·y| ≤ this for every light sample (|y| ≤ 1).
///
/// The decode maps each cell onto its spherical patch one to one, so the
/// point of the patch farthest from the centre normal is the image of a
/// point of the cell's boundary: the boundary is sampled (64 points per
/// side, in f64) and the decode's Lipschitz bound (4.5 per unit of
/// octahedral coordinates) covers what lies between two samples, plus
/// 1e-6 for the f32 rounding of the centre normal and of the encode. The
/// octahedral map's mirror symmetries in x and y leave one quadrant of the
/// cells to compute. Cached per resolution.
pub fn cell_radii(res: u32) -> std::sync::Arc<Vec<f32>> {
    use std::sync::{Arc, Mutex};
    static CACHE: Mutex<Vec<(u32, Arc<Vec<f32>>)>> = Mutex::new(Vec::new());
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, r)) = cache.iter().find(|(r, _)| *r == res) {
        return Arc::clone(r);
    }
    const STEPS: usize = 64;
    let step = 2.0 / res as f64;
    let decode = |x: f64, y: f64| {
        let mut n = glam::DVec3::new(x, y, 1.0 - x.abs() - y.abs());
        if n.z < 0.0 {
            let (a, b) = (n.x, n.y);
            n.x = (1.0 - b.abs()) * if a >= 0.0 { 1.0 } else { -1.0 };
            n.y = (1.0 - a.abs()) * if b >= 0.0 { 1.0 } else { -1.0 };
        }
        n.normalize()
    };
    let slack = 4.5 * step / STEPS as f64 / 2.0 + 1e-6;
    let radius = |i: u32, j: u32| {
        let (n, _) = lut_texel_plane(i, j, 0, res);
        let centre = n.as_dvec3();
        let (x0, y0) = (-1.0 + i as f64 * step, -1.0 + j as f64 * step);
        let mut worst = 0.0f64;
        for k in 0..=STEPS {
            let t = k as f64 / STEPS as f64 * step;
            for (x, y) in [
                (x0 + t, y0),
                (x0 + t, y0 + step),
                (x0, y0 + t),
                (x0 + step, y0 + t),
            ] {
                worst = worst.max(decode(x, y).distance(centre));
            }
        }
        (worst + slack) as f32
    };
    // Cell i mirrors to res − 1 − i; the quadrant i, j ≥ res / 2 − 1
    // (overlapping the axes for odd res) holds one of each pair.
    let first = (res / 2).saturating_sub(1);
    let mut quadrant = vec![0.0f32; (res * res) as usize];
    for j in first..res {
        for i in first..res {
            quadrant[(j * res + i) as usize] = radius(i, j);
        }
    }
    let mirror = |v: u32| if v < first { res - 1 - v } else { v };
    let out: Vec<f32> = (0..res * res)
        .map(|c| {
            let (i, j) = (c % res, c / res);
            let r = quadrant[(mirror(j) * res + mirror(i)) as usize];
            // Mirrored cells of odd resolutions differ by rounding only:
            // never below the computed one's.
            if mirror(i) == i && mirror(j) == j {
                r
            } else {
                r + 1e-6
            }
        })
        .collect();
    let out = Arc::new(out);
    cache.push((res, Arc::clone(&out)));
    out
}

/// The largest of [`cell_radii`].
pub fn normal_radius(res: u32) -> f32 {
    cell_radii(res).iter().copied().fold(0.0, f32::max)
}

/// The look-up mode's allowance for the rounding of the exact per-sample
/// test, in light radii: a pair whose rounding bound (64 f32 ulps of the
/// magnitudes involved, per light radius) passes it has all its bits tested
/// exactly instead (`soft_occlusion.comp`, `rounding_too_large`).
pub const LUT_ROUNDING: f32 = 1e-3;

/// The margin of the look-up mode's table at normal cell `cell`: the
/// cell's radius ([`cell_radii`]), half a cell of d, 2e-6 for the f32
/// comparisons of the build, plus [`LUT_ROUNDING`].
pub fn bounds_margin(res: u32, cell: usize) -> f32 {
    cell_radii(res)[cell] + 1.0 / res as f32 + 2e-6 + LUT_ROUNDING
}

/// The d of the centre of cell `k` of `res`, in f32 as
/// [`lut_texel_plane`] computes it.
fn cell_centre(k: u32, res: u32) -> f32 {
    let step = 2.0 / res as f32;
    -1.0 + (k as f32 + 0.5) * step
}

/// The look-up mode's table: per texel (index as [`lut_index`]), then per
/// 128-sample block, two masks: `[every, some]` at `2 · (texel · blocks +
/// block)`: the normalized samples y with n_t·y < d_t − w ("every") and
/// with n_t·y < d_t + w ("some"), (n_t, d_t) the texel's centre plane and
/// w = [`bounds_margin`] of its normal cell (all in f32). For a plane (u, d) in the texel's
/// cell, "every" holds samples certainly behind it and samples outside
/// "some" are certainly not (`soft_occlusion.comp`, SURE_BLOCK).
///
/// The masks grow with d, so each (normal cell, sample) has a first d cell
/// per mask (from the f32 comparison, found in a step or two): samples go
/// into buckets by it, and a running OR over d gives the masks, O(cells ·
/// samples + texels) rather than O(texels · samples). Rows of normal cells
/// (fixed j) run in parallel, each writing its texels, which are runs over
/// i at each d, in order.
pub fn build_bounds_lut(normalized: &[Vec3], res: u32) -> Vec<BlockBits> {
    let texels = (res as usize).pow(3) * blocks(normalized.len()) * 2;
    let mut lut = vec![[0u32; 4]; texels];
    build_bounds_lut_into(normalized, res, &mut lut);
    lut
}

/// [`build_bounds_lut`] into `lut` (the GPU buffer's mapped memory, or a
/// host vector), which must hold exactly its texels: every one is written,
/// so `lut` need not start zeroed.
pub fn build_bounds_lut_into(normalized: &[Vec3], res: u32, lut: &mut [BlockBits]) {
    use rayon::prelude::*;
    let nb = blocks(normalized.len());
    let r = res as usize;
    let step = 2.0 / res as f32;
    // The first cell k in 0..=res with t < centre(k) + shift (res: none):
    // the real-valued solution, then the f32 comparison itself decides.
    let first = |t: f32, shift: f32| -> usize {
        let below = |k: u32| t < cell_centre(k, res) + shift;
        let guess = ((t - shift + 1.0) / step - 0.5)
            .floor()
            .clamp(0.0, res as f32) as u32;
        let mut k = guess;
        while k > 0 && below(k - 1) {
            k -= 1;
        }
        while k < res && !below(k) {
            k += 1;
        }
        k as usize
    };
    assert_eq!(lut.len(), r * r * r * nb * 2, "the table's size");
    struct Out(*mut BlockBits);
    unsafe impl Sync for Out {}
    let out = Out(lut.as_mut_ptr());
    let out = &out;
    (0..res).into_par_iter().for_each(|j| {
        // buckets[((i · (res + 1) + k) · nb + block) · 2 + mask]
        let mut buckets = vec![[0u32; 4]; r * (r + 1) * nb * 2];
        for i in 0..res {
            let (n, _) = lut_texel_plane(i, j, 0, res);
            let w = bounds_margin(res, (j * res + i) as usize);
            for (s, y) in normalized.iter().enumerate() {
                let t = n.dot(*y);
                let (b, word, bit) = (s / 128, (s % 128) / 32, 1u32 << (s % 32));
                let at = |k: usize, m: usize| ((i as usize * (r + 1) + k) * nb + b) * 2 + m;
                buckets[at(first(t, -w), 0)][word] |= bit;
                buckets[at(first(t, w), 1)][word] |= bit;
            }
        }
        let mut acc = vec![[0u32; 4]; r * nb * 2];
        for k in 0..r {
            for i in 0..r {
                for bm in 0..nb * 2 {
                    let src = buckets[(i * (r + 1) + k) * nb * 2 + bm];
                    let a = &mut acc[i * nb * 2 + bm];
                    for word in 0..4 {
                        a[word] |= src[word];
                    }
                }
            }
            // Texels (k, j, 0..res): one run. Rows never overlap.
            let texel = (k * r + j as usize) * r;
            unsafe {
                std::ptr::copy_nonoverlapping(acc.as_ptr(), out.0.add(2 * texel * nb), r * nb * 2);
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_table_is_its_definition_and_brackets_every_plane() {
        let ys: Vec<Vec3> = (0..200)
            .map(|k| {
                let t = k as f32;
                Vec3::new((t * 0.37).sin(), (t * 0.91).cos(), (t * 0.13).sin()) * 0.55
            })
            .collect();
        let res = 12;
        let nb = 2;
        let lut = build_bounds_lut(&ys, res);
        assert_eq!(lut.len(), 12 * 12 * 12 * nb * 2);
        // Every bit is the f32 comparison that defines it.
        for texel in 0..(res * res * res) as usize {
            let t = texel as u32;
            let (n, d) = lut_texel_plane(t % res, (t / res) % res, t / (res * res), res);
            let w = bounds_margin(res, (t % (res * res)) as usize);
            for (s, y) in ys.iter().enumerate() {
                let at =
                    |m: usize| lut[2 * (texel * nb + s / 128) + m][(s % 128) / 32] >> (s % 32) & 1;
                assert_eq!(
                    at(0) == 1,
                    n.dot(*y) < d - w,
                    "texel {texel}, sample {s}: every"
                );
                assert_eq!(
                    at(1) == 1,
                    n.dot(*y) < d + w,
                    "texel {texel}, sample {s}: some"
                );
            }
        }
        // For planes anywhere in a cell, "every" is behind and outside
        // "some" is not, by more than the rounding allowance.
        let mut checked = 0;
        for k in 0..3000 {
            let t = k as f32 * 0.754_877;
            let u = Vec3::new((t * 2.3).sin(), (t * 1.1).cos(), (t * 0.71).sin() - 0.1).normalize();
            let d = (t * 0.37).sin() * 0.99;
            let texel = lut_index(u, d, res) as usize;
            for (s, y) in ys.iter().enumerate() {
                let at =
                    |m: usize| lut[2 * (texel * nb + s / 128) + m][(s % 128) / 32] >> (s % 32) & 1;
                let v = u.dot(*y) - d;
                if at(0) == 1 {
                    assert!(
                        v < -LUT_ROUNDING,
                        "plane {u} {d}, sample {s}: every, u.y - d = {v}"
                    );
                }
                if at(1) == 0 {
                    assert!(
                        v >= LUT_ROUNDING,
                        "plane {u} {d}, sample {s}: not some, u.y - d = {v}"
                    );
                }
                checked += 1;
            }
        }
        assert_eq!(checked, 3000 * 200);
    }

    #[test]
    fn normal_radius_bounds_every_cell() {
        // Random unit normals: each lies within the bound of its cell's
        // centre normal, and the bound is not wildly loose.
        for res in [8, 31, 128] {
            let r = normal_radius(res);
            let mut seen = 0.0f32;
            for k in 0..20000 {
                let t = k as f32 * 0.618_034;
                let n =
                    Vec3::new((t * 3.1).sin(), (t * 1.7).cos(), (t * 0.37).sin() - 0.3).normalize();
                let idx = lut_index(n, 0.0, res);
                let (c, _) = lut_texel_plane(idx % res, (idx / res) % res, 0, res);
                let d = n.distance(c);
                assert!(
                    d <= r,
                    "res {res}: {n} is {d} from its cell's centre, bound {r}"
                );
                seen = seen.max(d);
            }
            assert!(r < 1.5 * seen + 0.01, "res {res}: bound {r}, seen {seen}");
        }
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
