//! Frame times of [`Engine::render`] on the default Vulkan device (lavapipe
//! here), whole frame and per pass, for the sweeps of Sintorn et al. 2008 §5.
//!
//! Groups (one sweep each; every other setting stays at the scene's default,
//! 512² and 128 light samples in look-up mode unless the sweep varies it):
//!
//! | group            | scene                     | varies                                   |
//! |------------------|---------------------------|------------------------------------------|
//! | `triangles_hard` | `torus_knot:N`, point light | N = 1k, 10k, 30k, 100k (and `demo`)    |
//! | `triangles_soft` | `torus_knot:N`, sphere light r = 0.4 | N = 1k, 10k, 30k, 100k        |
//! | `light_radius`   | `torus_knot:10000`, sphere light | r = 0.1, 0.2, 0.4, 0.8, 1.6        |
//! | `samples_lut`    | `demo`                    | light samples 32 … 1024, look-up texture |
//! | `samples_exact`  | `demo`                    | light samples 32 … 1024, exact plane tests |
//! | `resolution`     | `demo`                    | view 256², 512², 1024²                   |
//!
//! **Whole frame**: criterion's time is the wall time of one
//! `Engine::render` call: view samples, the shadow passes, reading back,
//! CPU shading and the dump (the light samples are generated on the CPU each
//! frame too). The plane look-up texture is cached per light shape and
//! built by the first frame of each benchmark, criterion's warm-up frame, so
//! **measured frames do not include the look-up texture build**; a measured
//! frame that did build it would be reported (`lut_built_frames`).
//!
//! **Per pass**: every measured frame's GPU timestamp times (the frame's
//! stats: `lights[0].stats.ms.*`, plus `view_samples_gpu`, `inputs_cpu`, `shade_cpu`,
//! the GPU sum `gpu_ms` and `total_ms`) are collected; the median of each over
//! the measured frames is printed after the benchmark and written to
//! `$CARGO_TARGET_DIR/bench-passes/<group>/<parameter>.json` (default
//! `target/bench-passes/`), with one `<group>.csv` per group (one row per
//! parameter, one column per pass) for plotting and ratios. A filtered run
//! rewrites a group's CSV with only the points that ran.
//!
//! lavapipe is slow (a 512² soft frame at 1024 samples takes seconds), so each
//! benchmark takes 10 samples of one frame each after one warm-up frame;
//! criterion warns that it cannot finish in the (short) target time, which
//! is expected. The whole run took 18 min 16 s (build included) on 2 idle
//! CPU cores with lavapipe; the exact-mode sweep is about half of it.
//!
//! Run everything: `cargo bench --bench frame`. Run one sweep with a
//! criterion filter (a regex on `group/parameter`):
//! `cargo bench --bench frame -- samples` (both sample sweeps),
//! `-- samples_exact`, `-- triangles` (hard and soft), `-- triangles_soft`,
//! `-- light_radius`, `-- resolution`, or one point: `-- 'samples_lut/1024$'`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::render::{Engine, FrameOptions};
use alias_free_shadows::scene::file::{self, SceneDescription, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;
use criterion::measurement::WallTime;
use criterion::{
    criterion_group, criterion_main, BenchmarkGroup, BenchmarkId, Criterion, SamplingMode,
};
use glam::DVec3;

/// Per-pass milliseconds of the measured frames of one benchmark.
#[derive(Default)]
struct PassTimes {
    /// Pass name → one value per measured frame.
    ms: BTreeMap<String, Vec<f64>>,
    frames: usize,
    /// Measured frames that built the look-up texture (expected 0).
    lut_built_frames: usize,
}

impl PassTimes {
    fn record(&mut self, stats: &serde_json::Value) {
        self.frames += 1;
        let mut push = |name: &str, v: Option<f64>| {
            if let Some(v) = v {
                self.ms.entry(name.to_string()).or_default().push(v);
            }
        };
        push("total_ms", stats["total_ms"].as_f64());
        for pass in ["view_samples_gpu", "inputs_cpu", "shade_cpu"] {
            push(pass, stats["ms"][pass].as_f64());
        }
        // One light in every benchmark scene.
        let light = &stats["lights"][0]["stats"];
        push("gpu_ms", light["gpu_ms"].as_f64());
        if let Some(passes) = light["ms"].as_object() {
            for (pass, v) in passes {
                push(pass, v.as_f64());
            }
        }
        if light["lut_built"].as_bool() == Some(true) {
            self.lut_built_frames += 1;
        }
    }

    fn medians(&self) -> BTreeMap<String, f64> {
        self.ms
            .iter()
            .map(|(k, v)| (k.clone(), median(v)))
            .collect()
    }
}

fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Where per-pass results go: next to criterion's own output.
fn pass_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("target"))
        .join("bench-passes")
}

