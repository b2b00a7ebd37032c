//! The TOML scene file, and resolving any scene argument (`.toml`, `.gltf`,
//! `.glb` or `builtin:NAME`) into a complete [`SceneDescription`]: geometry,
//! camera, lights and engine settings. The format is documented in the README.

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use serde::Deserialize;

use super::{builtin, gltf_load, Camera, Scene};
use crate::light::{
    default_tangent, orthonormal_tangent, Distribution, Light, LightEmission, LightShape,
};
use crate::{Error, Result};

/// How soft shadows evaluate light samples against a triangle's planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SoftMode {
    /// The plane look-up texture bounds each plane's bits from both sides
    /// and the light samples it leaves unsure are tested exactly: the masks
    /// of [`SoftMode::Exact`], bit for bit, at nearly the look-up's speed.
    #[default]
    Lut,
    /// Every light sample tested against the planes directly (the twin of
    /// the look-up mode).
    Exact,
    /// The paper's nearest-texel look-up: each plane's bits are those of
    /// the nearest table texel's plane, so light samples near a plane can
    /// come out wrong (measured in the README).
    Approx,
}

impl SoftMode {
    /// The name in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SoftMode::Lut => "lut",
            SoftMode::Exact => "exact",
            SoftMode::Approx => "approx",
        }
    }
}

/// A light-texel map resolution (texels per side of each light face): a
/// fixed number, or chosen per frame from the view samples and triangles
/// ([`LightTexels::resolve`]). Only speed depends on it: every resolution
/// gives the same shadows (the lists and influence regions are
/// conservative at any texel size).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LightTexels {
    /// Chosen per frame ([`LightTexels::resolve`]); `"auto"` in scene files
    /// and on the command line.
    #[default]
    Auto,
    /// This many texels per side, 1..=16384.
    Fixed(u32),
}

impl LightTexels {
    /// The least and greatest resolution [`LightTexels::Auto`] picks.
    pub const AUTO_RANGE: (u32, u32) = (32, 1024);

    /// The resolution for a frame of `view_samples` view samples and
    /// `triangles` triangles; `soft` for a light with extent.
    ///
    /// Auto balances the two costs that the resolution trades: per work
    /// unit (an 8×8-texel tile holding samples and casters: more, emptier
    /// tiles at finer texels) and per view-sample–triangle test (each
    /// caster's influence region is padded to whole texels: at coarser
    /// texels every sample is tested against more small casters). With
    /// `u ∝ r²` units and `tests ∝ N·(c + T/r²)`, the sum is least at
    /// `r ∝ (N·T)^¼`. The factors were fitted on lavapipe (512² and 256²
    /// frames of the built-ins, ToyCar and TransmissionTest; see
    /// docs/status.md): 1 for hard shadows and 0.65 for soft ones, whose
    /// influence regions are wider. The result is rounded to a multiple of
    /// the 8-texel tile and kept in [`LightTexels::AUTO_RANGE`].
    pub fn resolve(self, view_samples: usize, triangles: usize, soft: bool) -> u32 {
        match self {
            LightTexels::Fixed(r) => r,
            LightTexels::Auto => {
                let k = if soft { 0.65 } else { 1.0 };
                let nt = view_samples.max(1) as f64 * triangles.max(1) as f64;
                let r = (k * nt.powf(0.25) / 8.0).round() * 8.0;
                let (lo, hi) = Self::AUTO_RANGE;
                (r as u32).clamp(lo, hi)
            }
        }
    }

    /// Checks a fixed resolution's range; the error names `key`.
    fn validate(self, key: &str) -> Result<()> {
        match self {
            LightTexels::Fixed(v) if !(1..=16384).contains(&v) => Err(Error::InvalidInput(
                format!("shadows.{key} must be \"auto\" or in 1..=16384, got {v}"),
            )),
            _ => Ok(()),
        }
    }
}

impl From<u32> for LightTexels {
    fn from(r: u32) -> Self {
        LightTexels::Fixed(r)
    }
}

impl std::fmt::Display for LightTexels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LightTexels::Auto => f.write_str("auto"),
            LightTexels::Fixed(r) => write!(f, "{r}"),
        }
    }
}

impl std::str::FromStr for LightTexels {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s == "auto" {
            return Ok(LightTexels::Auto);
        }
        s.parse::<u32>()
            .map(LightTexels::Fixed)
            .map_err(|_| format!("expected \"auto\" or a number of texels, got {s:?}"))
    }
}

impl<'de> Deserialize<'de> for LightTexels {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(i64),
            Name(String),
        }
        match Raw::deserialize(d)? {
            Raw::Number(n) => u32::try_from(n).map(LightTexels::Fixed).map_err(|_| {
                serde::de::Error::custom(format!("expected \"auto\" or 1..=16384, got {n}"))
            }),
            Raw::Name(s) => s.parse().map_err(serde::de::Error::custom),
        }
    }
}

