//! CPU twin of the light-view passes (`light_fit.comp`, `light_fit_finalize.comp`):
//! which light frustum ("face") each view sample falls in, where it projects,
//! and the per-face window fitted to the 2D bounding box of the projected
//! samples with the far plane at the farthest sample (paper §4.3).
//!
//! A point light is split into the six faces of a cube around it (faces
//! without samples are skipped), so a light that sees samples in every
//! direction works the same as one that sees them in a cone; a directional
//! light has one orthographic face. All arithmetic is `f32` on camera-relative
//! positions, exactly as the shaders do it.

use glam::Vec3;

/// Number of faces of a point light's cube.
pub const POINT_LIGHT_FACES: usize = 6;

/// The light, as the passes see it (camera-relative, `f32`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightView {
    /// A point light.
    Point {
        /// The light's camera-relative position.
        position: Vec3,
    },
    /// A directional light.
    Directional {
        /// Unit direction the light travels in.
        direction: Vec3,
    },
}

impl LightView {
    /// How many faces (frusta) this light has.
    pub fn face_count(&self) -> usize {
        match self {
            LightView::Point { .. } => POINT_LIGHT_FACES,
            LightView::Directional { .. } => 1,
        }
    }

    /// The origin that positions are taken relative to in the light's
    /// frame: the light position for a point light, 0 for a directional light.
    pub fn origin(&self) -> Vec3 {
        match self {
            LightView::Point { position } => *position,
            LightView::Directional { .. } => Vec3::ZERO,
        }
    }

    /// The basis (right, up, forward) of face `f`.
    pub fn basis(&self, f: usize) -> (Vec3, Vec3, Vec3) {
        match self {
            LightView::Point { .. } => {
                let w = match f {
                    0 => Vec3::X,
                    1 => Vec3::NEG_X,
                    2 => Vec3::Y,
                    3 => Vec3::NEG_Y,
                    4 => Vec3::Z,
                    _ => Vec3::NEG_Z,
                };
                let (r, u) = match f {
                    0 | 1 => (Vec3::Z, Vec3::Y),
                    2 | 3 => (Vec3::X, Vec3::Z),
                    _ => (Vec3::X, Vec3::Y),
                };
                (r, u, w)
            }
            LightView::Directional { direction } => {
                let w = *direction;
                let t = w.cross(Vec3::Y);
                let r = if t.length_squared() < 1e-12 {
                    Vec3::X
                } else {
                    t.normalize()
                };
                let r = (r - w * w.dot(r)).normalize();
                (r, w.cross(r), w)
            }
        }
    }

    /// Whether a surface at `p` with normal `n` faces the light (strictly).
    pub fn faces(&self, p: Vec3, n: Vec3) -> bool {
        match self {
            LightView::Point { position } => n.dot(*position - p) > 0.0,
            LightView::Directional { direction } => n.dot(-*direction) > 0.0,
        }
    }

    /// The face a point falls in and its projected coordinates (x, y) and
    /// depth z > 0 in that face; `None` for a point at the light.
    pub fn project(&self, p: Vec3) -> Option<(usize, f32, f32, f32)> {
        match self {
            LightView::Point { position } => {
                let d = p - *position;
                let a = d.abs();
                let f = if a.x >= a.y && a.x >= a.z {
                    if d.x >= 0.0 {
                        0
                    } else {
                        1
                    }
                } else if a.y >= a.z {
                    if d.y >= 0.0 {
                        2
                    } else {
                        3
                    }
                } else if d.z >= 0.0 {
                    4
                } else {
                    5
                };
                let (r, u, w) = self.basis(f);
                let z = d.dot(w);
                if z <= 0.0 || !z.is_finite() {
                    return None;
                }
                Some((f, d.dot(r) / z, d.dot(u) / z, z))
            }
            LightView::Directional { .. } => {
                let (r, u, w) = self.basis(0);
                Some((0, p.dot(r), p.dot(u), p.dot(w)))
            }
        }
    }
}

/// Float to a `u32` key whose unsigned order is the float order (for atomic min/max).
pub fn float_key(f: f32) -> u32 {
    let b = f.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// Inverse of [`float_key`].
pub fn key_float(k: u32) -> f32 {
    f32::from_bits(if k & 0x8000_0000 != 0 {
        k & 0x7fff_ffff
    } else {
        !k
    })
}

/// The fitted window of one face.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FaceWindow {
    /// Whether any view sample falls in this face.
    pub valid: bool,
    /// Left edge (lowest x) of the window in projected coordinates.
    pub x0: f32,
    /// Bottom edge (lowest y) of the window in projected coordinates.
    pub y0: f32,
    /// Texels per projected unit along x.
    pub sx: f32,
    /// Texels per projected unit along y.
    pub sy: f32,
    /// Depth of the farthest view sample in this face.
    pub z_far: f32,
}

