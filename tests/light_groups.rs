//! Exact mode tests a pair's four planes against a sphere around each group
//! of 16 light samples (`LIGHT_GROUP_SIZE`) before it tests any sample: a
//! group wholly outside one plane is skipped, one wholly inside all four is
//! blocked without a test. The rules must never change a mask. The cases
//! here aim at them: light samples on a grid, each group a 4 × 4 patch of
//! it, and casters whose supporting plane and edge planes, seen from the
//! view samples, pass exactly through rows of samples, so that groups
//! straddle planes with samples on them; and view samples moved off the
//! grid by a few ulps. Exact mode's masks must equal, bit for bit, the
//! CPU twin's (`cpu::soft_occlusion::blocked_bits`, which tests every
//! light sample) and look-up mode's (which tests its unsure bits one by
//! one); every rule must have fired.

use alias_free_shadows::cpu::soft_occlusion::{blocked_bits, PlaneBits};
use alias_free_shadows::gpu::soft_light::light_groups;
use alias_free_shadows::light::{Distribution, Light, LightShape};
use alias_free_shadows::oracle::ViewSample;
use alias_free_shadows::render::{self, Engine};
use alias_free_shadows::scene::file::{ShadowSettings, SoftMode};
use alias_free_shadows::scene::{Mesh, Scene};
use alias_free_shadows::vulkan::ContextOptions;
use glam::DVec3;

const EYE: DVec3 = DVec3::new(0.0, -1.0, 0.0);

/// 16 × 16 light samples at y = 8, x and z from -2 to 1.75 in steps of
/// 0.25, grid point (i, k) at x = -2 + i/4, z = -2 + k/4; each group of 16
/// is a 4 × 4 patch of the grid (compact, as the Z-order makes them).
fn grid_light() -> Light {
    let positions = (0..256)
        .map(|j| {
            let (patch, q) = (j / 16, j % 16);
            let i = (4 * (patch / 4) + q / 4) as f64;
            let k = (4 * (patch % 4) + q % 4) as f64;
            DVec3::new(-2.0 + 0.25 * i, 8.0, -2.0 + 0.25 * k)
        })
        .collect::<Vec<_>>();
    Light {
        shape: LightShape::Explicit { positions },
        samples: 256,
        distribution: Distribution::Poisson,
        seed: 1,
        color: [1.0; 3],
        intensity: 1.0,
        emission: None,
        per_pixel_rotation: false,
    }
}

/// Casters with exactly representable corners:
/// - a flat triangle at y = 4 with an edge along z at x = -0.5: from a view
///   sample at (u, 0, w) the plane through it and that edge meets y = 8 at
///   x = -1 - u, a row of samples for each u on the quarter grid;
/// - a tilted one whose own plane, y - 6 = 4 (x + 1.5), holds the row
///   x = -1 (samples exactly on the caster's plane);
/// - a small one at y = 6, whose cone leaves most groups outside.
fn scene() -> Scene {
    let mesh = |name: &str, p: [[f64; 3]; 3]| {
        let mut m = Mesh::new(
            name,
            p.iter().map(|&q| DVec3::from_array(q)).collect(),
            vec![[0, 1, 2]],
        );
        m.closed = false;
        m
    };
    Scene {
        meshes: vec![
            mesh(
                "flat",
                [[-0.5, 4.0, -3.0], [-0.5, 4.0, 3.0], [1.5, 4.0, 0.0]],
            ),
            mesh(
                "tilted",
                [[-1.5, 6.0, -3.0], [-1.5, 6.0, 3.0], [-0.5, 10.0, 0.0]],
            ),
            mesh(
                "small",
                [[0.5, 6.0, 0.5], [0.75, 6.0, 0.5], [0.5, 6.0, 0.75]],
            ),
        ],
        ..Default::default()
    }
}

/// View samples on the quarter grid at y = 0, and the same points moved by
/// a few f32 ulps (planes then pass within rounding of the samples).
fn view_samples() -> Vec<Option<ViewSample>> {
    let mut out = Vec::new();
    for a in -4i32..=4 {
        for b in -4..=4 {
            let p = DVec3::new(0.25 * a as f64, 0.0, 0.25 * b as f64);
            out.push(Some(ViewSample::user(p, DVec3::Y)));
            let nudge = DVec3::new(3e-7, 1e-7, -2e-7) * (1 + (a + b).rem_euclid(3)) as f64;
            out.push(Some(ViewSample::user(p + nudge, DVec3::Y)));
        }
    }
    out
}

