//! Shading: turns view samples and per-light visibility into a picture:
//! Lambert with coherent shading normals (paper §4.3, [`normals`]) and the
//! materials' base colours (factor × texture), plus ambient. The engine's
//! product is the visibility; the picture is there to be looked at.

pub mod normals;

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::light::{Light, LightShape};
use crate::oracle::ViewSamples;
use crate::scene::{Scene, TriangleIds};
pub use normals::ShadingNormals;

/// Ambient term so that fully shadowed surfaces are still readable.
const AMBIENT: f64 = 0.12;
/// Albedo of surfaces without a material.
const ALBEDO: f64 = 0.8;

/// Linear to 8-bit sRGB by the formula (one `powf`): what [`to_srgb8`]
/// computes without it.
fn to_srgb8_formula(linear: f64) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Buckets of [0, 1] in [`SrgbTable`]: fine enough that a bucket spans at
/// most one step of the 8-bit code (the steepest part, near 0, climbs
/// 3294 codes per unit).
const SRGB_BUCKETS: usize = 4096;

/// [`to_srgb8_formula`] as tables: per code k, the least linear value
/// that reaches it, and per bucket the code at its start.
struct SrgbTable {
    /// `first[k]`: the least f64 in [0, 1] whose code is at least k
    /// (`first[0]` = 0).
    first: [f64; 256],
    /// The code of each bucket's first value, `b / SRGB_BUCKETS`.
    bucket: Vec<u8>,
}

fn srgb_table() -> &'static SrgbTable {
    static TABLE: std::sync::OnceLock<SrgbTable> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        // Bisection over the bit patterns of [0, 1] (ordered like the
        // values for non-negative floats): the formula's code does not
        // decrease as its argument grows.
        let first = std::array::from_fn(|k| {
            let (mut lo, mut hi) = (0u64, 1f64.to_bits());
            if to_srgb8_formula(0.0) as usize >= k {
                return 0.0;
            }
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if to_srgb8_formula(f64::from_bits(mid)) as usize >= k {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            f64::from_bits(hi)
        });
        let bucket = (0..SRGB_BUCKETS)
            .map(|b| to_srgb8_formula(b as f64 / SRGB_BUCKETS as f64))
            .collect();
        SrgbTable { first, bucket }
    })
}

/// Linear to 8-bit sRGB: [`to_srgb8_formula`]'s code, found from its
/// bucket's code and the codes' thresholds (three `powf` per pixel were
/// most of a 512² frame's shading time).
fn to_srgb8(linear: f64) -> u8 {
    if linear.is_nan() || linear <= 0.0 {
        return 0; // as the formula's cast gives
    }
    let c = linear.min(1.0);
    let table = srgb_table();
    // c * SRGB_BUCKETS is exact (a power of two): the bucket starts at or below c.
    let mut k = table.bucket[((c * SRGB_BUCKETS as f64) as usize).min(SRGB_BUCKETS - 1)];
    while k < 255 && table.first[k as usize + 1] <= c {
        k += 1;
    }
    k
}

/// sRGB 8-bit to linear, as a table (texture look-ups need four texels
/// of three channels per pixel).
fn from_srgb8(v: u8) -> f64 {
    static TABLE: std::sync::OnceLock<[f64; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let c = i as f64 / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        })
    })[v as usize]
}

/// The materials of a scene's triangles (in [`Scene::triangles`] order),
/// read from the meshes themselves: no per-frame copy.
struct Surfaces<'a> {
    scene: &'a Scene,
    ids: TriangleIds,
}

impl<'a> Surfaces<'a> {
    fn new(scene: &'a Scene) -> Self {
        Surfaces {
            scene,
            ids: scene.triangle_ids(),
        }
    }

    /// Linear RGB base colour at barycentrics `bary` of triangle `t`:
    /// `baseColorFactor` × the base-colour texture (bilinear, repeating,
    /// sRGB decoded; glTF's UV origin is the image's top-left); grey
    /// without a material.
    /// `located`: the triangle's [`TriangleIds::locate`].
    fn albedo_at(&self, located: Option<(usize, usize)>, bary: DVec3) -> [f64; 3] {
        let Some((m, local)) = located else {
            return [ALBEDO; 3];
        };
        let mesh = &self.scene.meshes[m];
        let Some(material) = mesh.material.and_then(|i| self.scene.materials.get(i)) else {
            return [ALBEDO; 3];
        };
        let f = material.base_color_factor;
        let mut rgb = [f[0] as f64, f[1] as f64, f[2] as f64];
        let image = material
            .base_color_texture
            .as_ref()
            .and_then(|tex| tex.image.as_ref());
        if let (Some(image), Some(uvs)) = (image, &mesh.uvs) {
            let [a, b, c] = mesh.indices[local].map(|v| uvs[v as usize]);
            let texel = bilinear(image, a * bary.x + b * bary.y + c * bary.z);
            for (c, t) in rgb.iter_mut().zip(texel) {
                *c *= t;
            }
        }
        rgb
    }
}

