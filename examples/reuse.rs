//! Frames that reuse what did not change: a scene under two coloured
//! sphere lights, rendered with `Engine::render_reusing` after each kind of
//! change, with each frame's time next to a frame that reuses nothing.
//!
//! `cargo run --release --example reuse [-- SCENE [SIZE [ROUNDS]]]`
//! (default `builtin:demo`, 64 pixels, 1 round; a glTF model stands on a
//! ground under its default view).
use std::time::Instant;

use alias_free_shadows::bench::{bench_light, load_scene};
use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::render::{Engine, FrameOptions, FrameReuse, Generations};
use alias_free_shadows::stats::Stats;
use alias_free_shadows::vulkan::ContextOptions;
use glam::DVec3;

fn main() -> alias_free_shadows::Result<()> {
    let mut args = std::env::args().skip(1);
    let spec = args.next().unwrap_or_else(|| "builtin:demo".into());
    let size: u32 = args.next().and_then(|s| s.parse().ok()).unwrap_or(64);
    let rounds: u32 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1);

    let mut desc = load_scene(&spec, size)?;
    let warm = bench_light(&desc, 128)?;
    let LightShape::Sphere { position, radius } = warm.shape else {
        unreachable!("the bench light is a sphere")
    };
    let (lo, hi) = desc.scene.bounds().expect("bench scenes have triangles");
    let side = (hi - lo).length() * 0.3;
    let cool_at = position + DVec3::new(-side, 0.0, side);
    desc.lights = vec![
        Light {
            color: [1.0, 0.7, 0.4],
            intensity: 0.7,
            ..warm.clone()
        },
        Light {
            shape: LightShape::Sphere {
                position: cool_at,
                radius,
            },
            color: [0.4, 0.6, 1.0],
            intensity: 0.7,
            ..warm
        },
    ];
    desc.validate()?;

    let mut engine = Engine::new(&ContextOptions::default())?;
    let opts = FrameOptions::default();
    let mut gens = Generations::new(2);
    let mut reuse = FrameReuse::new();
    // Pipelines, tables and buffers warm before anything is timed.
    engine.render_reusing(&desc, &gens, &mut reuse, opts)?;
    let timed = |engine: &mut Engine, desc: &_, gens: &_, reuse: &mut FrameReuse, what| {
        let t = Instant::now();
        let frame = engine.render_reusing(desc, gens, reuse, opts)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let reused = match &frame.stats {
            Stats::Gpu(s) => s.reused.clone().unwrap_or_default(),
            _ => Default::default(),
        };
        println!("{what:<28} {ms:9.1} ms  reused: {reused:?}");
        Ok::<f64, alias_free_shadows::Error>(ms)
    };
    for round in 0..rounds {
        println!("round {}", round + 1);
        reuse.clear();
        let full = timed(&mut engine, &desc, &gens, &mut reuse, "nothing reused")?;
        let same = timed(&mut engine, &desc, &gens, &mut reuse, "unchanged")?;
        if let LightShape::Sphere { position, .. } = &mut desc.lights[1].shape {
            *position += DVec3::new(0.05, 0.0, -0.05) * side;
        }
        gens.lights[1] += 1;
        let light = timed(&mut engine, &desc, &gens, &mut reuse, "one light moved")?;
        desc.camera.eye += (desc.camera.target - desc.camera.eye) * 0.02;
        gens.camera += 1;
        let camera = timed(&mut engine, &desc, &gens, &mut reuse, "camera moved")?;
        println!(
            "against nothing reused: unchanged {:.3}, one light moved {:.3}, camera moved {:.3}",
            same / full,
            light / full,
            camera / full
        );
    }
    engine.context().check_validation()
}
