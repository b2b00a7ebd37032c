//! Ours against Embree, side by side in one process (the yardstick of
//! issue 14): per scene, our warm frame ([`Engine::render`]: view samples,
//! the shadow passes, read-back, shading) against Embree casting the same
//! shadow rays (our frame's own view samples, the same light samples, the
//! normal rule, all threads), for
//!
//! - soft shadows from the bench's sphere light (the scene's own, else one
//!   at its light with a radius a tenth of its distance to the scene) with
//!   128 and 1024 samples, in exact mode (and in look-up mode);
//! - hard shadows from a point light at the sphere's centre.
//!
//! Scenes: `builtin:torus_knot:100000`, `builtin:hairball` and, when
//! `../shared/assets` is there, ToyCar and TransmissionTest on a ground;
//! 512² (`AFS_EMBREE_SIZE`), `AFS_EMBREE_REPEATS` warm frames each (3; the
//! median is reported). Embree runs both ways (`rtcOccluded1` and packets
//! of eight, `rtcOccluded8`) and the faster counts; its time is the wall
//! time of casting the rays (the BVH build is reported apart). Prints a
//! table and writes `$CARGO_TARGET_DIR/bench-embree.csv` (default
//! `target/`).
//!
//! `cargo bench --features embree --bench embree` (`-- NAME` runs the scenes
//! whose name contains NAME; `AFS_EMBREE_CONFIGS=hard,soft 128` only the
//! configurations whose name contains one of those; `AFS_EMBREE_PASSES=1`
//! also prints where our last frame's time went, phase by phase and pass
//! by pass).

use std::path::{Path, PathBuf};

use alias_free_shadows::baselines::embree::{self, EmbreeScene, RayMode};
use alias_free_shadows::bench::{bench_light, hard_light, load_scene};
use alias_free_shadows::light::Light;
use alias_free_shadows::render::{Engine, FrameOptions};
use alias_free_shadows::scene::file::{SceneDescription, SoftMode};
use alias_free_shadows::stats::Stats;
use alias_free_shadows::vulkan::ContextOptions;

fn env_u32(key: &str, default: u32) -> u32 {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn scenes() -> Vec<String> {
    let mut s = vec![
        "builtin:torus_knot:100000".to_string(),
        "builtin:hairball".to_string(),
    ];
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets");
    for m in [
        "ToyCar/ToyCar.gltf",
        "TransmissionTest/TransmissionTest.glb",
    ] {
        let p = shared.join(m);
        if p.is_file() {
            s.push(p.display().to_string());
        }
    }
    s
}

struct Row {
    scene: String,
    config: String,
    ours_ms: f64,
    tests_per_sample: f64,
    embree_ms: f64,
    embree_mode: &'static str,
    rays: u64,
    build_ms: f64,
    /// View samples where ours and Embree differ by more than one light sample.
    differ: usize,
    samples: usize,
}

/// Our warm frames of `desc` lit by `light`: the median total and the last frame.
fn ours(
    engine: &mut Engine,
    desc: &SceneDescription,
    light: &Light,
    mode: SoftMode,
    repeats: u32,
) -> (f64, alias_free_shadows::render::Frame) {
    let mut d = desc.clone();
    d.lights = vec![light.clone()];
    d.shadows.mode = mode;
    let mut frame = engine.render(&d, FrameOptions::default()).expect("frame");
    let mut times = Vec::new();
    for _ in 0..repeats {
        frame = engine.render(&d, FrameOptions::default()).expect("frame");
        times.push(frame.stats.total_ms());
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], frame)
}