/// Bilinear, repeating look-up of `image` at `uv` (linear RGB).
fn bilinear(image: &image::RgbaImage, uv: DVec2) -> [f64; 3] {
    let (w, h) = (image.width().max(1) as i64, image.height().max(1) as i64);
    let x = uv.x * w as f64 - 0.5;
    let y = uv.y * h as f64 - 0.5;
    if !(x.is_finite() && y.is_finite()) || image.width() == 0 || image.height() == 0 {
        return [1.0; 3];
    }
    // Far out, f64 has no fraction left; clamped there, the corners' +1
    // cannot overflow i64.
    let (x, y) = (x.clamp(-1e15, 1e15), y.clamp(-1e15, 1e15));
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    // The repeat; coordinates inside the image (most) need no division.
    let wrap = |v: i64, n: i64| {
        if (0..n).contains(&v) {
            v
        } else {
            v.rem_euclid(n)
        }
    };
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (xs, ys) = (
        [wrap(x0, w), wrap(x0 + 1, w)],
        [wrap(y0, h), wrap(y0 + 1, h)],
    );
    let raw = image.as_raw();
    let texel = |dx: usize, dy: usize| {
        let i = 4 * (ys[dy] * w + xs[dx]) as usize;
        [
            from_srgb8(raw[i]),
            from_srgb8(raw[i + 1]),
            from_srgb8(raw[i + 2]),
        ]
    };
    let (a, b, c, d) = (texel(0, 0), texel(1, 0), texel(0, 1), texel(1, 1));
    std::array::from_fn(|i| {
        let top = a[i] + (b[i] - a[i]) * fx;
        let bottom = c[i] + (d[i] - c[i]) * fx;
        top + (bottom - top) * fy
    })
}

/// What a mesh's shading normals depend on: positions, triangles, normals.
type MeshGeometry = (Vec<DVec3>, Vec<[u32; 3]>, Option<Vec<DVec3>>);

/// [`ShadingNormals`] kept across frames: made again only when the
/// scene's geometry (positions, triangles, normals) differs from the last
/// frame's, which a comparison tells (no hashing).
#[derive(Default)]
pub struct ShadingCache {
    geometry: Vec<MeshGeometry>,
    normals: ShadingNormals,
}

impl ShadingCache {
    /// The shading normals of `scene`, and whether they were reused.
    pub fn get(&mut self, scene: &Scene) -> (&ShadingNormals, bool) {
        let same = self.geometry.len() == scene.meshes.len()
            && self
                .geometry
                .iter()
                .zip(&scene.meshes)
                .all(|(g, m)| g.0 == m.positions && g.1 == m.indices && g.2 == m.normals);
        if !same {
            self.normals = ShadingNormals::new(scene);
            self.geometry = scene
                .meshes
                .iter()
                .map(|m| (m.positions.clone(), m.indices.clone(), m.normals.clone()))
                .collect();
        }
        (&self.normals, same)
    }
}

/// What the unit direction from a point towards a light is taken from:
/// found once per light and frame, not per pixel (an explicit light's
/// centre is the mean of its samples: per pixel, that sum cost a
/// 1024-sample light's 512² frame 110 ms of shading).
#[derive(Clone, Copy, Debug, PartialEq)]
enum LightAim {
    /// Towards the light's centre.
    Centre(DVec3),
    /// Against a directional light's direction (already unit, or zero).
    Along(DVec3),
    /// A light without a centre (an explicit light with no samples).
    Nowhere,
}

impl LightAim {
    fn of(light: &Light) -> Self {
        match &light.shape {
            LightShape::Directional { direction } => {
                LightAim::Along(-direction.normalize_or_zero())
            }
            _ => light.center().map_or(LightAim::Nowhere, LightAim::Centre),
        }
    }

    /// The unit direction from `p` towards the light (its centre; against
    /// the direction of a directional light); zero for a light without a
    /// centre.
    fn direction_from(self, p: DVec3) -> DVec3 {
        match self {
            LightAim::Centre(c) => (c - p).normalize_or_zero(),
            LightAim::Along(d) => d,
            LightAim::Nowhere => DVec3::ZERO,
        }
    }
}

/// Shades every pixel: `visibility[k][pixel]` is light `k`'s visible
/// fraction. Samples on a scene triangle get coherent shading normals
/// (`normals`, made from `scene`) and their material's colour; others
/// (user samples) their own normal, grey.
pub fn shade(
    scene: &Scene,
    normals: &ShadingNormals,
    view: &ViewSamples,
    lights: &[Light],
    visibility: &[Vec<f32>],
) -> image::RgbImage {
    shade_coloured(
        scene,
        normals,
        view,
        lights,
        &light_colors(lights),
        visibility,
        &[],
    )
}

