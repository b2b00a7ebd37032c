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

#[cfg(test)]
mod tests {
    use super::*;

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