fn main() {
    let size = env_u32("AFS_EMBREE_SIZE", 512);
    let repeats = env_u32("AFS_EMBREE_REPEATS", 3).max(1);
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let threads = rayon::current_num_threads();
    let mut engine = Engine::new(&ContextOptions::default()).expect("engine");
    let mut rows = Vec::new();
    for spec in scenes() {
        if filter.as_ref().is_some_and(|f| !spec.contains(f.as_str())) {
            continue;
        }
        let desc = load_scene(&spec, size).expect("scene");
        let short = spec.rsplit('/').next().unwrap_or(&spec).to_string();
        let eye = desc.camera.eye;
        let scene = EmbreeScene::from_scene(&desc.scene, eye, threads).expect("embree scene");
        let configs: Vec<(String, Light, SoftMode)> = vec![
            ("hard".into(), hard_light(&desc).unwrap(), SoftMode::Exact),
            (
                "soft 128 exact".into(),
                bench_light(&desc, 128).unwrap(),
                SoftMode::Exact,
            ),
            (
                "soft 128 lut".into(),
                bench_light(&desc, 128).unwrap(),
                SoftMode::Lut,
            ),
            (
                "soft 1024 exact".into(),
                bench_light(&desc, 1024).unwrap(),
                SoftMode::Exact,
            ),
            (
                "soft 1024 lut".into(),
                bench_light(&desc, 1024).unwrap(),
                SoftMode::Lut,
            ),
        ];
        let show_passes = std::env::var("AFS_EMBREE_PASSES").is_ok_and(|v| v != "0");
        let wanted = std::env::var("AFS_EMBREE_CONFIGS").ok();
        let wanted = |c: &str| {
            wanted
                .as_deref()
                .is_none_or(|w| w.split(',').any(|p| c.contains(p.trim())))
        };
        for (config, light, mode) in configs.into_iter().filter(|c| wanted(&c.0)) {
            let (ours_ms, frame) = ours(&mut engine, &desc, &light, mode, repeats);
            let Stats::Gpu(stats) = &frame.stats else {
                unreachable!("a GPU frame")
            };
            let ls = &stats.lights[0].stats;
            let samples = stats.counters.view_samples;
            let mut best: Option<(f64, &'static str, embree::EmbreeShadows)> = None;
            for (ray_mode, name) in [
                (RayMode::Single, "rtcOccluded1"),
                (RayMode::Packets8, "rtcOccluded8"),
            ] {
                let mut times = Vec::new();
                let mut last = None;
                for _ in 0..repeats {
                    let e = embree::light_shadows(
                        &scene,
                        &desc.scene,
                        eye,
                        &frame.view.samples,
                        &light,
                        threads,
                        ray_mode,
                    )
                    .expect("embree");
                    times.push(e.ms);
                    last = Some(e);
                }
                times.sort_by(f64::total_cmp);
                let ms = times[times.len() / 2];
                if best.as_ref().is_none_or(|b| ms < b.0) {
                    best = Some((ms, name, last.unwrap()));
                }
            }
            let (embree_ms, embree_mode, e) = best.unwrap();
            let n_light = light.light_samples().len() as f32;
            let ours_vis = &frame.dump.visibility[0];
            let differ = e
                .visibility
                .iter()
                .zip(ours_vis)
                .filter(|(e, o)| e.is_some_and(|v| (v - o[0]).abs() * n_light > 1.5))
                .count();
            let row = Row {
                scene: short.clone(),
                config,
                ours_ms,
                tests_per_sample: ls.view_sample_triangle_tests as f64 / samples.max(1) as f64,
                embree_ms,
                embree_mode,
                rays: e.rays,
                build_ms: scene.build_ms,
                differ,
                samples,
            };
            println!(
                "{:>18} {:>16}: ours {:>9.1} ms ({:>7.1} tests/sample) | Embree {:>8.1} ms ({}, {} rays, {:.1} M rays/s, build {:.0} ms) | ours/Embree {:>6.2} | differ on {} of {} samples",
                row.scene,
                row.config,
                row.ours_ms,
                row.tests_per_sample,
                row.embree_ms,
                row.embree_mode,
                row.rays,
                row.rays as f64 / row.embree_ms * 1e-3,
                row.build_ms,
                row.ours_ms / row.embree_ms,
                row.differ,
                row.samples
            );
            if show_passes {
                // Where our last frame's time went (ms; the light's passes
                // by name, GPU time where the device has timestamps).
                let passes: Vec<String> = ls
                    .ms
                    .iter()
                    .filter_map(|(k, v)| v.map(|v| format!("{k} {v:.1}")))
                    .collect();
                println!(
                    "{:>18} {:>16}  view samples {:.1}, inputs {:.1}, shading {:.1}; light {}",
                    "",
                    "",
                    stats.ms.view_samples_gpu,
                    stats.ms.inputs_cpu,
                    stats.ms.shade_cpu,
                    passes.join(", ")
                );
            }
            rows.push(row);
        }
    }
    let dir = std::env::var("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
    let mut csv = String::from("scene,config,ours_ms,tests_per_view_sample,embree_ms,embree_mode,embree_rays,embree_rays_per_s,embree_build_ms,ours_over_embree,samples_differ,view_samples,threads\n");
    for r in &rows {
        csv.push_str(&format!(
            "{},{},{:.2},{:.2},{:.2},{},{},{:.0},{:.1},{:.4},{},{},{}\n",
            r.scene,
            r.config,
            r.ours_ms,
            r.tests_per_sample,
            r.embree_ms,
            r.embree_mode,
            r.rays,
            r.rays as f64 / r.embree_ms * 1e3,
            r.build_ms,
            r.ours_ms / r.embree_ms,
            r.differ,
            r.samples,
            threads
        ));
    }
    let path = dir.join("bench-embree.csv");
    std::fs::create_dir_all(&dir).ok();
    std::fs::write(&path, csv).expect("csv");
    println!("wrote {}", path.display());
}
