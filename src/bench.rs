//! `afs bench`: run time against error for the alias-free soft shadows and
//! the [`crate::baselines`] module, on several scenes, against a
//! converged oracle image (the CPU oracle with many Sobol light samples).
//!
//! Every scene gets a sphere light ([`bench_light`]: the scene's own, or
//! one at its light a tenth as wide as its distance from the scene) and
//! square images of [`BenchOptions::size`]. Each
//! method runs over its parameters; a configuration's time is the median
//! wall time of [`BenchOptions::repeats`] runs (the pipelines are warm: the
//! engine and the baselines are made once), its error that of its first run
//! over the pixels with a view sample: visibility RMSE, maximum absolute
//! error, and the share of pixels off by more than 1/255. Results go to
//! `bench.csv` and `bench.png` (log time against log RMSE, one curve per
//! method, one panel per scene).

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::baselines::{self, Baselines, Bias, PcfSettings, PcssSettings, PerSampleSettings};
use crate::light::{Distribution, Light, LightShape};
use crate::oracle::{Oracle, ViewSamples};
use crate::render::Engine;
use crate::scene::file::{self, SceneDescription, ShadowSettings, SoftMode};
use crate::{Error, Result};
use glam::DVec3;

/// What `afs bench` runs.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Folder for `bench.csv` and `bench.png` (made when missing).
    pub out: PathBuf,
    /// Image width and height.
    pub size: u32,
    /// A tiny sweep (for tests): few, cheap configurations.
    pub quick: bool,
    /// Scene specs ([`file::load`]); glTF models are put on a ground plane.
    pub scenes: Vec<String>,
    /// Timed runs per configuration (the median is reported).
    pub repeats: u32,
    /// Light samples of the converged oracle image.
    pub reference_samples: u32,
    /// Show a progress bar on standard error.
    pub progress: bool,
}

/// The default scenes: four built-ins (`builtin:fence` with its
/// alpha-tested lattice), and the Lantern model when `../shared/assets`
/// (next to the crate) holds it.
pub fn default_scenes() -> Vec<String> {
    let mut s: Vec<String> = [
        "builtin:demo",
        "builtin:plane_sphere",
        "builtin:torus_knot:20000",
        "builtin:fence",
    ]
    .map(String::from)
    .to_vec();
    let lantern =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets/Lantern/Lantern.gltf");
    if lantern.is_file() {
        s.push(lantern.display().to_string());
    }
    s
}

/// One configuration's result: a row of `bench.csv`.
#[derive(Clone, Debug)]
pub struct BenchRow {
    /// The scene's name without its folders (`builtin:demo`, `Lantern.gltf`).
    pub scene: String,
    /// `ours-lut`, `ours-exact`, `pcf`, `pcss`, `per-sample-maps` or `oracle`.
    pub method: String,
    /// The method's parameters, `key=value` separated by spaces.
    pub params: String,
    /// Light samples the method used (0: not sample-based).
    pub light_samples: u32,
    /// Median wall milliseconds.
    pub time_ms: f64,
    /// Root mean square visibility error against the oracle's reference,
    /// over the pixels with a view sample.
    pub rmse: f64,
    /// Largest absolute visibility error of such a pixel.
    pub max_abs: f64,
    /// Share of pixels off by more than 1/255.
    pub share_over_1_255: f64,
}

/// One configuration of one method.
#[derive(Clone, Copy, Debug)]
enum Config {
    Ours {
        samples: u32,
        mode: SoftMode,
        lut_resolution: u32,
    },
    Pcf {
        resolution: u32,
        kernel: u32,
    },
    Pcss {
        resolution: u32,
        kernel: u32,
    },
    PerSample {
        samples: u32,
        resolution: u32,
    },
    Oracle {
        samples: u32,
    },
    /// Our hard shadows for a point light at the light's centre.
    OursHard,
    /// One shadow map (one tap) for that point light.
    MapHard {
        resolution: u32,
    },
    /// Embree's shadow rays (all threads) with the same light samples.
    #[cfg(feature = "embree")]
    Embree {
        samples: u32,
    },
    /// Embree's shadow rays for the point light of the hard-shadow rows.
    #[cfg(feature = "embree")]
    EmbreeHard,
}

