//! Alias-free hard shadows on the GPU (lavapipe, validation on) against the
//! CPU oracle, fed exactly the same view samples; and the CPU twins chained.

use alias_free_shadows::cpu::alpha::AlphaTables;
use alias_free_shadows::cpu::hard_shadows::hard_shadows;
use alias_free_shadows::cpu::light_view::LightView;
use alias_free_shadows::gpu::alpha::mark_alpha_triangles;
use alias_free_shadows::gpu::shared::counter;
use alias_free_shadows::gpu::{gpu_inputs, ShadowPipeline};
use alias_free_shadows::light::{LightSamples, LightShape};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::scene::file;
use alias_free_shadows::vulkan::{ContextOptions, GpuContext};
use glam::Vec3;

struct Case {
    light: LightView,
    light_samples: LightSamples,
    samples: Vec<Option<(Vec3, Vec3)>>,
    sample_tris: Vec<u32>,
    triangles: Vec<([Vec3; 3], bool)>,
    /// The scene's alpha tests (builtin:fence's lattice).
    alpha: AlphaTables,
    oracle_lit: Vec<f32>,
}

fn case(spec: &str, size: u32) -> Case {
    let mut desc = file::load(spec).unwrap();
    desc.camera.width = size;
    desc.camera.height = size;
    let eye = desc.camera.eye;
    let tris = desc.scene.triangles();
    let oracle = Oracle::new(&tris, eye);
    let view = oracle.primary_view_samples(&desc.camera);
    let light = &desc.lights[0];
    let (lv, ls) = match &light.shape {
        LightShape::Directional { direction } => (
            LightView::Directional {
                direction: direction.as_vec3(),
            },
            LightSamples::Direction(*direction),
        ),
        _ => {
            let c = light.center().unwrap();
            (
                LightView::Point {
                    position: (c - eye).as_vec3(),
                },
                LightSamples::Positions(vec![c]),
            )
        }
    };
    // The engine's view samples are f32 camera-relative: the oracle gets
    // exactly those (converted back), so both judge the same points.
    let samples: Vec<Option<(Vec3, Vec3)>> = view
        .samples
        .iter()
        .map(|s| s.map(|s| ((s.position - eye).as_vec3(), s.normal.as_vec3())))
        .collect();
    let mut exact_view = view.clone();
    for (s, f) in exact_view.samples.iter_mut().zip(&samples) {
        if let (Some(s), Some((p, n))) = (s.as_mut(), f) {
            s.position = eye + p.as_dvec3();
            s.normal = n.as_dvec3().normalize();
        }
    }
    let oracle_lit = oracle.visibility(&exact_view, &ls, None);
    Case {
        light: lv,
        light_samples: ls,
        sample_tris: view
            .samples
            .iter()
            .map(|s| s.map_or(u32::MAX, |s| s.triangle))
            .collect(),
        samples,
        triangles: tris
            .iter()
            .map(|t| (t.vertices.map(|v| (v - eye).as_vec3()), t.closed))
            .collect(),
        alpha: AlphaTables::new(&desc.scene),
        oracle_lit,
    }
}

fn differences(lit: &[Option<bool>], c: &Case) -> (usize, usize) {
    let mut d = 0;
    let mut n = 0;
    for (i, s) in c.samples.iter().enumerate() {
        if s.is_some() {
            n += 1;
            if (lit[i] == Some(true)) != (c.oracle_lit[i] > 0.5) {
                d += 1;
            }
        }
    }
    (d, n)
}

const SCENES: [&str; 7] = [
    "builtin:plane_sphere",
    "builtin:columns",
    "builtin:stairs",
    "builtin:torus_knot:2000",
    "builtin:hairball",
    "builtin:demo",
    "builtin:fence",
];

#[test]
fn cpu_twins_match_the_oracle() {
    for spec in SCENES {
        let c = case(spec, 96);
        let got = hard_shadows(
            &c.light,
            &c.samples,
            &c.sample_tris,
            &c.triangles,
            64,
            &c.alpha,
        );
        let (d, n) = differences(&got.lit, &c);
        eprintln!("twin {spec}: {d} of {n} differ");
        assert!(n > 0);
        assert_eq!(d, 0, "{spec}: {d} of {n} pixels differ from the oracle");
        let _ = &c.light_samples;
    }
}

#[test]
fn gpu_matches_the_oracle_and_the_twins() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut pass = ShadowPipeline::new(&ctx).unwrap();
    for spec in SCENES {
        let c = case(spec, 96);
        for res in [16, 64, 256] {
            let with_ids: Vec<_> = c
                .samples
                .iter()
                .zip(&c.sample_tris)
                .map(|(s, &t)| s.map(|(p, n)| (p, n, t)))
                .collect();
            let (vs, mut ts) = gpu_inputs(&with_ids, &c.triangles);
            mark_alpha_triangles(&mut ts, &c.alpha);
            pass.set_alpha(&ctx, &c.alpha).unwrap();
            let out = pass.run(&ctx, &vs, &ts, &c.light, res, None).unwrap();
            let (d, n) = differences(&out.lit, &c);
            let twin = hard_shadows(
                &c.light,
                &c.samples,
                &c.sample_tris,
                &c.triangles,
                res,
                &c.alpha,
            );
            let twin_d = out
                .lit
                .iter()
                .zip(&twin.lit)
                .filter(|(a, b)| a != b)
                .count();
            eprintln!(
                "gpu {spec} R={res}: {d} of {n} differ from the oracle, {twin_d} from the twin; pairs {} tests {}",
                out.counters[counter::PAIRS],
                out.counters[counter::TESTS]
            );
            assert_eq!(
                d, 0,
                "{spec} R={res}: {d} of {n} pixels differ from the oracle"
            );
            assert_eq!(twin_d, 0, "{spec} R={res}: GPU differs from its twin");
            // The caster passes (caster_setup + caster_clip) against their twin.
            let k = &twin.casters;
            assert_eq!(
                [
                    out.counters[counter::DEGENERATE],
                    out.counters[counter::FRONT_FACING_CLOSED],
                    out.counters[counter::CULLED],
                    out.counters[counter::RASTERIZED],
                ],
                [
                    k.degenerate,
                    k.front_facing_closed,
                    k.culled_frustum,
                    k.rasterized,
                ],
                "{spec} R={res}: caster counters differ from the twin"
            );
        }
    }
    ctx.check_validation().unwrap();
}
