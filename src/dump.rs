//! The dump: everything a frame computed, written to a folder so that two
//! runs (GPU and oracle, two devices, two settings) can be compared pixel by
//! pixel. The format is documented in the README:
//!
//! - `position.exr`: RGB = view-sample position minus the camera eye, A = 1 where there is a view sample;
//! - `normal.exr`: RGB = unit geometric normal facing the camera, A as above;
//! - `visibility_K.exr`: R = visible fraction of light K's samples, G = 1 where the shadow passes evaluated the sample, A as above;
//! - `visibility_K_rgb.exr` (lights with an emission texture): RGB = the visible share of each channel's emission, A as above;
//! - `scene.json`: camera and lights (with their exact world-space samples);
//! - `stats.json`: device, settings, milliseconds per pass and counters;
//! - `image.png`: the shaded image.

use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::light::{Light, LightSamples, LightShape};
use crate::scene::Camera;
use crate::{Error, Result};

/// One light as recorded in `scene.json`: every resolved parameter and the
/// exact samples used.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpLight {
    /// The [`LightShape`]: `point`, `directional`, `sphere`, `disk`,
    /// `rect`, `ellipsoid` or `explicit`.
    pub kind: String,
    /// World-space position or centre; `None` for directional and explicit
    /// lights.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub position: Option<[f64; 3]>,
    /// Unit direction light travels in; directional lights only.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub direction: Option<[f64; 3]>,
    /// Radius in world units; sphere and disk lights only.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub radius: Option<f64>,
    /// Full extent along the tangent and bitangent; rect lights only.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub size: Option<[f64; 2]>,
    /// Semi-axis lengths along tangent, bitangent and normal; ellipsoid
    /// lights only.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub semi_axes: Option<[f64; 3]>,
    /// Unit normal; disk, rect and ellipsoid lights only.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub normal: Option<[f64; 3]>,
    /// Unit tangent (orthogonal to `normal`); disk, rect and ellipsoid
    /// lights only.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub tangent: Option<[f64; 3]>,
    /// The [`Distribution`](crate::light::Distribution), lower case
    /// (`uniform`, `stratified`, `poisson` or `sobol`).
    pub distribution: String,
    /// The light's sample seed ([`Light::seed`]).
    pub seed: u64,
    /// Linear RGB colour used in shading.
    pub color: [f32; 3],
    /// Scale of `color` in shading.
    pub intensity: f32,
    /// World-space sample positions in order (empty for a directional light).
    pub samples: Vec<[f64; 3]>,
    /// Whether the sample pattern was rotated per pixel
    /// ([`Light::per_pixel_rotation`]): pixel `i` saw each sample turned
    /// by angle [`crate::light::pixel_rotation_angle`]`(i, rotation_seed)`
    /// about `rotation_axis` through `position`.
    pub per_pixel_rotation: bool,
    /// The rotation's unit axis, world space (with `per_pixel_rotation`).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub rotation_axis: Option<[f64; 3]>,
    /// The rotation's seed (with `per_pixel_rotation`).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub rotation_seed: Option<u32>,
}

impl DumpLight {
    /// Records `light` and the samples that were used for it, seen from a
    /// camera at `eye` (a sphere's rotation axis points at it).
    pub fn new(light: &Light, samples: &LightSamples, eye: DVec3) -> Self {
        let rotation = light.pixel_rotation(eye);
        let a = |v: DVec3| Some(v.to_array());
        let mut d = DumpLight {
            kind: String::new(),
            position: None,
            direction: None,
            radius: None,
            size: None,
            semi_axes: None,
            normal: None,
            tangent: None,
            distribution: format!("{:?}", light.distribution).to_lowercase(),
            seed: light.seed,
            color: light.color,
            intensity: light.intensity,
            samples: match samples {
                LightSamples::Positions(p) => p.iter().map(|p| p.to_array()).collect(),
                LightSamples::Direction(_) => Vec::new(),
            },
            per_pixel_rotation: rotation.is_some(),
            rotation_axis: rotation.map(|r| r.axis.to_array()),
            rotation_seed: rotation.map(|r| r.seed),
        };
        match &light.shape {
            LightShape::Point { position } => {
                d.kind = "point".into();
                d.position = a(*position);
            }
            LightShape::Directional { direction } => {
                d.kind = "directional".into();
                d.direction = a(*direction);
            }
            LightShape::Sphere { position, radius } => {
                d.kind = "sphere".into();
                d.position = a(*position);
                d.radius = Some(*radius);
            }
            LightShape::Disk {
                position,
                radius,
                normal,
                tangent,
            } => {
                d.kind = "disk".into();
                d.position = a(*position);
                d.radius = Some(*radius);
                d.normal = a(*normal);
                d.tangent = a(*tangent);
            }
            LightShape::Rect {
                position,
                size,
                normal,
                tangent,
            } => {
                d.kind = "rect".into();
                d.position = a(*position);
                d.size = Some(size.to_array());
                d.normal = a(*normal);
                d.tangent = a(*tangent);
            }
            LightShape::Ellipsoid {
                position,
                semi_axes,
                normal,
                tangent,
            } => {
                d.kind = "ellipsoid".into();
                d.position = a(*position);
                d.semi_axes = a(*semi_axes);
                d.normal = a(*normal);
                d.tangent = a(*tangent);
            }
            LightShape::Explicit { .. } => d.kind = "explicit".into(),
        }
        d
    }

