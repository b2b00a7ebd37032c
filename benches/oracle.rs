//! Oracle speed: shadow rays per second on the built-in demo scene.
//! `cargo bench --bench oracle`; timings live here, never in tests.

use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::scene::file;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn oracle(c: &mut Criterion) {
    let mut desc = file::load("builtin:demo").expect("demo scene");
    desc.camera.width = 128;
    desc.camera.height = 128;
    let oracle = Oracle::new(&desc.scene.triangles(), desc.camera.eye);
    let view = oracle.primary_view_samples(&desc.camera);
    let samples = desc.lights[0].light_samples();
    let rays = view.samples.iter().filter(|s| s.is_some()).count() * samples.len();
    let mut g = c.benchmark_group("oracle");
    g.sample_size(10);
    g.throughput(Throughput::Elements(rays as u64));
    g.bench_function("demo_128x128_shadow_rays", |b| {
        b.iter(|| oracle.visibility(&view, &samples, None))
    });
    g.bench_function("demo_128x128_primary_rays", |b| {
        b.iter(|| oracle.primary_view_samples(&desc.camera))
    });
    g.finish();
}

criterion_group!(benches, oracle);
criterion_main!(benches);