/// One sweep: a criterion group plus the per-pass medians of its points.
struct Sweep<'a> {
    group: BenchmarkGroup<'a, WallTime>,
    name: String,
    /// (parameter, medians) of every point that ran (not filtered out).
    rows: Vec<(String, BTreeMap<String, f64>)>,
}

impl<'a> Sweep<'a> {
    fn new(c: &'a mut Criterion, name: &str) -> Self {
        let mut group = c.benchmark_group(name);
        // Frames take 0.1-15 s: one frame per sample, ten samples, and a
        // single warm-up frame (which builds the look-up texture).
        group
            .sample_size(10)
            .sampling_mode(SamplingMode::Flat)
            .warm_up_time(Duration::from_millis(1))
            .measurement_time(Duration::from_secs(2));
        Sweep {
            group,
            name: name.to_string(),
            rows: Vec::new(),
        }
    }

    /// Benchmarks whole frames of `desc` and collects their per-pass times.
    fn frame(&mut self, engine: &mut Engine, parameter: &str, desc: &SceneDescription) {
        let mut passes = PassTimes::default();
        let mut warm_up_done = false;
        self.group
            .bench_function(BenchmarkId::from_parameter(parameter), |b| {
                b.iter_custom(|iters| {
                    let mut elapsed = Duration::ZERO;
                    for _ in 0..iters {
                        let start = Instant::now();
                        let frame = engine.render(desc, FrameOptions::default()).expect("frame");
                        elapsed += start.elapsed();
                        // Criterion's first call is its warm-up (one frame
                        // with a 1 ms warm-up time): not a measured frame.
                        if warm_up_done {
                            passes.record(&frame.dump.stats);
                        }
                    }
                    warm_up_done = true;
                    elapsed
                })
            });
        // Filtered out by the command line: nothing ran.
        if passes.frames == 0 {
            return;
        }
        let medians = passes.medians();
        report(&self.name, parameter, &passes, &medians);
        self.rows.push((parameter.to_string(), medians));
    }

    /// Writes the group's CSV (only when some point ran).
    fn finish(self) {
        self.group.finish();
        if self.rows.is_empty() {
            return;
        }
        let mut columns: Vec<&String> = self.rows.iter().flat_map(|(_, m)| m.keys()).collect();
        columns.sort();
        columns.dedup();
        let mut csv = format!(
            "parameter,{}\n",
            columns
                .iter()
                .map(|c| c.as_str())
                .collect::<Vec<_>>()
                .join(",")
        );
        for (parameter, medians) in &self.rows {
            let cells: Vec<String> = columns
                .iter()
                .map(|c| medians.get(*c).map_or(String::new(), |v| format!("{v:.3}")))
                .collect();
            csv += &format!("{parameter},{}\n", cells.join(","));
        }
        let path = pass_dir().join(format!("{}.csv", self.name));
        if let Err(e) = std::fs::create_dir_all(pass_dir()).and_then(|_| std::fs::write(&path, csv))
        {
            eprintln!("could not write {}: {e}", path.display());
        } else {
            println!("per-pass medians: {}", path.display());
        }
    }
}

/// Prints a benchmark's per-pass medians (slowest first) and writes its JSON.
fn report(group: &str, parameter: &str, passes: &PassTimes, medians: &BTreeMap<String, f64>) {
    let mut by_time: Vec<(&String, &f64)> = medians
        .iter()
        .filter(|(k, _)| !matches!(k.as_str(), "total_ms" | "gpu_ms"))
        .collect();
    by_time.sort_by(|a, b| b.1.total_cmp(a.1));
    let list: Vec<String> = by_time.iter().map(|(k, v)| format!("{k} {v:.1}")).collect();
    println!(
        "{group}/{parameter}: median of {} frames: frame {:.1} ms, GPU passes {:.1} ms: {}",
        passes.frames,
        medians.get("total_ms").copied().unwrap_or(f64::NAN),
        medians.get("gpu_ms").copied().unwrap_or(f64::NAN),
        list.join(", ")
    );
    if passes.lut_built_frames > 0 {
        println!(
            "  warning: {} measured frame(s) built the look-up texture",
            passes.lut_built_frames
        );
    }
    let dir = pass_dir().join(group);
    let json = serde_json::json!({
        "group": group,
        "parameter": parameter,
        "frames": passes.frames,
        "lut_built_frames": passes.lut_built_frames,
        "median_ms": medians,
        "frames_ms": passes.ms,
    });
    let path = dir.join(format!("{parameter}.json"));
    let written = std::fs::create_dir_all(&dir).and_then(|_| {
        std::fs::write(
            &path,
            serde_json::to_string_pretty(&json).expect("JSON of numbers"),
        )
    });
    if let Err(e) = written {
        eprintln!("could not write {}: {e}", path.display());
    }
}