impl serde::Serialize for LightTexels {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            LightTexels::Auto => s.serialize_str("auto"),
            LightTexels::Fixed(r) => s.serialize_u32(*r),
        }
    }
}

/// Engine settings (the `[shadows]` table); CLI flags override them.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShadowSettings {
    /// Light-texel map resolution for point and directional lights (the
    /// map is `light_texels`² per face; auto by default).
    pub light_texels: LightTexels,
    /// Light-texel map resolution for lights with extent (auto by default:
    /// coarser than for hard shadows, since an influence region spans many
    /// texels anyway).
    pub soft_light_texels: LightTexels,
    /// Soft-shadow evaluation mode.
    pub mode: SoftMode,
    /// Resolution of the plane look-up texture (`lut_resolution`³).
    pub lut_resolution: u32,
    /// View-sample clusters: tile binning drops the casters that cannot
    /// shadow any sample of a tile's box ([`crate::gpu::clusters`]). The
    /// results are the same either way; off only to measure what they save.
    pub clusters: bool,
    /// The wedge rule of soft occlusion: a caster whose cone from a view
    /// sample passes the light's bounding sphere (two edges' planes
    /// together leave it outside, where neither does alone) is skipped
    /// before its per-light-sample tests (exact mode only;
    /// `soft_occlusion.comp`: `wedges_miss_light`; look-up mode has it
    /// compiled out, where it cost more than it saved). The results are the
    /// same either way; off only to measure what it saves.
    pub wedge_rule: bool,
}

impl Default for ShadowSettings {
    fn default() -> Self {
        ShadowSettings {
            light_texels: LightTexels::Auto,
            soft_light_texels: LightTexels::Auto,
            mode: SoftMode::Lut,
            lut_resolution: 128,
            clusters: true,
            wedge_rule: true,
        }
    }
}

impl ShadowSettings {
    /// Checks the ranges; the error names the key.
    pub fn validate(&self) -> Result<()> {
        self.light_texels.validate("light_texels")?;
        self.soft_light_texels.validate("soft_light_texels")?;
        // The GPU look-up texture takes at most 512 (its build checks too).
        if !(8..=512).contains(&self.lut_resolution) {
            return Err(Error::InvalidInput(format!(
                "shadows.lut_resolution must be in 8..=512, got {}",
                self.lut_resolution
            )));
        }
        Ok(())
    }
}

/// A fully resolved scene: what a frame needs.
#[derive(Clone, Debug)]
pub struct SceneDescription {
    /// A name for reports (the file name or `builtin:NAME`).
    pub name: String,
    /// The geometry (world space), with any ground plane the file adds.
    pub scene: Scene,
    /// The camera the frame is rendered from.
    pub camera: Camera,
    /// Every light, in order: light K of the dump and of the statistics.
    pub lights: Vec<Light>,
    /// The engine settings (the `[shadows]` table, or the defaults).
    pub shadows: ShadowSettings,
}

impl SceneDescription {
    /// Validates the camera, the geometry (finite, in range of the camera,
    /// indices in range: [`Scene::validate`]), every light and the settings.
    pub fn validate(&self) -> Result<()> {
        self.camera.validate()?;
        self.scene
            .validate(self.camera.eye)
            .map_err(|e| Error::InvalidInput(format!("{}: {}", self.name, strip_prefix(&e))))?;
        for (i, l) in self.lights.iter().enumerate() {
            l.validate()
                .and_then(|()| l.validate_relative_to(self.camera.eye))
                .map_err(|e| Error::InvalidInput(format!("light {i}: {}", strip_prefix(&e))))?;
        }
        self.shadows.validate()
    }
}

fn strip_prefix(e: &Error) -> String {
    let s = e.to_string();
    s.strip_prefix("invalid input: ").unwrap_or(&s).to_string()
}