impl Config {
    fn method(&self) -> &'static str {
        match self {
            Config::Ours {
                mode: SoftMode::Lut,
                ..
            } => "ours-lut",
            Config::Ours {
                mode: SoftMode::Approx,
                ..
            } => "ours-approx",
            Config::Ours { .. } => "ours-exact",
            Config::Pcf { .. } => "pcf",
            Config::Pcss { .. } => "pcss",
            Config::PerSample { .. } => "per-sample-maps",
            Config::Oracle { .. } => "oracle",
            Config::OursHard => "ours-hard",
            #[cfg(feature = "embree")]
            Config::Embree { .. } => "embree",
            #[cfg(feature = "embree")]
            Config::EmbreeHard => "embree-hard",
            Config::MapHard { .. } => "shadow-map-hard",
        }
    }

    /// Hard-shadow configurations: a point light at the light's centre,
    /// measured against the oracle's hard shadows.
    fn hard(&self) -> bool {
        match self {
            Config::OursHard | Config::MapHard { .. } => true,
            #[cfg(feature = "embree")]
            Config::EmbreeHard => true,
            _ => false,
        }
    }

    fn params(&self) -> String {
        match self {
            Config::Ours {
                samples,
                lut_resolution,
                mode,
            } => match mode {
                SoftMode::Lut | SoftMode::Approx => {
                    format!("samples={samples} lut={lut_resolution}")
                }
                SoftMode::Exact => format!("samples={samples}"),
            },
            Config::Pcf { resolution, kernel } | Config::Pcss { resolution, kernel } => {
                format!("map={resolution} kernel={kernel}")
            }
            Config::PerSample {
                samples,
                resolution,
            } => format!("samples={samples} map={resolution}"),
            Config::Oracle { samples } => format!("samples={samples}"),
            Config::OursHard => String::new(),
            #[cfg(feature = "embree")]
            Config::Embree { samples } => format!("samples={samples}"),
            #[cfg(feature = "embree")]
            Config::EmbreeHard => String::new(),
            Config::MapHard { resolution } => format!("map={resolution}"),
        }
    }

    fn light_samples(&self) -> u32 {
        match self {
            Config::Ours { samples, .. }
            | Config::PerSample { samples, .. }
            | Config::Oracle { samples } => *samples,
            #[cfg(feature = "embree")]
            Config::Embree { samples } => *samples,
            _ => 0,
        }
    }

    /// Runs that are slow (seconds each) are timed once: the oracle, 256
    /// or more shadow maps, and our exact mode at 512 or more samples.
    fn repeats(&self, repeats: u32) -> u32 {
        match self {
            Config::Oracle { .. } => 1,
            Config::PerSample { samples, .. } if *samples >= 256 => 1,
            Config::Ours {
                samples,
                mode: SoftMode::Exact,
                ..
            } if *samples >= 512 => 1,
            _ => repeats,
        }
    }
}