    /// The light samples recorded in the dump, ready for the oracle.
    pub fn light_samples(&self) -> LightSamples {
        match self.direction {
            Some(dir) if self.kind == "directional" => {
                LightSamples::Direction(DVec3::from_array(dir))
            }
            _ => LightSamples::Positions(
                self.samples.iter().map(|p| DVec3::from_array(*p)).collect(),
            ),
        }
    }
}

/// `scene.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpScene {
    /// The camera the frame was rendered with.
    pub camera: Camera,
    /// Every light, in scene order (light K of `visibility_K.exr`).
    pub lights: Vec<DumpLight>,
    /// Accumulated dumps (`afs render --frames N`): per frame, every light
    /// with the samples that frame used; `visibility_K.exr` is then the
    /// mean over the frames. Empty (and absent from the file) for a single
    /// frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<Vec<DumpLight>>,
}

/// One frame's results, in memory: what `--dump DIR` writes and
/// [`Dump::read`] reads back.
#[derive(Clone, Debug)]
pub struct Dump {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Per pixel: view-sample position minus the camera eye, and 1 in w where
    /// there is a view sample (0 elsewhere).
    pub position: Vec<[f32; 4]>,
    /// Per pixel: unit geometric normal facing the camera, w as above.
    pub normal: Vec<[f32; 4]>,
    /// Per light, per pixel: [visible fraction, evaluated by the shadow passes (1/0), 0, has view sample].
    pub visibility: Vec<Vec<[f32; 4]>>,
    /// Per light with an emission texture (`None` for the others), per
    /// pixel: [visible share of red, green, blue emission, has view sample]
    /// (`visibility_K_rgb.exr`, [`crate::light::channel_visibility`]).
    pub visibility_rgb: Vec<Option<Vec<[f32; 4]>>>,
    /// `scene.json`: the camera and the lights with their samples.
    pub scene: DumpScene,
    /// `stats.json` (free-form: device, settings, timings, counters).
    pub stats: serde_json::Value,
}

fn write_exr(path: &Path, width: u32, height: u32, data: &[[f32; 4]]) -> Result<()> {
    let flat: Vec<f32> = data.iter().flat_map(|p| p.iter().copied()).collect();
    let img = image::Rgba32FImage::from_raw(width, height, flat).ok_or_else(|| {
        Error::Image(format!(
            "{}: buffer size does not match {width}x{height}",
            path.display()
        ))
    })?;
    image::DynamicImage::ImageRgba32F(img)
        .save_with_format(path, image::ImageFormat::OpenExr)
        .map_err(|e| Error::Image(format!("{}: {e}", path.display())))
}

fn read_exr(path: &Path) -> Result<(u32, u32, Vec<[f32; 4]>)> {
    let img = image::open(path)
        .map_err(|e| Error::Image(format!("{}: {e}", path.display())))?
        .into_rgba32f();
    let (w, h) = img.dimensions();
    let data = img
        .into_raw()
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    Ok((w, h, data))
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| Error::Image(format!("{}: {e}", path.display())))?;
    std::fs::write(path, text).map_err(|e| Error::io(path, e))
}

