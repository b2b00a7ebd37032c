//! The soft-shadow passes against their CPU twin ([`cpu::plane_lut`], [`cpu::soft_occlusion`]): the GPU's
//! plane look-up texture bit for bit, and the GPU's visible light samples
//! against the twin's brute force (every view sample against every
//! triangle, no influence regions, no binning), in look-up and exact modes.
//! The brute force checks that the influence regions, the culling of closed
//! triangles and the sphere rejection drop no triangle that blocks a sample.

use alias_free_shadows::cpu::alpha::AlphaTables;
use alias_free_shadows::cpu::plane_lut as soft;
use alias_free_shadows::cpu::soft_occlusion::{blocked_bits, PlaneBits};
use alias_free_shadows::light::{pixel_rotation_angle, unrotate_f32, Light};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::render::{self, Engine};
use alias_free_shadows::scene::file::{self, ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;

mod common;
use common::{engine_view_samples, sphere_light};

/// The share of (pixel, light sample) pairs where GPU and twin may differ:
/// the GPU's `inversesqrt` and division round differently from the CPU's,
/// which can move a plane that lies within rounding of a LUT cell boundary
/// into the next cell (LUT mode) or flip a light sample within rounding of
/// a plane (exact mode).
const TWIN_SHARE: f64 = 1e-4;

#[test]
fn plane_lut_matches_the_twin() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = file::load("builtin:demo").unwrap();
    let eye = desc.camera.eye;
    // 200 samples: two blocks, the second one partial. The approximate
    // mode's table, which the GPU builds (look-up mode's is built on the
    // host: tests/lut_exact.rs and cpu::plane_lut's tests check it).
    let light = sphere_light(&desc, 200);
    let settings = ShadowSettings {
        lut_resolution: 24,
        mode: SoftMode::Approx,
        ..Default::default()
    };
    let gpu = engine.plane_lut_bits(&light, eye, &settings).unwrap();
    let (sl, _) = render::soft_light(&light, eye, &settings).unwrap();
    let (c, r) = sl.bounds();
    let ys = soft::normalized_samples(&sl.samples, c, r);
    let cpu = soft::build_lut(&ys, 24);
    assert_eq!(gpu.len(), cpu.len());
    // Bits may differ only for samples within rounding of a texel's plane.
    let res = 24;
    let mut differ = 0;
    for (t, (g, w)) in gpu.iter().zip(&cpu).enumerate() {
        if g == w {
            continue;
        }
        let (texel, block) = (t / 2, t % 2);
        let (i, j, k) = (
            texel as u32 % res,
            (texel as u32 / res) % res,
            texel as u32 / (res * res),
        );
        let (n, d) = soft::lut_texel_plane(i, j, k, res);
        for b in 0..128 {
            let s = block * 128 + b;
            if (g[b / 32] ^ w[b / 32]) >> (b % 32) & 1 == 1 {
                differ += 1;
                let y = ys[s];
                assert!(
                    (n.dot(y) - d).abs() < 1e-5,
                    "texel {texel} block {block} sample {s}: GPU and twin differ {:.3e} from the plane",
                    n.dot(y) - d
                );
            }
        }
    }
    eprintln!(
        "plane LUT 24³ x 2 blocks: {differ} bits differ (all within 1e-5 of their plane) of {}",
        cpu.len() * 128
    );
    engine.context().check_validation().unwrap();
}