/// The parameter sweep. The default one is sized for about 5 minutes per
/// scene at 256² on lavapipe (2 cores).
fn sweep(quick: bool) -> Vec<Config> {
    let mut c = Vec::new();
    if quick {
        c.push(Config::Ours {
            samples: 32,
            mode: SoftMode::Lut,
            lut_resolution: 64,
        });
        c.push(Config::Pcf {
            resolution: 256,
            kernel: 1,
        });
        c.push(Config::Pcss {
            resolution: 256,
            kernel: 1,
        });
        c.push(Config::PerSample {
            samples: 8,
            resolution: 128,
        });
        c.push(Config::Oracle { samples: 8 });
        c.push(Config::OursHard);
        c.push(Config::MapHard { resolution: 256 });
        #[cfg(feature = "embree")]
        c.extend([Config::Embree { samples: 8 }, Config::EmbreeHard]);
        return c;
    }
    for samples in [32, 128, 512, 1024] {
        for mode in [SoftMode::Lut, SoftMode::Exact, SoftMode::Approx] {
            c.push(Config::Ours {
                samples,
                mode,
                lut_resolution: 128,
            });
        }
    }
    for lut_resolution in [64, 256] {
        c.push(Config::Ours {
            samples: 256,
            mode: SoftMode::Lut,
            lut_resolution,
        });
    }
    for resolution in [2048, 4096, 8192] {
        for kernel in [0, 1, 3] {
            c.push(Config::Pcf { resolution, kernel });
        }
    }
    for resolution in [2048, 4096] {
        for kernel in [2, 4] {
            c.push(Config::Pcss { resolution, kernel });
        }
    }
    for samples in [16, 64, 128, 256, 1024] {
        c.push(Config::PerSample {
            samples,
            resolution: 1024,
        });
    }
    c.push(Config::PerSample {
        samples: 128,
        resolution: 2048,
    });
    for samples in [16, 128] {
        c.push(Config::Oracle { samples });
    }
    c.push(Config::OursHard);
    #[cfg(feature = "embree")]
    {
        for samples in [32, 128, 512, 1024] {
            c.push(Config::Embree { samples });
        }
        c.push(Config::EmbreeHard);
    }
    for resolution in [2048, 8192] {
        c.push(Config::MapHard { resolution });
    }
    c
}

/// A scene as the bench uses it: glTF models on a ground, `size`² pixels.
pub fn load_scene(spec: &str, size: u32) -> Result<SceneDescription> {
    let mut desc = file::load(spec)?;
    if !spec.starts_with("builtin:") && !spec.ends_with(".toml") {
        file::place_on_ground(&mut desc.scene);
        let (camera, light) = file::default_view(&desc.scene);
        desc.camera = camera;
        desc.lights = vec![light];
    }
    desc.camera.width = size;
    desc.camera.height = size;
    desc.validate()?;
    Ok(desc)
}

/// The bench's light with extent: the scene's first light when it is a
/// sphere (the demo's), else a sphere at the scene's first light (above the
/// scene when it has no centre) whose radius is a tenth of its distance
/// from the centre of the scene's bounds (an angular radius of about 5.7°
/// seen from there; a share of the bounds' diagonal would follow the ground
/// plane's size instead of the objects').
pub fn bench_light(desc: &SceneDescription, samples: u32) -> Result<Light> {
    let (lo, hi) = desc
        .scene
        .bounds()
        .ok_or_else(|| Error::InvalidInput(format!("{}: the scene is empty", desc.name)))?;
    let first = desc.lights.first();
    let shape = match first.map(|l| &l.shape) {
        Some(sphere @ LightShape::Sphere { .. }) => sphere.clone(),
        _ => {
            let position = first
                .and_then(|l| l.center())
                .unwrap_or(hi + (hi - lo) * 0.5);
            let radius = 0.1 * position.distance((lo + hi) * 0.5);
            if !(radius > 0.0 && radius.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "{}: the light is at the centre of the scene; the bench needs it apart",
                    desc.name
                )));
            }
            LightShape::Sphere { position, radius }
        }
    };
    Ok(Light {
        shape,
        samples,
        distribution: first.map_or(Distribution::Poisson, |l| l.distribution),
        seed: first.map_or(7, |l| l.seed),
        color: [1.0; 3],
        intensity: 1.0,
        emission: None,
        per_pixel_rotation: false,
    })
}

/// The rows' scenes, each once, in order of appearance.
fn scene_names(rows: &[BenchRow]) -> Vec<&str> {
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    scenes
}

