//! Shading: turns view samples and per-light visibility into a picture.
//! Deliberately simple (grey Lambert plus ambient): the engine's product is
//! the visibility, and the picture is there to be looked at.

use glam::DVec3;

use crate::light::{Light, LightShape};
use crate::oracle::ViewSamples;

/// Ambient term so that fully shadowed surfaces are still readable.
const AMBIENT: f64 = 0.12;
const ALBEDO: f64 = 0.8;

fn to_srgb8(linear: f64) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Shades every pixel: `visibility[k][pixel]` is light `k`'s visible fraction.
pub fn shade(view: &ViewSamples, lights: &[Light], visibility: &[Vec<f32>]) -> image::RgbImage {
    let (w, h) = (view.width, view.height);
    let mut img = image::RgbImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let rgb = match &view.samples[i] {
                None => {
                    // A plain vertical gradient for the background.
                    let t = y as f64 / h.max(1) as f64;
                    let c = 0.35 + 0.25 * (1.0 - t);
                    [c * 0.8, c * 0.9, c]
                }
                Some(s) => {
                    let mut c = [AMBIENT * ALBEDO; 3];
                    for (k, light) in lights.iter().enumerate() {
                        let to_light = match &light.shape {
                            LightShape::Directional { direction } => -*direction,
                            _ => light.center().unwrap_or(s.position) - s.position,
                        };
                        let l = to_light.normalize_or_zero();
                        let ndotl = s.normal.dot(l).max(0.0);
                        let v = visibility
                            .get(k)
                            .and_then(|v| v.get(i))
                            .copied()
                            .unwrap_or(0.0) as f64;
                        for (ch, lc) in c.iter_mut().zip(light.color) {
                            *ch += ALBEDO * ndotl * v * lc as f64 * light.intensity as f64;
                        }
                    }
                    c
                }
            };
            img.put_pixel(x, y, image::Rgb(rgb.map(to_srgb8)));
        }
    }
    img
}

/// Whether any of the light's sample points lies strictly in front of the
/// surface at `position` with normal `normal`; a sample facing away from
/// the whole light is unlit without any shadow test.
pub fn faces_light(position: DVec3, normal: DVec3, samples: &crate::light::LightSamples) -> bool {
    match samples {
        crate::light::LightSamples::Direction(d) => normal.dot(-*d) > 0.0,
        crate::light::LightSamples::Positions(p) => {
            p.iter().any(|s| normal.dot(*s - position) > 0.0)
        }
    }
}