// ----------------------------------------------------------------------------
// The TOML schema. Unknown keys are errors (deny_unknown_fields) so that a
// typo is never silently ignored.

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct FileRoot {
    scene: String,
    ground: Option<FileGround>,
    camera: Option<FileCamera>,
    #[serde(default)]
    light: Vec<FileLight>,
    #[serde(default)]
    shadows: ShadowSettings,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct FileGround {
    y: f64,
    half_size: f64,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct FileCamera {
    eye: [f64; 3],
    target: [f64; 3],
    #[serde(default = "default_up")]
    up: [f64; 3],
    #[serde(default = "default_fov")]
    fov_y_deg: f64,
    #[serde(default = "default_size")]
    width: u32,
    #[serde(default = "default_size")]
    height: u32,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
fn default_fov() -> f64 {
    45.0
}
fn default_size() -> u32 {
    512
}

#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum FileLightKind {
    Point,
    Directional,
    Sphere,
    Disk,
    Rect,
    Ellipsoid,
    Explicit,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct FileLight {
    kind: FileLightKind,
    position: Option<[f64; 3]>,
    radius: Option<f64>,
    size: Option<[f64; 2]>,
    semi_axes: Option<[f64; 3]>,
    normal: Option<[f64; 3]>,
    tangent: Option<[f64; 3]>,
    direction: Option<[f64; 3]>,
    positions: Option<Vec<[f64; 3]>>,
    samples: Option<u32>,
    #[serde(default)]
    distribution: Distribution,
    #[serde(default = "default_seed")]
    seed: u64,
    #[serde(default = "default_color")]
    color: [f32; 3],
    #[serde(default = "default_intensity")]
    intensity: f32,
    /// An emission texture (PNG or any format `image` reads), relative to
    /// the scene file: rect and disk lights only.
    texture: Option<String>,
    /// Per-pixel rotation of the samples ([`Light::per_pixel_rotation`]).
    #[serde(default)]
    per_pixel_rotation: bool,
}

fn default_seed() -> u64 {
    7
}
fn default_color() -> [f32; 3] {
    [1.0; 3]
}
fn default_intensity() -> f32 {
    1.0
}

/// Default number of samples for area and volumetric lights.
pub const DEFAULT_AREA_SAMPLES: u32 = 128;

impl FileLight {
    fn resolve(&self, base: &Path) -> std::result::Result<Light, String> {
        let v = |a: [f64; 3]| DVec3::from_array(a);
        let need = |name: &str, x: Option<[f64; 3]>| {
            x.map(v)
                .ok_or_else(|| format!("missing key `{name}` for a {:?} light", self.kind))
        };
        let need_f = |name: &str, x: Option<f64>| {
            x.ok_or_else(|| format!("missing key `{name}` for a {:?} light", self.kind))
        };
        let unit = |name: &str, x: DVec3| {
            let l = x.length();
            if !l.is_finite() || l == 0.0 {
                Err(format!(
                    "`{name}` must be a finite non-zero vector, got {x:?}"
                ))
            } else {
                Ok(x / l)
            }
        };
        // normal and tangent of oriented shapes: the normal defaults to
        // straight down (a ceiling light), the tangent as documented.
        let frame = || -> std::result::Result<(DVec3, DVec3), String> {
            let n = unit("normal", self.normal.map(v).unwrap_or(DVec3::NEG_Y))?;
            let t = match self.tangent {
                Some(t) => {
                    let t = unit("tangent", v(t))?;
                    orthonormal_tangent(n, t)
                        .ok_or_else(|| "`tangent` is parallel to `normal`".to_string())?
                }
                None => default_tangent(n),
            };
            Ok((n, t))
        };
        let area = !matches!(self.kind, FileLightKind::Point | FileLightKind::Directional);
        let shape = match self.kind {
            FileLightKind::Point => LightShape::Point {
                position: need("position", self.position)?,
            },
            FileLightKind::Directional => LightShape::Directional {
                direction: unit("direction", need("direction", self.direction)?)?,
            },
            FileLightKind::Sphere => LightShape::Sphere {
                position: need("position", self.position)?,
                radius: need_f("radius", self.radius)?,
            },
            FileLightKind::Disk => {
                let (normal, tangent) = frame()?;
                LightShape::Disk {
                    position: need("position", self.position)?,
                    radius: need_f("radius", self.radius)?,
                    normal,
                    tangent,
                }
            }
            FileLightKind::Rect => {
                let (normal, tangent) = frame()?;
                let size = self
                    .size
                    .ok_or_else(|| "missing key `size` for a Rect light".to_string())?;
                LightShape::Rect {
                    position: need("position", self.position)?,
                    size: DVec2::from_array(size),
                    normal,
                    tangent,
                }
            }
            FileLightKind::Ellipsoid => {
                let (normal, tangent) = frame()?;
                LightShape::Ellipsoid {
                    position: need("position", self.position)?,
                    semi_axes: need("semi_axes", self.semi_axes)?,
                    normal,
                    tangent,
                }
            }
            FileLightKind::Explicit => {
                let p = self
                    .positions
                    .as_ref()
                    .ok_or_else(|| "missing key `positions` for an Explicit light".to_string())?;
                LightShape::Explicit {
                    positions: p.iter().map(|a| v(*a)).collect(),
                }
            }
        };
        let samples = match (&shape, self.samples) {
            (LightShape::Explicit { positions }, None) => positions.len() as u32,
            (LightShape::Explicit { positions }, Some(s)) if s as usize != positions.len() => {
                return Err(format!(
                    "`samples` = {s} but `positions` has {} entries",
                    positions.len()
                ))
            }
            (_, Some(s)) if !area && s != 1 => {
                return Err(format!(
                    "`samples` must be 1 for a {:?} light, got {s}",
                    self.kind
                ))
            }
            (_, Some(s)) => s,
            (_, None) if area => DEFAULT_AREA_SAMPLES,
            (_, None) => 1,
        };
        let light = Light {
            shape,
            samples,
            distribution: self.distribution,
            seed: self.seed,
            color: self.color,
            intensity: self.intensity,
            emission: match &self.texture {
                Some(t) => {
                    let path = base.join(t);
                    let image = image::open(&path)
                        .map_err(|e| format!("`texture` {}: {e}", path.display()))?;
                    Some(LightEmission {
                        path: path.display().to_string(),
                        image: std::sync::Arc::new(image.to_rgb8()),
                    })
                }
                None => None,
            },
            per_pixel_rotation: self.per_pixel_rotation,
        };
        light.validate().map_err(|e| strip_prefix(&e))?;
        Ok(light)
    }
}

/// Parses a TOML scene file's text. `path` is used for messages and to
/// resolve the relative `scene` path.
pub fn parse_scene_file(text: &str, path: &Path) -> Result<SceneDescription> {
    parse_scene_file_with(text, path, &load_geometry)
}

/// [`parse_scene_file`] with the geometry loader supplied:
/// `geometry(scene, base)` resolves the file's `scene` value (`base` is the
/// file's folder) into the scene, camera and lights that the file's own
/// tables then override. For tests and fuzzing, which parse scene files
/// without reading models or generating large built-in scenes.
pub fn parse_scene_file_with(
    text: &str,
    path: &Path,
    geometry: &dyn Fn(&str, &Path) -> Result<SceneDescription>,
) -> Result<SceneDescription> {
    let err = |message: String| Error::SceneFile {
        path: path.to_path_buf(),
        message,
    };
    let root: FileRoot = toml::from_str(text).map_err(|e| err(toml_message(&e)))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut desc = geometry(&root.scene, base)?;
    desc.name = path.display().to_string();
    if let Some(g) = &root.ground {
        if !(g.y.is_finite() && g.half_size.is_finite() && g.half_size > 0.0) {
            return Err(err(format!(
                "ground: `y` must be finite and `half_size` finite and > 0, got y = {}, half_size = {}",
                g.y, g.half_size
            )));
        }
        desc.scene.add_ground(g.y, g.half_size);
    }
    if let Some(c) = &root.camera {
        desc.camera = Camera {
            eye: DVec3::from_array(c.eye),
            target: DVec3::from_array(c.target),
            up: DVec3::from_array(c.up),
            fov_y_deg: c.fov_y_deg,
            width: c.width,
            height: c.height,
        };
        desc.camera.validate().map_err(|e| err(strip_prefix(&e)))?;
    }
    if !root.light.is_empty() {
        desc.lights = root
            .light
            .iter()
            .enumerate()
            .map(|(i, l)| l.resolve(base).map_err(|m| err(format!("light {i}: {m}"))))
            .collect::<Result<_>>()?;
    }
    root.shadows.validate().map_err(|e| err(strip_prefix(&e)))?;
    desc.shadows = root.shadows;
    // What only the whole description can tell: geometry and lights in
    // range of this camera.
    let eye = desc.camera.eye;
    desc.scene
        .validate(eye)
        .map_err(|e| err(strip_prefix(&e)))?;
    for (i, l) in desc.lights.iter().enumerate() {
        l.validate_relative_to(eye)
            .map_err(|e| err(format!("light {i}: {}", strip_prefix(&e))))?;
    }
    Ok(desc)
}

/// The toml crate's message, on one line, with the line number first.
fn toml_message(e: &toml::de::Error) -> String {
    e.to_string().trim().replace('\n', " ").replace("  ", " ")
}

/// Loads a scene argument: a TOML scene file, a `.gltf`/`.glb` file, or
/// `builtin:NAME`. Scenes without a camera or lights of their own (glTF
/// cameras, `KHR_lights_punctual`) get a framing camera and a point light
/// above ([`default_view`]).
pub fn load(spec: &str) -> Result<SceneDescription> {
    let path = PathBuf::from(spec);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    if ext.as_deref() == Some("toml") {
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        parse_scene_file(&text, &path)
    } else {
        load_geometry(spec, Path::new("."))
    }
}

/// Loads `builtin:NAME` or a glTF file (relative to `base`), with the
/// scene's own camera and lights or defaults.
fn load_geometry(spec: &str, base: &Path) -> Result<SceneDescription> {
    if let Some(name) = spec.strip_prefix("builtin:") {
        let b = builtin::builtin(name)?;
        return Ok(SceneDescription {
            name: spec.to_string(),
            scene: b.scene,
            camera: b.camera,
            lights: b.lights,
            shadows: ShadowSettings::default(),
        });
    }
    let path = base.join(spec);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("gltf") | Some("glb") => {}
        _ => {
            return Err(Error::InvalidInput(format!(
            "{}: a scene is a .toml scene file, a .gltf or .glb file, or builtin:NAME (one of {})",
            path.display(),
            builtin::NAMES.join(", ")
        )))
        }
    }
    let scene = gltf_load::load_gltf(&path)?;
    if scene.triangle_count() == 0 {
        // A file that yields nothing to render is almost always a broken
        // export; the library API still accepts empty scenes built in code.
        return Err(Error::Gltf {
            path,
            message: "the scene contains no triangles".into(),
        });
    }
    let (camera, light) = default_view(&scene);
    let camera = scene.cameras.first().copied().unwrap_or(camera);
    // The file's own lights (KHR_lights_punctual), else the default one.
    let lights = match scene.lights.is_empty() {
        true => vec![light],
        false => scene.lights.clone(),
    };
    // Vertices finite in f64 (the loader checks that) can still be out of
    // the f32 range of the GPU passes, relative to the camera.
    scene.validate(camera.eye).map_err(|e| Error::Gltf {
        path: path.clone(),
        message: strip_prefix(&e),
    })?;
    // Then the file's own lights, so that a bad vertex is named first.
    for (i, l) in scene.lights.iter().enumerate() {
        l.validate_relative_to(camera.eye)
            .map_err(|e| Error::Gltf {
                path: path.clone(),
                message: format!("light {i}: {}", strip_prefix(&e)),
            })?;
    }
    Ok(SceneDescription {
        name: path.display().to_string(),
        scene,
        camera,
        lights,
        shadows: ShadowSettings::default(),
    })
}

/// A camera that frames the scene from a three-quarter view and a point
/// light above and to the side, for scenes that bring neither.
pub fn default_view(scene: &Scene) -> (Camera, Light) {
    let (lo, hi) = scene
        .bounds()
        .unwrap_or((DVec3::splat(-1.0), DVec3::splat(1.0)));
    let center = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-6);
    let fov_y_deg: f64 = 45.0;
    let dist = radius / (fov_y_deg.to_radians() * 0.5).sin();
    let dir = DVec3::new(0.55, 0.45, 0.7).normalize();
    let camera = Camera {
        eye: center + dir * dist,
        target: center,
        up: DVec3::Y,
        fov_y_deg,
        width: 512,
        height: 512,
    };
    let light = Light {
        shape: LightShape::Point {
            position: center + DVec3::new(-0.6, 1.6, 0.5).normalize() * (radius * 3.0),
        },
        samples: 1,
        distribution: Distribution::Poisson,
        seed: 7,
        color: [1.0; 3],
        intensity: 1.0,
        emission: None,
        per_pixel_rotation: false,
    };
    (camera, light)
}

/// Adds a square ground plane (normal +y) just under the scene's lowest
/// point, centred under the model and four model radii wide, so that a loose
/// model is "placed on a ground plane" that catches its shadows.
pub fn place_on_ground(scene: &mut Scene) {
    if let Some((lo, hi)) = scene.bounds() {
        let c = (lo + hi) * 0.5;
        let h = ((hi - lo).length() * 2.0).max(1e-6);
        let y = lo.y;
        let positions = vec![
            DVec3::new(c.x - h, y, c.z - h),
            DVec3::new(c.x + h, y, c.z - h),
            DVec3::new(c.x + h, y, c.z + h),
            DVec3::new(c.x - h, y, c.z + h),
        ];
        let mut m = super::Mesh::new("ground", positions, vec![[0, 3, 2], [0, 2, 1]]);
        m.closed = false;
        scene.meshes.push(m);
    }
}

/// Replaces the scene's lights with the one `spec` describes (the CLI's
/// `--light`): `KIND[:KEY=VALUE,...]`, KIND one of `point`, `directional`,
/// `sphere`, `disk`, `rect`; keys `radius` (sphere and disk radius, half
/// the rect's side; default a tenth of the light's distance to the scene's
/// centre) and `samples` (area lights; default 128). The light stands where
/// the scene's first light is (its centre), else where [`default_view`]
/// puts one; planar and directional lights face the scene's centre.
pub fn replace_light(desc: &mut SceneDescription, spec: &str) -> Result<()> {
    let err = |m: String| Error::InvalidInput(format!("--light {spec}: {m}"));
    let (kind, rest) = spec.split_once(':').unwrap_or((spec, ""));
    let (mut radius, mut samples, mut rotate) = (None, 128u32, false);
    for kv in rest.split(',').filter(|s| !s.is_empty()) {
        let (k, v) = kv
            .split_once('=')
            .ok_or_else(|| err(format!("{kv:?} is not KEY=VALUE")))?;
        match k {
            "radius" => {
                let r: f64 = v
                    .parse()
                    .map_err(|_| err(format!("radius {v:?} is not a number")))?;
                if !(r > 0.0 && r.is_finite()) {
                    return Err(err(format!("radius must be positive and finite, got {v}")));
                }
                radius = Some(r);
            }
            "samples" => {
                samples = v
                    .parse()
                    .ok()
                    .filter(|n| (1..=crate::gpu::MAX_SOFT_SAMPLES as u32).contains(n))
                    .ok_or_else(|| {
                        err(format!(
                            "samples {v:?} is not a whole number from 1 to {}",
                            crate::gpu::MAX_SOFT_SAMPLES
                        ))
                    })?;
            }
            "rotate" => {
                rotate = v
                    .parse()
                    .map_err(|_| err(format!("rotate {v:?} is not true or false")))?;
            }
            _ => return Err(err(format!("unknown key {k:?} (radius, samples, rotate)"))),
        }
    }
    let (lo, hi) = desc
        .scene
        .bounds()
        .ok_or_else(|| err("the scene is empty".into()))?;
    let centre = (lo + hi) * 0.5;
    let position = desc
        .lights
        .first()
        .and_then(|l| l.center())
        .unwrap_or_else(|| default_view(&desc.scene).1.center().unwrap_or(hi));
    let toward = centre - position;
    let distance = toward.length();
    if !(distance > 0.0 && distance.is_finite()) {
        return Err(err("the light is at the scene's centre".into()));
    }
    let normal = toward / distance;
    let tangent = default_tangent(normal);
    let r = radius.unwrap_or(0.1 * distance);
    if radius.is_some() && !matches!(kind, "sphere" | "disk" | "rect") {
        return Err(err(format!("a {kind} light has no radius")));
    }
    let (shape, samples) = match kind {
        "point" => (LightShape::Point { position }, 1),
        "directional" => (LightShape::Directional { direction: normal }, 1),
        "sphere" => (
            LightShape::Sphere {
                position,
                radius: r,
            },
            samples,
        ),
        "disk" => (
            LightShape::Disk {
                position,
                radius: r,
                normal,
                tangent,
            },
            samples,
        ),
        "rect" => (
            LightShape::Rect {
                position,
                size: DVec2::splat(2.0 * r),
                normal,
                tangent,
            },
            samples,
        ),
        _ => {
            return Err(err(format!(
                "unknown kind {kind:?} (point, directional, sphere, disk, rect)"
            )))
        }
    };
    let template = desc
        .lights
        .first()
        .cloned()
        .unwrap_or(default_view(&desc.scene).1);
    // The first light's texture goes only to a light that can carry one.
    let textured = matches!(shape, LightShape::Rect { .. } | LightShape::Disk { .. });
    let light = Light {
        shape,
        samples,
        per_pixel_rotation: rotate,
        emission: template.emission.clone().filter(|_| textured),
        ..template
    };
    light.validate().map_err(|e| err(strip_prefix(&e)))?;
    desc.lights = vec![light];
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replace_light_keeps_a_texture_only_where_it_fits() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/stained_glass.toml");
        let textured = load(path.to_str().unwrap()).unwrap();
        assert!(textured.lights[0].emission.is_some());
        let mut desc = textured.clone();
        replace_light(&mut desc, "sphere").unwrap();
        assert!(desc.lights[0].emission.is_none());
        let mut desc = textured.clone();
        replace_light(&mut desc, "rect").unwrap();
        assert!(desc.lights[0].emission.is_some());
        let mut desc = textured;
        let e = replace_light(&mut desc, "disk:rotate=true")
            .unwrap_err()
            .to_string();
        assert!(e.contains("texture"), "{e}");
    }

    #[test]
    fn replace_light_puts_the_kind_where_the_light_was() {
        let mut desc = load("builtin:plane_sphere").unwrap();
        let at = desc.lights[0].center().unwrap();
        let (lo, hi) = desc.scene.bounds().unwrap();
        let d = at.distance((lo + hi) * 0.5);
        replace_light(&mut desc, "sphere").unwrap();
        assert_eq!(desc.lights.len(), 1);
        match desc.lights[0].shape {
            LightShape::Sphere { position, radius } => {
                assert_eq!(position, at);
                assert!((radius - 0.1 * d).abs() < 1e-12);
            }
            ref s => panic!("{s:?}"),
        }
        assert_eq!(desc.lights[0].samples, 128);
        replace_light(&mut desc, "disk:radius=0.25,samples=64").unwrap();
        let LightShape::Disk { radius, normal, .. } = desc.lights[0].shape else {
            panic!("a disk")
        };
        assert_eq!((radius, desc.lights[0].samples), (0.25, 64));
        // Facing the scene's centre.
        assert!(normal.dot(((lo + hi) * 0.5 - at).normalize()) > 0.999_999);
        replace_light(&mut desc, "point").unwrap();
        assert_eq!(desc.lights[0].samples, 1);
        replace_light(&mut desc, "rect:radius=0.5").unwrap();
        assert!(
            matches!(desc.lights[0].shape, LightShape::Rect { size, .. } if size == DVec2::ONE)
        );
        desc.validate().unwrap();
    }

    #[test]
    fn replace_light_names_what_is_wrong() {
        let mut desc = load("builtin:plane_sphere").unwrap();
        for (spec, needle) in [
            ("lamp", "unknown kind \"lamp\""),
            ("sphere:radius=-1", "radius must be positive"),
            ("sphere:radius=x", "radius \"x\" is not a number"),
            (
                "sphere:samples=0",
                "samples \"0\" is not a whole number from 1 to 1024",
            ),
            ("sphere:samples=2000", "from 1 to 1024"),
            ("sphere:colour=red", "unknown key \"colour\""),
            ("sphere:radius", "\"radius\" is not KEY=VALUE"),
            ("point:radius=1", "a point light has no radius"),
        ] {
            let e = replace_light(&mut desc, spec).unwrap_err().to_string();
            assert!(e.contains(needle) && e.contains(spec), "{spec}: {e}");
        }
    }

    fn parse(text: &str) -> Result<SceneDescription> {
        parse_scene_file(text, Path::new("/nonexistent/scene.toml"))
    }

    #[test]
    fn full_example_parses() {
        let d = parse(
            r#"
scene = "builtin:plane_sphere"
ground = { y = -1.0, half_size = 10.0 }
[camera]
eye = [0.0, 2.0, 5.0]
target = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 45.0
width = 64
height = 32
[[light]]
kind = "sphere"
position = [2.0, 5.0, 1.0]
radius = 0.5
samples = 256
distribution = "sobol"
seed = 3
[[light]]
kind = "rect"
position = [0.0, 4.0, 0.0]
size = [1.0, 0.5]
normal = [0.0, -1.0, 0.0]
[[light]]
kind = "directional"
direction = [0.0, -2.0, 0.0]
[shadows]
light_texels = 256
mode = "exact"
lut_resolution = 64
"#,
        )
        .unwrap();
        assert_eq!(d.camera.width, 64);
        assert_eq!(d.lights.len(), 3);
        assert_eq!(d.lights[0].samples, 256);
        assert_eq!(d.lights[0].distribution, Distribution::Sobol);
        assert_eq!(d.lights[1].samples, DEFAULT_AREA_SAMPLES);
        match &d.lights[1].shape {
            LightShape::Rect { tangent, .. } => {
                // normalize(cross(-y, +y)) is degenerate -> +x
                assert_eq!(*tangent, DVec3::X)
            }
            s => panic!("{s:?}"),
        }
        assert_eq!(
            d.lights[2].shape,
            LightShape::Directional {
                direction: DVec3::NEG_Y
            }
        );
        assert_eq!(d.shadows.mode, SoftMode::Exact);
        assert_eq!(d.shadows.light_texels, LightTexels::Fixed(256));
        assert_eq!(d.shadows.soft_light_texels, LightTexels::Auto);
    }

    #[test]
    fn light_texels_auto_or_a_number() {
        for (text, want) in [
            ("light_texels = \"auto\"", LightTexels::Auto),
            ("light_texels = 96", LightTexels::Fixed(96)),
        ] {
            let d = parse(&format!("scene = \"builtin:demo\"\n[shadows]\n{text}\n")).unwrap();
            assert_eq!(d.shadows.light_texels, want, "{text}");
        }
        for bad in ["\"fine\"", "-3", "0", "16385", "5000000000"] {
            let e = parse(&format!(
                "scene = \"builtin:demo\"\n[shadows]\nsoft_light_texels = {bad}\n"
            ))
            .unwrap_err()
            .to_string();
            assert!(e.contains("soft_light_texels"), "{bad}: {e}");
        }
        assert_eq!("auto".parse::<LightTexels>(), Ok(LightTexels::Auto));
        assert_eq!("64".parse::<LightTexels>(), Ok(LightTexels::Fixed(64)));
        assert!("sixty".parse::<LightTexels>().is_err());
        for t in [LightTexels::Auto, LightTexels::Fixed(40)] {
            assert_eq!(t.to_string().parse::<LightTexels>(), Ok(t));
        }
    }

    #[test]
    fn auto_light_texels_follow_samples_and_triangles() {
        let (lo, hi) = LightTexels::AUTO_RANGE;
        assert_eq!(LightTexels::Fixed(7).resolve(1 << 20, 1 << 20, false), 7);
        // A 512² frame of 5 000 triangles (the demo) takes 192 texels for
        // hard shadows and 120 for soft ones.
        assert_eq!(LightTexels::Auto.resolve(512 * 512, 5000, false), 192);
        assert_eq!(LightTexels::Auto.resolve(512 * 512, 5000, true), 120);
        let mut last = 0;
        for n in [0usize, 1, 100, 10_000, 1 << 20, 1 << 26, usize::MAX] {
            for t in [0usize, 1, 1000, 100_000, 1 << 30, usize::MAX] {
                for soft in [false, true] {
                    let r = LightTexels::Auto.resolve(n, t, soft);
                    assert!(
                        (lo..=hi).contains(&r) && r.is_multiple_of(8),
                        "{n} {t} {soft}: {r}"
                    );
                    let finer = LightTexels::Auto.resolve(n.saturating_mul(4), t, soft);
                    assert!(finer >= r, "more samples, coarser: {n} {t}");
                    let finer = LightTexels::Auto.resolve(n, t.saturating_mul(4), soft);
                    assert!(finer >= r, "more triangles, coarser: {n} {t}");
                }
            }
            last = last.max(LightTexels::Auto.resolve(n, 1 << 20, false));
        }
        assert_eq!(last, hi);
    }

    #[test]
    fn unknown_key_is_named() {
        let e = parse("scene = \"builtin:demo\"\nfoo = 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("foo"), "{e}");
        let e = parse(
            "scene = \"builtin:demo\"\n[camera]\neye=[0.0,0.0,1.0]\ntarget=[0.0,0.0,0.0]\nfovy=3\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("fovy"), "{e}");
        let e = parse("scene = \"builtin:demo\"\n[[light]]\nkind=\"point\"\nposition=[0.0,1.0,0.0]\nradius2=1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("radius2"), "{e}");
    }

    #[test]
    fn wrong_type_is_named() {
        let e = parse("scene = \"builtin:demo\"\n[shadows]\nlight_texels = \"big\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("light_texels"), "{e}");
        let e = parse("scene = 3\n").unwrap_err().to_string();
        assert!(e.contains("scene"), "{e}");
        let e = parse("scene = \"builtin:demo\"\n[[light]]\nkind=\"laser\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("laser"), "{e}");
    }

    #[test]
    fn bad_values_are_errors() {
        for (text, needle) in [
            (
                "[[light]]\nkind=\"point\"\nposition=[0.0,1.0,0.0]\nsamples=4\n",
                "samples",
            ),
            (
                "[[light]]\nkind=\"sphere\"\nposition=[0.0,1.0,0.0]\nradius=0.5\nsamples=0\n",
                "samples",
            ),
            (
                "[[light]]\nkind=\"sphere\"\nposition=[0.0,1.0,0.0]\nradius=0.5\nsamples=5000\n",
                "samples",
            ),
            (
                "[[light]]\nkind=\"sphere\"\nposition=[0.0,1.0,0.0]\nradius=-1.0\n",
                "radius",
            ),
            (
                "[[light]]\nkind=\"sphere\"\nposition=[0.0,1.0,0.0]\n",
                "radius",
            ),
            (
                "[[light]]\nkind=\"point\"\nposition=[0.0,nan,0.0]\n",
                "position",
            ),
            (
                "[[light]]\nkind=\"directional\"\ndirection=[0.0,0.0,0.0]\n",
                "direction",
            ),
            (
                "[camera]\neye=[0.0,0.0,1.0]\ntarget=[0.0,0.0,0.0]\nwidth=0\n",
                "size",
            ),
            ("[camera]\neye=[0.0,inf,1.0]\ntarget=[0.0,0.0,0.0]\n", "eye"),
            ("[shadows]\nlight_texels=0\n", "light_texels"),
            ("ground = { y = nan, half_size = 1.0 }\n", "ground"),
        ] {
            let e = parse(&format!("scene = \"builtin:plane_sphere\"\n{text}"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }

    #[test]
    fn malformed_toml_is_an_error() {
        let e = parse("scene = \"builtin:demo\n").unwrap_err().to_string();
        assert!(e.contains("scene.toml"), "{e}");
    }
}