/// RMSE, maximum absolute error and share of values off by more than 1/255.
pub fn errors(got: &[f64], want: &[f64]) -> (f64, f64, f64) {
    let n = got.len().max(1) as f64;
    let mut se = 0.0;
    let mut max: f64 = 0.0;
    let mut over = 0usize;
    for (g, w) in got.iter().zip(want) {
        let d = (g - w).abs();
        se += d * d;
        max = max.max(d);
        over += usize::from(d > 1.0 / 255.0);
    }
    ((se / n).sqrt(), max, over as f64 / n)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

impl BenchOptions {
    /// A size in 1..=2048, at least one repeat and one scene.
    fn validate(&self) -> Result<()> {
        if self.size == 0 || self.size > 2048 {
            return Err(Error::InvalidInput(format!(
                "bench size must be in 1..=2048, got {}",
                self.size
            )));
        }
        if self.repeats == 0 {
            return Err(Error::InvalidInput(
                "bench repeats must be at least 1".into(),
            ));
        }
        if self.scenes.is_empty() {
            return Err(Error::InvalidInput("no scenes to bench".into()));
        }
        Ok(())
    }
}

/// The bench's progress bar over `len` steps.
fn progress_bar(len: u64) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg:>40} [{bar:30}] {pos}/{len}, {elapsed} (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    pb
}

/// Runs the sweep on every scene and writes `bench.csv` and `bench.png`
/// into `options.out`; returns the rows.
pub fn run(engine: &mut Engine, options: &BenchOptions) -> Result<Vec<BenchRow>> {
    options.validate()?;
    let scenes: Vec<SceneDescription> = options
        .scenes
        .iter()
        .map(|s| load_scene(s, options.size))
        .collect::<Result<_>>()?;
    std::fs::create_dir_all(&options.out).map_err(|e| Error::io(&options.out, e))?;
    let configs = sweep(options.quick);
    let mut baselines = Baselines::new(engine.context())?;
    let pb = options
        .progress
        .then(|| progress_bar((scenes.len() * (configs.len() + 1)) as u64));
    let mut rows = Vec::new();
    for desc in &scenes {
        let short = desc
            .name
            .rsplit('/')
            .next()
            .unwrap_or(&desc.name)
            .to_string();
        if let Some(pb) = &pb {
            pb.set_message(format!("{short}: reference"));
        }
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = f32_view_samples(&oracle, desc);
        let pixels: Vec<usize> = (0..view.samples.len())
            .filter(|&i| view.samples[i].is_some())
            .collect();
        let reference_light = Light {
            distribution: Distribution::Sobol,
            ..bench_light(desc, options.reference_samples)?
        };
        let reference = oracle.visibility(&view, &reference_light.light_samples(), None);
        let want: Vec<f64> = pixels.iter().map(|&i| reference[i] as f64).collect();
        let hard_light = hard_light(desc)?;
        let hard_reference = oracle.visibility(&view, &hard_light.light_samples(), None);
        let want_hard: Vec<f64> = pixels.iter().map(|&i| hard_reference[i] as f64).collect();
        if let Some(pb) = &pb {
            pb.inc(1);
        }
        for config in &configs {
            if let Some(pb) = &pb {
                pb.set_message(format!("{short}: {} {}", config.method(), config.params()));
            }
            let samples = config.light_samples().max(1);
            let light = if config.hard() {
                hard_light.clone()
            } else {
                bench_light(desc, samples)?
            };
            let mut times = Vec::new();
            let mut first = None;
            for _ in 0..config.repeats(options.repeats) {
                let t0 = Instant::now();
                let vis = run_config(engine, &mut baselines, desc, &view, &light, config)?;
                times.push(t0.elapsed().as_secs_f64() * 1e3);
                first.get_or_insert(vis);
            }
            let vis = first.expect("at least one run");
            let got: Vec<f64> = pixels
                .iter()
                .map(|&i| vis[i].unwrap_or(0.0) as f64)
                .collect();
            let (rmse, max_abs, over) =
                errors(&got, if config.hard() { &want_hard } else { &want });
            let row = BenchRow {
                scene: short.clone(),
                method: config.method().into(),
                params: config.params(),
                light_samples: config.light_samples(),
                time_ms: median(times),
                rmse,
                max_abs,
                share_over_1_255: over,
            };
            if let Some(pb) = &pb {
                pb.inc(1);
                // The bar is hidden when standard error is not a terminal
                // (a log file): then one line per configuration.
                if pb.is_hidden() {
                    eprintln!(
                        "[{:>4.0} s] {short}: {} {}: {:.1} ms, RMSE {:.2e}",
                        pb.elapsed().as_secs_f64(),
                        row.method,
                        row.params,
                        row.time_ms,
                        row.rmse
                    );
                }
            }
            rows.push(row);
        }
        // What is done so far survives an interrupted run.
        write_csv(&options.out.join("bench.csv"), &rows)?;
    }
    if let Some(pb) = pb {
        pb.finish_and_clear();
    }
    engine.context().check_validation()?;
    write_csv(&options.out.join("bench.csv"), &rows)?;
    plot(&options.out.join("bench.png"), &rows)?;
    let table = ratios(&rows);
    let path = options.out.join("bench-ratios.md");
    std::fs::write(&path, &table).map_err(|e| Error::io(&path, e))?;
    Ok(rows)
}

