//! Frame time of the alias-free hard-shadow path on the default Vulkan
//! device (lavapipe here): whole frames at 512² with warm pipelines.
//! `cargo bench --bench hard_shadows`; per-pass times are in
//! `afs render SCENE --stats --repeat 3`.

use alias_free_shadows::light::{Distribution, Light, LightShape};
use alias_free_shadows::render::{Engine, FrameOptions};
use alias_free_shadows::scene::file;
use alias_free_shadows::vulkan::ContextOptions;
use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;

fn hard_shadows(c: &mut Criterion) {
    let mut engine = Engine::new(&ContextOptions::default()).expect("a Vulkan device");
    let mut g = c.benchmark_group("hard_shadows_512");
    g.sample_size(10);
    for spec in [
        "builtin:demo",
        "builtin:torus_knot:10000",
        "builtin:torus_knot:100000",
    ] {
        let mut desc = file::load(spec).expect("built-in scene");
        desc.camera.width = 512;
        desc.camera.height = 512;
        // Hard shadows: a point light where the scene's light is.
        let centre = desc.lights[0].center().unwrap_or(DVec3::new(3.0, 8.0, 2.0));
        desc.lights = vec![Light {
            shape: LightShape::Point { position: centre },
            samples: 1,
            distribution: Distribution::Poisson,
            seed: 7,
            color: [1.0; 3],
            intensity: 1.0,
        }];
        engine
            .render(&desc, FrameOptions::default())
            .expect("warm-up frame");
        g.bench_function(spec, |b| {
            b.iter(|| {
                engine
                    .render(&desc, FrameOptions::default())
                    .expect("frame")
            })
        });
    }
    g.finish();
}

criterion_group!(benches, hard_shadows);
criterion_main!(benches);