#[test]
fn light_groups_hold_their_samples() {
    // Random clouds at several sizes and offsets: every sample lies within
    // its group's radius, measured in f64.
    let mut state = 0x2545_f491_u32;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32 - 0.5
    };
    for (scale, offset) in [(1.0f32, 0.0f32), (1e-4, 3.0), (1e4, -7e4), (3.0, 1e6)] {
        let samples: Vec<glam::Vec3> = (0..1000)
            .map(|_| glam::Vec3::new(next(), next(), next()) * scale + offset)
            .collect();
        let groups = light_groups(&samples);
        assert_eq!(groups.len(), samples.len().div_ceil(16));
        for (k, s) in samples.iter().enumerate() {
            let g = groups[k / 16];
            let d = s
                .as_dvec3()
                .distance(glam::DVec3::new(g[0] as f64, g[1] as f64, g[2] as f64));
            assert!(
                d <= g[3] as f64,
                "sample {k} at {d} outside radius {}",
                g[3]
            );
        }
    }
}

#[test]
fn light_group_rules_change_no_mask() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let (scene, light, view) = (scene(), grid_light(), view_samples());
    let run = |engine: &mut Engine, mode| {
        let settings = ShadowSettings {
            mode,
            ..Default::default()
        };
        engine
            .soft_shadows(&scene, EYE, &view, &light, &settings)
            .unwrap()
    };
    let exact = run(&mut engine, SoftMode::Exact);
    let lut = run(&mut engine, SoftMode::Lut);
    assert_eq!(exact.visible, lut.visible, "exact and look-up masks differ");

    // The twin: every light sample against every triangle.
    let settings = ShadowSettings {
        mode: SoftMode::Exact,
        ..Default::default()
    };
    let (sl, _) = render::soft_light(&light, EYE, &settings).unwrap();
    let (c, rad) = sl.bounds();
    let tris = render::user_gpu_triangles(&scene, EYE, &view);
    let bits = PlaneBits::Exact {
        samples: &sl.samples,
    };
    let n = sl.samples.len();
    let words = exact.mask_words;
    let (mut blocked_total, mut on_boundary) = (0usize, 0usize);
    for (i, s) in view.iter().enumerate() {
        let s = s.as_ref().unwrap();
        let p = (s.position - EYE).as_vec3();
        let mut blocked = vec![[0u32; 4]; n.div_ceil(128)];
        for (v, closed) in &tris {
            if let Some(b) = blocked_bits(p, *v, *closed, c, rad, n, &bits, None) {
                for (acc, w) in blocked.iter_mut().zip(b) {
                    for k in 0..4 {
                        acc[k] |= w[k];
                    }
                }
            }
        }
        let hidden_here: u32 = blocked.iter().flatten().map(|w| w.count_ones()).sum();
        assert!(
            (hidden_here as usize) < n,
            "view sample {i}: every light sample hidden (the skip count below assumes none is)"
        );
        let got = &exact.visible[i * words..(i + 1) * words];
        for j in 0..n {
            let hidden = blocked[j / 128][(j % 128) / 32] >> (j % 32) & 1 == 1;
            let visible = got[j / 32] >> (j % 32) & 1 == 1;
            assert_eq!(
                visible, !hidden,
                "view sample {i} at {:?}, light sample {j}: GPU and twin differ",
                s.position
            );
            blocked_total += hidden as usize;
        }
        // Samples whose row lies on the flat caster's edge plane (exact
        // arithmetic: the grid points without a nudge).
        if i % 2 == 0 {
            on_boundary += 1;
        }
    }
    let soft = exact.stats.soft.as_ref().unwrap();
    let groups_per_test = 128 / 16;
    let evaluated = soft.past_sphere_tests as u64 * groups_per_test;
    let skipped = evaluated - soft.light_groups_tested - soft.light_groups_every;
    eprintln!(
        "{} view samples ({on_boundary} on the grid), {blocked_total} blocked (sample, light sample) pairs; \
         groups: {evaluated} evaluated, {} tested one by one, {} wholly blocked, {skipped} skipped",
        view.len(),
        soft.light_groups_tested,
        soft.light_groups_every
    );
    assert!(blocked_total > 0 && blocked_total < view.len() * n);
    // Every rule fired (no mask is ever full here, so every pair past the
    // sphere tests evaluates all its groups).
    assert!(soft.light_groups_tested > 0, "no group was tested");
    assert!(soft.light_groups_every > 0, "no group was wholly blocked");
    assert!(skipped > 0, "no group was skipped");
    // Look-up mode has no groups.
    let lut_soft = lut.stats.soft.as_ref().unwrap();
    assert_eq!(
        (lut_soft.light_groups_tested, lut_soft.light_groups_every),
        (0, 0)
    );
    engine.context().check_validation().unwrap();
}