/// The key ratios (issue 6, the paper's §5) per scene, as a Markdown
/// table: run time of the first configuration over the second's, with
/// both RMSEs. A ratio whose rows are missing (a custom sweep) is left out.
pub fn ratios(rows: &[BenchRow]) -> String {
    const PAIRS: [(&str, &str, &str, &str, &str); 11] = [
        (
            "ours 128 (look-up) / Embree 128 (all threads)",
            "ours-lut",
            "samples=128 lut=128",
            "embree",
            "samples=128",
        ),
        (
            "ours 128 (exact) / Embree 128",
            "ours-exact",
            "samples=128",
            "embree",
            "samples=128",
        ),
        (
            "ours 1024 (look-up) / Embree 1024",
            "ours-lut",
            "samples=1024 lut=128",
            "embree",
            "samples=1024",
        ),
        (
            "ours hard / Embree hard",
            "ours-hard",
            "",
            "embree-hard",
            "",
        ),
        (
            "ours 128 (look-up) / ours 128 (approximate look-up)",
            "ours-lut",
            "samples=128 lut=128",
            "ours-approx",
            "samples=128 lut=128",
        ),
        (
            "ours 128 (look-up) / one shadow map per sample, 128 × 1024²",
            "ours-lut",
            "samples=128 lut=128",
            "per-sample-maps",
            "samples=128 map=1024",
        ),
        (
            "ours 128 (exact) / one shadow map per sample, 128 × 1024²",
            "ours-exact",
            "samples=128",
            "per-sample-maps",
            "samples=128 map=1024",
        ),
        (
            "ours 128 (look-up) / CPU oracle, 128 samples",
            "ours-lut",
            "samples=128 lut=128",
            "oracle",
            "samples=128",
        ),
        (
            "ours 1024 / ours 128 (look-up)",
            "ours-lut",
            "samples=1024 lut=128",
            "ours-lut",
            "samples=128 lut=128",
        ),
        (
            "ours 1024 / ours 128 (exact)",
            "ours-exact",
            "samples=1024",
            "ours-exact",
            "samples=128",
        ),
        (
            "ours hard / one 8192² shadow map",
            "ours-hard",
            "",
            "shadow-map-hard",
            "map=8192",
        ),
    ];
    let scenes = scene_names(rows);
    let find = |scene: &str, method: &str, params: &str| {
        rows.iter()
            .find(|r| r.scene == scene && r.method == method && r.params == params)
    };
    let mut s =
        String::from("| scene | ratio | time ratio | times (ms) | RMSE |\n|---|---|---|---|---|\n");
    for scene in scenes {
        for (name, m1, p1, m2, p2) in PAIRS {
            if let (Some(a), Some(b)) = (find(scene, m1, p1), find(scene, m2, p2)) {
                s.push_str(&format!(
                    "| {scene} | {name} | {:.2} | {:.1} / {:.1} | {:.2e} / {:.2e} |\n",
                    a.time_ms / b.time_ms,
                    a.time_ms,
                    b.time_ms,
                    a.rmse,
                    b.rmse
                ));
            }
        }
    }
    s
}