/// A built-in scene at `size`² pixels.
fn scene(spec: &str, size: u32) -> SceneDescription {
    let mut desc = file::load(spec).expect("built-in scene");
    desc.camera.width = size;
    desc.camera.height = size;
    desc
}

/// The scene's one light replaced by a point light at its centre.
fn with_point_light(mut desc: SceneDescription) -> SceneDescription {
    let light = &desc.lights[0];
    let position = light.center().expect("a built-in light has a centre");
    desc.lights = vec![Light {
        shape: LightShape::Point { position },
        samples: 1,
        ..light.clone()
    }];
    desc
}

/// The scene's one light replaced by a sphere light at its centre.
fn with_sphere_light(mut desc: SceneDescription, radius: f64, samples: u32) -> SceneDescription {
    let light = &desc.lights[0];
    let position: DVec3 = light.center().expect("a built-in light has a centre");
    desc.lights = vec![Light {
        shape: LightShape::Sphere { position, radius },
        samples,
        ..light.clone()
    }];
    desc
}

const TORUS_KNOT_TRIANGLES: [u32; 4] = [1_000, 10_000, 30_000, 100_000];
const LIGHT_SAMPLES: [u32; 5] = [32, 128, 256, 512, 1024];
/// Radius of the sphere light in the triangle sweep, and the default of
/// the radius sweep's scene (at about 5 units from the knot).
const SOFT_RADIUS: f64 = 0.4;
const VIEW: u32 = 512;

fn frames(c: &mut Criterion) {
    let mut engine = Engine::new(&ContextOptions::default()).expect("a Vulkan device");

    let mut sweep = Sweep::new(c, "triangles_hard");
    for n in TORUS_KNOT_TRIANGLES {
        let desc = with_point_light(scene(&format!("builtin:torus_knot:{n}"), VIEW));
        sweep.frame(&mut engine, &n.to_string(), &desc);
    }
    sweep.frame(
        &mut engine,
        "demo",
        &with_point_light(scene("builtin:demo", VIEW)),
    );
    sweep.finish();

    let mut sweep = Sweep::new(c, "triangles_soft");
    for n in TORUS_KNOT_TRIANGLES {
        let knot = scene(&format!("builtin:torus_knot:{n}"), VIEW);
        let desc = with_sphere_light(knot, SOFT_RADIUS, 128);
        sweep.frame(&mut engine, &n.to_string(), &desc);
    }
    sweep.finish();

    let mut sweep = Sweep::new(c, "light_radius");
    for radius in [0.1, 0.2, 0.4, 0.8, 1.6] {
        let knot = scene("builtin:torus_knot:10000", VIEW);
        let desc = with_sphere_light(knot, radius, 128);
        sweep.frame(&mut engine, &radius.to_string(), &desc);
    }
    sweep.finish();

    for (name, mode) in [
        ("samples_lut", SoftMode::Lut),
        ("samples_exact", SoftMode::Exact),
    ] {
        let mut sweep = Sweep::new(c, name);
        for samples in LIGHT_SAMPLES {
            let mut desc = scene("builtin:demo", VIEW);
            desc.lights[0].samples = samples;
            desc.shadows.mode = mode;
            sweep.frame(&mut engine, &samples.to_string(), &desc);
        }
        sweep.finish();
    }

    let mut sweep = Sweep::new(c, "resolution");
    for size in [256, 512, 1024] {
        let desc = scene("builtin:demo", size);
        sweep.frame(&mut engine, &size.to_string(), &desc);
    }
    sweep.finish();

    // Perforated casters (alpha-tested lattice): the same scene with its
    // alpha tests, and with them off (opaque), hard and soft.
    let mut sweep = Sweep::new(c, "perforated");
    for (name, masks) in [("masked", true), ("opaque", false)] {
        let mut fence = scene("builtin:fence", VIEW);
        if !masks {
            for m in &mut fence.scene.materials {
                m.alpha_mode = alias_free_shadows::scene::AlphaMode::Opaque;
            }
        }
        let hard = with_point_light(fence.clone());
        sweep.frame(&mut engine, &format!("hard_{name}"), &hard);
        let soft = with_sphere_light(fence, 0.4, 128);
        sweep.frame(&mut engine, &format!("soft_{name}"), &soft);
    }
    sweep.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);