#[test]
fn visible_samples_match_the_brute_force_twin() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    // The last two: the per-pixel rotation, whose twin is the same test on
    // each pixel's geometry turned back (light::unrotate_f32).
    for (name, samples, rotate) in [
        ("demo", 128, false),
        ("fence", 200, false),
        ("hairball", 64, false),
        ("demo", 128, true),
        ("fence", 64, true),
    ] {
        let mut desc = file::load(&format!("builtin:{name}")).unwrap();
        desc.camera.width = 32;
        desc.camera.height = 32;
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        let light = Light {
            per_pixel_rotation: rotate,
            ..sphere_light(&desc, samples)
        };
        let table = alias_free_shadows::light::pixel_rotation_table();
        let tris = render::user_gpu_triangles(&desc.scene, eye, &view.samples);
        let alpha = AlphaTables::new(&desc.scene);
        for mode in [SoftMode::Approx, SoftMode::Lut, SoftMode::Exact] {
            let settings = ShadowSettings {
                mode,
                lut_resolution: 48,
                ..Default::default()
            };
            let r = engine
                .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
                .unwrap();
            let (sl, _) = render::soft_light(&light, eye, &settings).unwrap();
            let (c, rad) = sl.bounds();
            let lut = soft::build_lut(&soft::normalized_samples(&sl.samples, c, rad), 48);
            let bits = PlaneBits::Lut { lut: &lut, res: 48 };
            let exact_bits = PlaneBits::Exact {
                samples: &sl.samples,
            };
            let n_light = sl.samples.len();
            let blocks = soft::blocks(n_light);
            let (mut pairs, mut differ) = (0u64, 0u64);
            for (i, s) in view.samples.iter().enumerate() {
                let Some(s) = s else { continue };
                let p = (s.position - eye).as_vec3();
                let nrm = s.normal.as_vec3().normalize_or_zero();
                // The pixel's turn, undone on its geometry.
                let turn = |v: glam::Vec3, centre: glam::Vec3| match &sl.rotation {
                    Some(rot) => {
                        let cs = table[pixel_rotation_angle(i as u32, rot.seed)];
                        unrotate_f32(v, centre, rot.axis, cs)
                    }
                    None => v,
                };
                let (p, nrm) = (turn(p, c), turn(nrm, glam::Vec3::ZERO));
                let got = &r.visible[i * r.mask_words..(i + 1) * r.mask_words];
                // Blocked bits that the GPU must find (from triangles that
                // hide some light sample exactly: every influence region
                // holds them) and that it may find (any triangle: a look-up
                // can return bits for a triangle that hides nothing, which
                // the GPU tests only where its influence region reaches).
                let mut must = vec![[0u32; 4]; blocks];
                let mut may = vec![[0u32; 4]; blocks];
                let listed = nrm.dot(c - p) > -rad * nrm.length();
                if listed {
                    for (t, (v, closed)) in tris.iter().enumerate() {
                        if t as u32 == s.triangle {
                            continue;
                        }
                        let v = &v.map(|q| turn(q, c));
                        // An alpha-tested caster blocks where the segment
                        // crosses it opaque; the GPU tests it per light
                        // sample in every mode.
                        let tested = alpha.is_tested(t as u32);
                        let opaque = |l: glam::Vec3| alpha.segment_opaque(t as u32, *v, p, l - p);
                        let opaque = tested.then_some(&opaque as &dyn Fn(glam::Vec3) -> bool);
                        let exact =
                            blocked_bits(p, *v, *closed, c, rad, n_light, &exact_bits, opaque);
                        let Some(exact) = exact else { continue };
                        let hides = exact.iter().any(|b| b.iter().any(|&w| w != 0));
                        // Look-up mode gives exact mode's masks; the
                        // approximate mode, the nearest texel's bits.
                        let b = match mode {
                            SoftMode::Approx if !tested => {
                                blocked_bits(p, *v, *closed, c, rad, n_light, &bits, None).unwrap()
                            }
                            _ => exact,
                        };
                        for (k, x) in b.iter().enumerate() {
                            for w in 0..4 {
                                may[k][w] |= x[w];
                                if hides {
                                    must[k][w] |= x[w];
                                }
                            }
                        }
                    }
                }
                for (j, &l) in sl.samples.iter().enumerate() {
                    let front = listed && nrm.dot(l - p) > 0.0;
                    let bit = |m: &Vec<[u32; 4]>| m[j / 128][(j % 128) / 32] >> (j % 32) & 1 == 1;
                    let visible = got[j / 32] >> (j % 32) & 1 == 1;
                    // visible = front and not blocked, blocked between must and may.
                    let ok = if !front {
                        !visible
                    } else {
                        (!visible || !bit(&must)) && (visible || bit(&may))
                    };
                    pairs += 1;
                    differ += (!ok) as u64;
                }
            }
            let share = differ as f64 / pairs.max(1) as f64;
            eprintln!(
                "builtin:{name} {mode:?} {samples} samples (rotated: {rotate}): {differ} of {pairs} (pixel, light sample) pairs differ from the twin ({share:.2e})"
            );
            assert!(pairs > 0);
            assert!(
                share <= TWIN_SHARE,
                "builtin:{name} {mode:?}: {share:.2e} of the pairs differ from the twin"
            );
        }
    }
    engine.context().check_validation().unwrap();
}