impl Dump {
    /// Whether `name` is one of the files [`Dump::write`] writes
    /// (`image.png` included).
    pub fn is_file_name(name: &str) -> bool {
        [
            "position.exr",
            "normal.exr",
            "scene.json",
            "stats.json",
            "image.png",
        ]
        .contains(&name)
            || name
                .strip_prefix("visibility_")
                .and_then(|n| n.strip_suffix(".exr"))
                .map(|n| n.strip_suffix("_rgb").unwrap_or(n))
                .is_some_and(|k| k.parse::<usize>().is_ok())
    }

    /// Writes the dump into `dir` (created if needed), with `image` as
    /// `image.png`. Files are written under temporary names and renamed at
    /// the end, so a failed run never leaves a dump that looks complete.
    pub fn write(&self, dir: &Path, image: &image::RgbImage) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let mut written: Vec<(PathBuf, PathBuf)> = Vec::new();
        let mut tmp = |name: &str| {
            let final_path = dir.join(name);
            let tmp_path = dir.join(format!(".partial.{name}"));
            written.push((tmp_path.clone(), final_path));
            tmp_path
        };
        let (w, h) = (self.width, self.height);
        write_exr(&tmp("position.exr"), w, h, &self.position)?;
        write_exr(&tmp("normal.exr"), w, h, &self.normal)?;
        for (k, v) in self.visibility.iter().enumerate() {
            write_exr(&tmp(&format!("visibility_{k}.exr")), w, h, v)?;
        }
        for (k, v) in self.visibility_rgb.iter().enumerate() {
            if let Some(v) = v {
                write_exr(&tmp(&format!("visibility_{k}_rgb.exr")), w, h, v)?;
            }
        }
        write_json(&tmp("scene.json"), &self.scene)?;
        write_json(&tmp("stats.json"), &self.stats)?;
        let png = tmp("image.png");
        image
            .save_with_format(&png, image::ImageFormat::Png)
            .map_err(|e| Error::Image(format!("{}: {e}", png.display())))?;
        for (from, to) in written {
            std::fs::rename(&from, &to).map_err(|e| Error::io(&to, e))?;
        }
        // A light without channels leaves no per-channel file of an
        // earlier dump in the same folder behind ([`Dump::read`] would
        // take it for this one's).
        for (k, v) in self.visibility_rgb.iter().enumerate() {
            let stale = dir.join(format!("visibility_{k}_rgb.exr"));
            if v.is_none() && stale.exists() {
                std::fs::remove_file(&stale).map_err(|e| Error::io(&stale, e))?;
            }
        }
        Ok(())
    }

    /// Reads a dump written by [`Dump::write`].
    pub fn read(dir: &Path) -> Result<Dump> {
        let scene_path = dir.join("scene.json");
        let text = std::fs::read_to_string(&scene_path).map_err(|e| Error::io(&scene_path, e))?;
        let scene: DumpScene = serde_json::from_str(&text)
            .map_err(|e| Error::InvalidInput(format!("{}: {e}", scene_path.display())))?;
        let stats_path = dir.join("stats.json");
        let stats = match std::fs::read_to_string(&stats_path) {
            Ok(t) => serde_json::from_str(&t)
                .map_err(|e| Error::InvalidInput(format!("{}: {e}", stats_path.display())))?,
            Err(_) => serde_json::Value::Null,
        };
        let (width, height, position) = read_exr(&dir.join("position.exr"))?;
        let (nw, nh, normal) = read_exr(&dir.join("normal.exr"))?;
        let mut visibility = Vec::new();
        for k in 0..scene.lights.len() {
            let (vw, vh, v) = read_exr(&dir.join(format!("visibility_{k}.exr")))?;
            if (vw, vh) != (width, height) {
                return Err(Error::InvalidInput(format!(
                    "{}: visibility_{k}.exr is {vw}x{vh}, position.exr is {width}x{height}",
                    dir.display()
                )));
            }
            visibility.push(v);
        }
        let mut visibility_rgb = Vec::new();
        for k in 0..scene.lights.len() {
            let path = dir.join(format!("visibility_{k}_rgb.exr"));
            visibility_rgb.push(if path.exists() {
                let (vw, vh, v) = read_exr(&path)?;
                if (vw, vh) != (width, height) {
                    return Err(Error::InvalidInput(format!(
                        "{}: visibility_{k}_rgb.exr is {vw}x{vh}, position.exr is {width}x{height}",
                        dir.display()
                    )));
                }
                Some(v)
            } else {
                None
            });
        }
        if (nw, nh) != (width, height) {
            return Err(Error::InvalidInput(format!(
                "{}: normal.exr is {nw}x{nh}, position.exr is {width}x{height}",
                dir.display()
            )));
        }
        Ok(Dump {
            width,
            height,
            position,
            normal,
            visibility,
            visibility_rgb,
            scene,
            stats,
        })
    }
}