/// Running min/max keys of one face: xmin, ymin, xmax, ymax, zmax (as
/// [`float_key`]s), what `light_fit.comp` accumulates with atomics.
pub type FitKeys = [u32; 5];

/// The empty accumulator.
pub const FIT_EMPTY: FitKeys = [u32::MAX, u32::MAX, 0, 0, 0];

/// Folds one projected sample into its face's keys.
pub fn fit_accumulate(keys: &mut FitKeys, x: f32, y: f32, z: f32) {
    keys[0] = keys[0].min(float_key(x));
    keys[1] = keys[1].min(float_key(y));
    keys[2] = keys[2].max(float_key(x));
    keys[3] = keys[3].max(float_key(y));
    keys[4] = keys[4].max(float_key(z));
}

/// Turns a face's keys into its window over `resolution`² texels: the
/// bounding box, widened by a small margin so that every sample lands
/// strictly inside, and never narrower than a tiny relative width.
pub fn fit_finalize(keys: &FitKeys, resolution: u32) -> FaceWindow {
    if keys[2] == 0 {
        return FaceWindow::default();
    }
    let (xmin, ymin, xmax, ymax) = (
        key_float(keys[0]),
        key_float(keys[1]),
        key_float(keys[2]),
        key_float(keys[3]),
    );
    let z_far = key_float(keys[4]);
    let axis = |lo: f32, hi: f32| {
        let scale = lo.abs().max(hi.abs()).max(1e-30);
        let width = (hi - lo).max(scale * 1e-5);
        let pad = width * 1e-3;
        let x0 = lo - pad;
        (x0, resolution as f32 / (width + 2.0 * pad))
    };
    let (x0, sx) = axis(xmin, xmax);
    let (y0, sy) = axis(ymin, ymax);
    FaceWindow {
        valid: true,
        x0,
        y0,
        sx,
        sy,
        z_far,
    }
}

/// The texel (column, row) a projected point falls in, clamped to the map.
pub fn texel_of(w: &FaceWindow, x: f32, y: f32, resolution: u32) -> (u32, u32) {
    let max = resolution as f32 - 1.0;
    let tx = ((x - w.x0) * w.sx).floor().clamp(0.0, max);
    let ty = ((y - w.y0) * w.sy).floor().clamp(0.0, max);
    (tx as u32, ty as u32)
}

/// Fits every face's window to the samples that face the light.
pub fn fit_windows(
    light: &LightView,
    samples: &[(Vec3, Vec3)],
    resolution: u32,
) -> Vec<FaceWindow> {
    let mut keys = vec![FIT_EMPTY; light.face_count()];
    for &(p, n) in samples {
        if !light.faces(p, n) {
            continue;
        }
        if let Some((f, x, y, z)) = light.project(p) {
            fit_accumulate(&mut keys[f], x, y, z);
        }
    }
    keys.iter().map(|k| fit_finalize(k, resolution)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_keys_preserve_order() {
        let v = [-1e30f32, -2.5, -1e-30, -0.0, 0.0, 1e-30, 3.0, 1e30];
        for w in v.windows(2) {
            assert!(float_key(w[0]) <= float_key(w[1]), "{w:?}");
        }
        for x in v {
            assert_eq!(key_float(float_key(x)).to_bits(), x.to_bits());
        }
    }

    #[test]
    fn every_sample_lands_inside_its_window() {
        let light = LightView::Point {
            position: Vec3::new(0.3, 5.0, -0.2),
        };
        let mut samples = Vec::new();
        for i in 0..50 {
            for j in 0..50 {
                let p = Vec3::new(i as f32 * 0.2 - 5.0, 0.0, j as f32 * 0.2 - 5.0);
                samples.push((p, Vec3::Y));
            }
        }
        let r = 64;
        let w = fit_windows(&light, &samples, r);
        assert!(w[3].valid, "samples below the light are in face -Y");
        for (p, _) in &samples {
            let (f, x, y, _) = light.project(*p).unwrap();
            let tx = (x - w[f].x0) * w[f].sx;
            let ty = (y - w[f].y0) * w[f].sy;
            assert!(
                tx > 0.0 && tx < r as f32 && ty > 0.0 && ty < r as f32,
                "{tx} {ty}"
            );
        }
    }
}