/// Per light, the colour it shines with: the mean of its samples' emission
/// for a light with an emission texture ([`Light::sample_colors`]), else
/// its `color`.
pub fn light_colors(lights: &[Light]) -> Vec<[f32; 3]> {
    lights
        .iter()
        .map(|l| match l.sample_colors() {
            Some(c) if !c.is_empty() => std::array::from_fn(|k| {
                (c.iter().map(|s| s[k] as f64).sum::<f64>() / c.len() as f64) as f32
            }),
            _ => l.color,
        })
        .collect()
}

/// [`shade`] with each light's colour given (`colors[k]`, [`light_colors`])
/// and, per light, its per-channel visibility where it has an emission
/// texture (`visibility_rgb[k]`, [`crate::light::channel_visibility`]):
/// each channel of such a light is scaled by that channel's visibility.
pub fn shade_coloured(
    scene: &Scene,
    normals: &ShadingNormals,
    view: &ViewSamples,
    lights: &[Light],
    colors: &[[f32; 3]],
    visibility: &[Vec<f32>],
    visibility_rgb: &[Option<Vec<[f32; 3]>>],
) -> image::RgbImage {
    let (w, h) = (view.width, view.height);
    let surfaces = Surfaces::new(scene);
    let mut img = image::RgbImage::new(w, h);
    let row_bytes = 3 * w as usize;
    // Per light, the corner bends of every triangle the picture shows
    // (`slot` numbers them), once per frame rather than per pixel.
    let mut slot = vec![u32::MAX; normals.triangle_count()];
    let mut shown = Vec::new();
    for s in view.samples.iter().flatten() {
        let t = s.triangle as usize;
        if t < slot.len() && slot[t] == u32::MAX {
            slot[t] = shown.len() as u32;
            shown.push(t);
        }
    }
    // Where each shown triangle's material is (a search per triangle, not per pixel).
    let located: Vec<Option<(usize, usize)>> =
        shown.par_iter().map(|&t| surfaces.ids.locate(t)).collect();
    let aims: Vec<LightAim> = lights.iter().map(LightAim::of).collect();
    let bends: Vec<Vec<[[f64; 2]; 3]>> = aims
        .iter()
        .map(|&aim| {
            shown
                .par_iter()
                .map(|&t| normals.corner_bends(t, |p| aim.direction_from(p)))
                .collect()
        })
        .collect();
    img.par_chunks_mut(row_bytes.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w as usize {
                let i = y * w as usize + x;
                let rgb = match &view.samples[i] {
                    None => {
                        // A plain vertical gradient for the background.
                        let t = y as f64 / h.max(1) as f64;
                        let c = 0.35 + 0.25 * (1.0 - t);
                        [c * 0.8, c * 0.9, c]
                    }
                    Some(s) => {
                        let t = s.triangle as usize;
                        let on_mesh = t < normals.triangle_count();
                        let bary = if on_mesh {
                            normals.barycentrics(t, s.position)
                        } else {
                            DVec3::ZERO
                        };
                        let albedo = if on_mesh {
                            surfaces.albedo_at(located[slot[t] as usize], bary)
                        } else {
                            [ALBEDO; 3]
                        };
                        let mut c = albedo.map(|a| AMBIENT * a);
                        for (k, light) in lights.iter().enumerate() {
                            let v = visibility
                                .get(k)
                                .and_then(|v| v.get(i))
                                .copied()
                                .unwrap_or(0.0) as f64;
                            if v == 0.0 {
                                continue;
                            }
                            let lambert = if on_mesh {
                                let b = &bends[k][slot[t] as usize];
                                normals.lambert_bent(t, bary, s.normal, b, |p| {
                                    aims[k].direction_from(p)
                                })
                            } else {
                                s.normal.dot(aims[k].direction_from(s.position)).max(0.0)
                            };
                            let rgb = visibility_rgb
                                .get(k)
                                .and_then(|v| v.as_ref())
                                .and_then(|v| v.get(i));
                            for (n, ((ch, lc), a)) in
                                c.iter_mut().zip(colors[k]).zip(albedo).enumerate()
                            {
                                let v = rgb.map_or(v, |rgb| rgb[n] as f64);
                                *ch += a * lambert * v * lc as f64 * light.intensity as f64;
                            }
                        }
                        c
                    }
                };
                row[3 * x..3 * x + 3].copy_from_slice(&rgb.map(to_srgb8));
            }
        });
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A light's aim, found once, gives each point the direction of the
    /// definition: towards the centre (an explicit light's mean sample),
    /// against a directional light, zero without a centre.
    #[test]
    fn light_aim_is_the_direction_to_the_light() {
        let light = |shape| Light {
            shape,
            samples: 1,
            distribution: crate::light::Distribution::Uniform,
            seed: 0,
            color: [1.0; 3],
            intensity: 1.0,
            emission: None,
            per_pixel_rotation: false,
        };
        let positions = vec![
            DVec3::new(1.0, 4.0, -2.0),
            DVec3::new(1.5, 4.5, -2.0),
            DVec3::new(0.25, 3.0, -1.0),
        ];
        let mean = positions.iter().sum::<DVec3>() / 3.0;
        let cases = [
            (
                LightShape::Point {
                    position: DVec3::new(0.0, 5.0, 0.0),
                },
                DVec3::new(0.0, 5.0, 0.0),
            ),
            (LightShape::Explicit { positions }, mean),
        ];
        let points = [
            DVec3::ZERO,
            DVec3::new(3.0, -1.0, 0.5),
            DVec3::new(-1e3, 2e3, 7.0),
        ];
        for (shape, centre) in cases {
            let aim = LightAim::of(&light(shape));
            for p in points {
                let want = (centre - p).normalize_or_zero();
                assert_eq!(aim.direction_from(p), want, "{aim:?} at {p}");
                assert!((aim.direction_from(p).length() - 1.0).abs() < 1e-12);
            }
        }
        let direction = DVec3::new(1.0, -2.0, 0.5);
        let aim = LightAim::of(&light(LightShape::Directional { direction }));
        for p in points {
            assert_eq!(aim.direction_from(p), -direction.normalize());
        }
        let aim = LightAim::of(&light(LightShape::Explicit {
            positions: Vec::new(),
        }));
        for p in points {
            assert_eq!(aim.direction_from(p), DVec3::ZERO);
        }
    }

    #[test]
    fn bilinear_reads_far_coordinates_without_overflow() {
        let img = image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 255, 255, 255]));
        for far in [1e12, 1e19, 1e300, -1e300, f64::MAX] {
            let c = bilinear(&img, DVec2::new(far, -far));
            assert!(c.iter().all(|v| (v - 1.0).abs() < 1e-9), "{far}: {c:?}");
        }
    }

    /// The repeat without a division for coordinates inside the image
    /// gives what `rem_euclid` on every corner gives, inside, outside and
    /// on the borders of a non-square image of distinct texels.
    #[test]
    fn bilinear_repeats_like_rem_euclid() {
        let (w, h) = (5u32, 3u32);
        let img = image::RgbaImage::from_fn(w, h, |x, y| {
            image::Rgba([
                (40 * x + 7 * y) as u8,
                (90 + 50 * y) as u8,
                (x * y * 13) as u8,
                255,
            ])
        });
        let reference = |uv: DVec2| {
            let x = uv.x * w as f64 - 0.5;
            let y = uv.y * h as f64 - 0.5;
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let texel = |dx: i64, dy: i64| {
                let px = (x0 as i64 + dx).rem_euclid(w as i64) as u32;
                let py = (y0 as i64 + dy).rem_euclid(h as i64) as u32;
                let p = img.get_pixel(px, py).0;
                [from_srgb8(p[0]), from_srgb8(p[1]), from_srgb8(p[2])]
            };
            let (a, b, c, d) = (texel(0, 0), texel(1, 0), texel(0, 1), texel(1, 1));
            std::array::from_fn::<f64, 3, _>(|i| {
                let top = a[i] + (b[i] - a[i]) * fx;
                let bottom = c[i] + (d[i] - c[i]) * fx;
                top + (bottom - top) * fy
            })
        };
        for i in -40..=40 {
            for j in -25..=25 {
                let uv = DVec2::new(i as f64 / 13.0, j as f64 / 7.0);
                assert_eq!(bilinear(&img, uv), reference(uv), "at {uv}");
            }
        }
    }

    /// The tables give the formula's code for every value tried: a sweep
    /// of [−0.1, 1.1] and the floats on both sides of every threshold.
    #[test]
    fn srgb8_tables_match_the_formula() {
        let n = 2_000_000;
        for i in 0..=n {
            let c = -0.1 + 1.2 * i as f64 / n as f64;
            assert_eq!(to_srgb8(c), to_srgb8_formula(c), "at {c}");
        }
        for &t in &srgb_table().first {
            for d in -3i64..=3 {
                let c = f64::from_bits((t.to_bits() as i64 + d).max(0) as u64);
                assert_eq!(to_srgb8(c), to_srgb8_formula(c), "at {c}");
            }
        }
        for c in [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -0.0,
            0.0,
            1.0,
            2.0,
        ] {
            assert_eq!(to_srgb8(c), to_srgb8_formula(c), "at {c}");
        }
    }
}