/// How two dumps' visibilities differ, per light.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Index of the light in both dumps.
    pub light: usize,
    /// Pixels that have a view sample in both dumps.
    pub pixels: usize,
    /// Pixels where exactly one of the dumps has a view sample.
    pub coverage_mismatch: usize,
    /// Mean absolute visibility difference over the compared pixels (0
    /// when there are none).
    pub mean_abs: f64,
    /// Root mean square visibility difference over the compared pixels.
    pub rmse: f64,
    /// Largest absolute visibility difference of a compared pixel.
    pub max_abs: f64,
    /// Share of compared pixels whose visibilities differ by more than one light sample (1/samples).
    pub share_over_one_sample: f64,
    /// A light with an emission texture in both dumps
    /// (`visibility_K_rgb.exr`): the same differences per channel.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub channels: Option<ChannelComparison>,
}

/// How two dumps' per-channel visibilities of one light differ, over the
/// pixels that have a view sample in both.
#[derive(Clone, Debug, Serialize)]
pub struct ChannelComparison {
    /// Root mean square difference of red, green and blue.
    pub rmse: [f64; 3],
    /// Largest absolute difference of red, green and blue.
    pub max_abs: [f64; 3],
}

/// Compares the visibility of every light of `a` and `b`.
pub fn compare(a: &Dump, b: &Dump) -> Result<Vec<Comparison>> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::InvalidInput(format!(
            "the dumps differ in size: {}x{} and {}x{}",
            a.width, a.height, b.width, b.height
        )));
    }
    if a.visibility.len() != b.visibility.len() {
        return Err(Error::InvalidInput(format!(
            "the dumps have {} and {} lights",
            a.visibility.len(),
            b.visibility.len()
        )));
    }
    let mut out = Vec::new();
    for (k, (va, vb)) in a.visibility.iter().zip(&b.visibility).enumerate() {
        let samples = a.scene.lights[k]
            .samples
            .len()
            .max(b.scene.lights[k].samples.len())
            .max(1);
        let one = 1.0 / samples as f64;
        let (mut n, mut mismatch, mut sum, mut sq, mut max, mut over) =
            (0usize, 0usize, 0.0, 0.0, 0.0f64, 0usize);
        for (pa, pb) in va.iter().zip(vb) {
            match (pa[3] > 0.5, pb[3] > 0.5) {
                (true, true) => {
                    let d = (pa[0] as f64 - pb[0] as f64).abs();
                    n += 1;
                    sum += d;
                    sq += d * d;
                    max = max.max(d);
                    // A tolerance of 1e-6 absorbs f32 rounding of the fraction.
                    if d > one + 1e-6 {
                        over += 1;
                    }
                }
                (false, false) => {}
                _ => mismatch += 1,
            }
        }
        let nf = n.max(1) as f64;
        let channels = match (&a.visibility_rgb.get(k), &b.visibility_rgb.get(k)) {
            (Some(Some(ca)), Some(Some(cb))) => {
                let (mut sq, mut max) = ([0.0f64; 3], [0.0f64; 3]);
                let both = va.iter().zip(vb).map(|(pa, pb)| pa[3] > 0.5 && pb[3] > 0.5);
                for ((pa, pb), both) in ca.iter().zip(cb).zip(both) {
                    if !both {
                        continue;
                    }
                    for c in 0..3 {
                        let d = (pa[c] as f64 - pb[c] as f64).abs();
                        sq[c] += d * d;
                        max[c] = max[c].max(d);
                    }
                }
                Some(ChannelComparison {
                    rmse: sq.map(|q| (q / nf).sqrt()),
                    max_abs: max,
                })
            }
            _ => None,
        };
        out.push(Comparison {
            light: k,
            pixels: n,
            coverage_mismatch: mismatch,
            mean_abs: sum / nf,
            rmse: (sq / nf).sqrt(),
            max_abs: max,
            share_over_one_sample: over as f64 / nf,
            channels,
        });
    }
    Ok(out)
}