fn run_config(
    engine: &mut Engine,
    baselines: &mut Baselines,
    desc: &SceneDescription,
    view: &ViewSamples,
    light: &Light,
    config: &Config,
) -> Result<Vec<Option<f32>>> {
    let (scene, eye, samples) = (&desc.scene, desc.camera.eye, &view.samples);
    let bias = Bias::default();
    let ctx = engine.context();
    Ok(match *config {
        Config::Ours {
            mode,
            lut_resolution,
            ..
        } => {
            let settings = ShadowSettings {
                mode,
                lut_resolution,
                ..Default::default()
            };
            engine
                .soft_shadows(scene, eye, samples, light, &settings)?
                .visibility
        }
        Config::Pcf { resolution, kernel } => {
            let s = PcfSettings {
                resolution,
                kernel,
                bias,
            };
            baselines
                .pcf(ctx, scene, eye, samples, light, &s)?
                .visibility
        }
        Config::Pcss { resolution, kernel } => {
            let s = PcssSettings {
                resolution,
                kernel,
                max_radius_texels: resolution as f32 / 16.0,
                bias,
            };
            baselines
                .pcss(ctx, scene, eye, samples, light, &s)?
                .visibility
        }
        Config::PerSample { resolution, .. } => {
            let s = PerSampleSettings {
                resolution,
                kernel: 0,
                bias,
            };
            baselines
                .per_sample_maps(ctx, scene, eye, samples, light, &s)?
                .visibility
        }
        Config::Oracle { .. } => baselines::oracle(scene, eye, samples, light)?.visibility,
        Config::OursHard => engine
            .hard_shadows(
                scene,
                eye,
                samples,
                light,
                ShadowSettings::default().light_texels,
            )?
            .lit
            .iter()
            .map(|l| Some(if *l == Some(true) { 1.0 } else { 0.0 }))
            .collect(),
        Config::MapHard { resolution } => {
            let s = PcfSettings {
                resolution,
                kernel: 0,
                bias,
            };
            baselines
                .pcf(ctx, scene, eye, samples, light, &s)?
                .visibility
        }
        #[cfg(feature = "embree")]
        Config::Embree { .. } | Config::EmbreeHard => {
            baselines.embree(scene, eye, samples, light)?.visibility
        }
    })
}

/// The point light of the hard-shadow rows: at the bench light's centre.
pub fn hard_light(desc: &SceneDescription) -> Result<Light> {
    let soft = bench_light(desc, 1)?;
    Ok(Light {
        shape: LightShape::Point {
            position: soft.center().unwrap_or(DVec3::ZERO),
        },
        samples: 1,
        ..soft
    })
}

/// The oracle's primary view samples rounded through camera-relative f32,
/// as the GPU passes see them, so that every method sees the same points.
pub fn f32_view_samples(oracle: &Oracle, desc: &SceneDescription) -> ViewSamples {
    let eye = desc.camera.eye;
    let mut view = oracle.primary_view_samples(&desc.camera);
    for s in view.samples.iter_mut().flatten() {
        s.position = eye + (s.position - eye).as_vec3().as_dvec3();
        s.normal = s.normal.as_vec3().as_dvec3();
    }
    view
}

fn write_csv(path: &Path, rows: &[BenchRow]) -> Result<()> {
    let mut s = String::from(
        "scene,method,params,light_samples,time_ms,rmse,max_abs_error,share_over_1_255\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{:.3},{:.6e},{:.6e},{:.6e}\n",
            r.scene,
            r.method,
            r.params,
            r.light_samples,
            r.time_ms,
            r.rmse,
            r.max_abs,
            r.share_over_1_255
        ));
    }
    std::fs::write(path, s).map_err(|e| Error::io(path, e))
}

/// Registers a system sans-serif font for the plot's text, when one of the
/// usual files exists; without one the plot has no text.
fn register_font() -> bool {
    use std::sync::OnceLock;
    static FONT: OnceLock<bool> = OnceLock::new();
    *FONT.get_or_init(|| {
        for path in [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
        ] {
            if let Ok(bytes) = std::fs::read(path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font(
                    "sans-serif",
                    plotters::style::FontStyle::Normal,
                    bytes,
                )
                .is_ok()
                {
                    return true;
                }
            }
        }
        false
    })
}

