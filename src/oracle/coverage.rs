//! The oracle's own alpha test, in `f64`: whether a hit on an alpha-tested
//! triangle (glTF `MASK`, `BLEND` cast as `MASK` at 0.5) is opaque. It
//! follows the documented rules (`crate::cpu::alpha`: texture coordinates
//! from the hit's barycentrics, glTF's top-left origin, `NEAREST` or
//! `LINEAR` between texel centres, `REPEAT` / `CLAMP_TO_EDGE` /
//! `MIRRORED_REPEAT`, opaque where `factor × alpha ≥ cutoff`) but shares no
//! code with the GPU's twin: its interpolation and texel look-up are its
//! own, in double precision.

use glam::DVec2;

use crate::scene::{AlphaTest, MagFilter, Wrap};

/// An alpha-tested triangle as the oracle sees it.
#[derive(Clone, Debug)]
pub(crate) struct Coverage {
    pub test: std::sync::Arc<AlphaTest>,
    /// Texture coordinates of the corners.
    pub uvs: [DVec2; 3],
    /// The corners, origin-relative.
    pub vertices: [glam::DVec3; 3],
}

impl Coverage {
    /// The texture coordinates at barycentrics (`b1`, `b2`) of corners 1, 2.
    pub fn uv(&self, b1: f64, b2: f64) -> DVec2 {
        let [a, b, c] = self.uvs;
        a + (b - a) * b1 + (c - a) * b2
    }

    /// Whether the triangle is opaque at texture coordinates `uv`.
    pub fn opaque_at(&self, uv: DVec2) -> bool {
        let t = &self.test;
        let cutoff = t.cutoff as f64;
        let factor = t.factor as f64;
        let Some(img) = &t.image else {
            return factor >= cutoff;
        };
        let (w, h) = (img.width() as i64, img.height() as i64);
        let texel = |i: i64, j: i64| -> f64 {
            let x = wrapped(i, w, t.sampler.wrap_s);
            let y = wrapped(j, h, t.sampler.wrap_t);
            img.get_pixel(x as u32, y as u32).0[3] as f64 / 255.0
        };
        let limit = 16_777_216.0;
        let alpha = match t.sampler.mag_filter {
            MagFilter::Nearest => {
                let x = (uv.x * w as f64).clamp(-limit, limit).floor();
                let y = (uv.y * h as f64).clamp(-limit, limit).floor();
                texel(x as i64, y as i64)
            }
            MagFilter::Linear => {
                // Texel centres sit at half-integer coordinates.
                let x = (uv.x * w as f64 - 0.5).clamp(-limit, limit);
                let y = (uv.y * h as f64 - 0.5).clamp(-limit, limit);
                let (i, j) = (x.floor(), y.floor());
                let (fx, fy) = (x - i, y - j);
                let (i, j) = (i as i64, j as i64);
                let lerp = |a: f64, b: f64, f: f64| a + (b - a) * f;
                lerp(
                    lerp(texel(i, j), texel(i + 1, j), fx),
                    lerp(texel(i, j + 1), texel(i + 1, j + 1), fx),
                    fy,
                )
            }
        };
        factor * alpha >= cutoff
    }

    /// Whether the hit at barycentrics (`b1`, `b2`) is opaque.
    pub fn opaque(&self, b1: f64, b2: f64) -> bool {
        self.opaque_at(self.uv(b1, b2))
    }

    /// Barycentrics (`b1`, `b2`) of the point of the triangle's plane
    /// nearest to the origin-relative `p` (least squares).
    pub fn barycentrics(&self, p: glam::DVec3) -> (f64, f64) {
        let [a, b, c] = self.vertices;
        let (e1, e2, d) = (b - a, c - a, p - a);
        let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let (r1, r2) = (d.dot(e1), d.dot(e2));
        let den = d11 * d22 - d12 * d12;
        ((d22 * r1 - d12 * r2) / den, (d11 * r2 - d12 * r1) / den)
    }
}

/// Texel index `i` on a side of `n` texels, wrapped as glTF says.
fn wrapped(i: i64, n: i64, mode: Wrap) -> i64 {
    match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.max(0).min(n - 1),
        Wrap::MirroredRepeat => {
            // Even periods run forwards, odd ones backwards.
            let period = i.div_euclid(n);
            let k = i.rem_euclid(n);
            if period % 2 == 0 {
                k
            } else {
                n - 1 - k
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Sampler;
    use std::sync::Arc;

    fn coverage(alphas: &[u8], w: u32, sampler: Sampler) -> Coverage {
        let img =
            image::RgbaImage::from_fn(w, 1, |x, _| image::Rgba([0, 0, 0, alphas[x as usize]]));
        Coverage {
            test: Arc::new(AlphaTest {
                material: "t".into(),
                image: Some(Arc::new(img)),
                sampler,
                cutoff: 0.5,
                factor: 1.0,
            }),
            uvs: [DVec2::ZERO, DVec2::X, DVec2::Y],
            vertices: [glam::DVec3::ZERO, glam::DVec3::X, glam::DVec3::Y],
        }
    }

    #[test]
    fn mirrored_repeat_runs_back_and_forth() {
        let got: Vec<i64> = (-3..7)
            .map(|i| wrapped(i, 3, Wrap::MirroredRepeat))
            .collect();
        assert_eq!(got, [2, 1, 0, 0, 1, 2, 2, 1, 0, 0]);
    }

    #[test]
    fn nearest_and_linear_read_the_documented_texels() {
        let nearest = Sampler {
            mag_filter: MagFilter::Nearest,
            ..Sampler::default()
        };
        let c = coverage(&[255, 0, 255, 0], 4, nearest);
        assert!(c.opaque_at(DVec2::new(0.1, 0.5)));
        assert!(!c.opaque_at(DVec2::new(0.3, 0.5)));
        assert!(c.opaque_at(DVec2::new(-0.4, 0.5)), "repeat: texel 2");
        let l = coverage(&[255, 0, 255, 0], 4, Sampler::default());
        // Centres at 0.125 (255) and 0.375 (0): half way at 0.25.
        assert!(l.opaque_at(DVec2::new(0.24, 0.5)));
        assert!(!l.opaque_at(DVec2::new(0.26, 0.5)));
    }
}