/// The soft-shadow methods drawn, in legend order (colours by position).
/// `embree` rows exist only in a build with the `embree` feature.
const METHODS: [&str; 8] = [
    "ours-lut",
    "ours-exact",
    "pcf",
    "pcss",
    "per-sample-maps",
    "oracle",
    "ours-approx",
    "embree",
];

/// Log time against log RMSE of the soft-shadow methods, one curve per
/// method (its Pareto front; every configuration a dot), one panel per scene.
fn plot(path: &Path, rows: &[BenchRow]) -> Result<()> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| Error::InvalidInput(format!("plot: {e}"));
    let text = register_font();
    let scenes = scene_names(rows);
    let cols = scenes.len().clamp(1, 2);
    let rows_n = scenes.len().div_ceil(cols).max(1);
    let size = (640 * cols as u32, 480 * rows_n as u32);
    // Drawn into memory and written with the `image` crate (plotters'
    // own encoder would pull in a second `image`).
    let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let panels = root.split_evenly((rows_n, cols));
        let floor = 1e-5;
        for (scene, area) in scenes.iter().zip(panels.iter()) {
            let mine: Vec<&BenchRow> = rows
                .iter()
                .filter(|r| r.scene == *scene && METHODS.contains(&r.method.as_str()))
                .collect();
            let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for r in &mine {
                let t = r.time_ms.max(1e-3);
                let e = r.rmse.max(floor);
                (t0, t1, e0, e1) = (t0.min(t), t1.max(t), e0.min(e), e1.max(e));
            }
            if mine.is_empty() {
                continue;
            }
            let mut builder = ChartBuilder::on(area);
            builder.margin(10);
            if text {
                builder
                    .caption(*scene, ("sans-serif", 18))
                    .x_label_area_size(35)
                    .y_label_area_size(60);
            }
            let mut chart = builder
                .build_cartesian_2d(
                    (t0 / 1.5..t1 * 1.5).log_scale(),
                    (e0 / 1.5..e1 * 1.5).log_scale(),
                )
                .map_err(|e| err(&e))?;
            let mut mesh = chart.configure_mesh();
            if text {
                mesh.x_desc("time (ms)").y_desc("visibility RMSE");
            } else {
                mesh.disable_x_mesh().disable_y_mesh();
            }
            mesh.draw().map_err(|e| err(&e))?;
            for (k, method) in METHODS.iter().enumerate() {
                let mut pts: Vec<(f64, f64)> = mine
                    .iter()
                    .filter(|r| r.method == *method)
                    .map(|r| (r.time_ms.max(1e-3), r.rmse.max(floor)))
                    .collect();
                if pts.is_empty() {
                    continue;
                }
                pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
                // The curve joins the method's best trade-offs (no faster
                // configuration is as accurate); every configuration is a dot.
                let mut front: Vec<(f64, f64)> = Vec::new();
                for p in &pts {
                    if front.last().is_none_or(|f| p.1 < f.1) {
                        front.push(*p);
                    }
                }
                let color = Palette99::pick(k).to_rgba();
                let series = chart
                    .draw_series(LineSeries::new(front, color.stroke_width(2)))
                    .map_err(|e| err(&e))?;
                if text {
                    series.label(*method).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
                }
                chart
                    .draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))
                    .map_err(|e| err(&e))?;
            }
            if text {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .position(SeriesLabelPosition::LowerLeft)
                    .draw()
                    .map_err(|e| err(&e))?;
            }
        }
        root.present().map_err(|e| err(&e))?;
    }
    image::RgbImage::from_raw(size.0, size.1, pixels)
        .ok_or_else(|| Error::Image("plot buffer has the wrong size".into()))?
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| Error::Image(format!("{}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_of_known_values() {
        let (rmse, max, over) = errors(&[0.0, 1.0, 0.5, 0.5], &[0.0, 0.0, 0.5, 0.501]);
        assert!((rmse - 0.5).abs() < 1e-3);
        assert_eq!(max, 1.0);
        assert_eq!(over, 0.25);
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
    }
}
