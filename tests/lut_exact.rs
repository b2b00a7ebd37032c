//! Look-up mode (the default) against exact mode, mask word by mask word:
//! the table only bounds each plane's bits and the bits it leaves unsure
//! are tested as exact mode tests every light sample, so the two must give
//! the same visible light samples, bit for bit, on every built-in scene and
//! every shared model (`../shared/assets`, on a ground) with sphere, disk,
//! rect and ellipsoid lights at 128, 256 and 1024 samples (the sphere at
//! each count on every scene, the other kinds at 128 and one more count by
//! turns; `AFS_LUT_EXACT_ALL=1` runs every kind at every count).

use alias_free_shadows::bench::{bench_light, load_scene};
use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::{ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;
use glam::{DVec2, DVec3};

mod common;
use common::{engine_view_samples, soft_in_mode, words_differ};

const SIZE: u32 = 40;
/// Pairs per occlusion work unit in look-up mode.
const UNIT_PAIRS: usize = alias_free_shadows::gpu::tile_bin::LOOKUP_PAIR_CHUNK.1 as usize;

/// `AFS_LUT_EXACT_ALL=1`: every light kind at every sample count on every
/// scene (the full set that the doc above names; `AFS_LUT_EXACT_SIZE`
/// sets the image size, 40 by default). Without it the suite still covers
/// every (kind, count) pair, over the scenes by turns.
fn all_counts() -> bool {
    std::env::var("AFS_LUT_EXACT_ALL").is_ok_and(|v| v != "0")
}

fn size() -> u32 {
    std::env::var("AFS_LUT_EXACT_SIZE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(SIZE)
}

/// The sample counts of light kind `kind` (0: the sphere) on scene number
/// `scene`: the sphere at 128, 256 and 1024; each other kind at 128 and
/// at 256 or 1024 by turns, so that every kind meets every count on some
/// scene; every count for every kind with `all`.
fn counts(scene: usize, kind: usize, all: bool) -> Vec<u32> {
    const COUNTS: [u32; 3] = [128, 256, 1024];
    if all || kind == 0 {
        COUNTS.to_vec()
    } else {
        vec![128, COUNTS[1 + (scene + kind) % 2]]
    }
}

fn specs() -> Vec<String> {
    let mut out: Vec<String> = alias_free_shadows::scene::builtin::NAMES
        .iter()
        .map(|n| format!("builtin:{n}"))
        .collect();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets");
    for m in [
        "Lantern/Lantern.gltf",
        "BoomBox/BoomBox.gltf",
        "Suzanne/Suzanne.gltf",
        "ToyCar/ToyCar.gltf",
        "TransmissionTest/TransmissionTest.glb",
        "StainedGlassLamp/StainedGlassLamp.gltf",
    ] {
        let p = root.join(m);
        if p.is_file() {
            out.push(p.display().to_string());
        }
    }
    out
}

/// The four light kinds around the bench's sphere light (the scene's own,
/// else one at its light a tenth of its distance across).
fn lights(sphere: &Light) -> Vec<Light> {
    let LightShape::Sphere { position, radius } = sphere.shape else {
        unreachable!("the bench light is a sphere")
    };
    let toward = DVec3::new(0.2, -1.0, 0.1).normalize();
    let tangent = DVec3::new(1.0, 0.0, 0.3).normalize();
    [
        sphere.shape.clone(),
        LightShape::Disk {
            position,
            radius,
            normal: toward,
            tangent,
        },
        LightShape::Rect {
            position,
            size: DVec2::new(2.0 * radius, 0.8 * radius),
            normal: toward,
            tangent,
        },
        LightShape::Ellipsoid {
            position,
            semi_axes: DVec3::new(1.4, 0.5, 0.8) * radius,
            normal: toward,
            tangent,
        },
    ]
    .into_iter()
    .map(|shape| Light {
        shape,
        ..sphere.clone()
    })
    .collect()
}

#[test]
fn look_up_mode_masks_equal_exact_mode() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let (mut words, mut configs) = (0u64, 0);
    let (mut unsure, mut bits) = (0u64, 0f64);
    let all = all_counts();
    let mut covered = std::collections::BTreeSet::new();
    for (n, spec) in specs().into_iter().enumerate() {
        let desc = load_scene(&spec, size()).unwrap();
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);
        for (k, light) in lights(&bench_light(&desc, 128).unwrap())
            .into_iter()
            .enumerate()
        {
            for samples in counts(n, k, all) {
                covered.insert((k, samples));
                let light = Light {
                    samples,
                    ..light.clone()
                };
                let lut = soft_in_mode(&mut engine, &desc, &view, &light, SoftMode::Lut);
                let exact = soft_in_mode(&mut engine, &desc, &view, &light, SoftMode::Exact);
                assert_eq!(lut.visible.len(), exact.visible.len());
                let differ = words_differ(&lut.visible, &exact.visible);
                let s = lut.stats.soft.as_ref().unwrap();
                eprintln!(
                    "{spec} {} {samples}: {} words, {differ} differ; {} unsure bits ({:.2e} of the tested bits)",
                    ["sphere", "disk", "rect", "ellipsoid"][k],
                    lut.visible.len(),
                    s.unsure_bits,
                    s.unsure_share
                );
                assert_eq!(
                    differ, 0,
                    "{spec}, light {k}, {samples} samples: look-up and exact masks differ"
                );
                assert_eq!(lut.visibility, exact.visibility);
                words += lut.visible.len() as u64;
                configs += 1;
                unsure += s.unsure_bits;
                bits += s.unsure_bits as f64 / s.unsure_share.max(1e-300);
            }
        }
    }
    eprintln!(
        "{configs} configurations, {words} mask words equal; unsure bits {unsure} ({:.2e} of all tested bits)",
        unsure as f64 / bits.max(1.0)
    );
    assert!(configs >= 7 * 6, "every built-in scene and light kind");
    assert_eq!(
        covered.len(),
        4 * 3,
        "every light kind at every sample count"
    );
    engine.context().check_validation().unwrap();
}

/// Look-up mode's table kept on disk: a second engine reads it (or, on a
/// CPU device with `VK_EXT_external_memory_host`, maps it) instead of
/// building it and gets the same masks, whether mapped or read; a file
/// that does not hold the key (corrupted) is not used; at most `KEPT` files
/// stay.
#[test]
fn the_table_is_kept_across_runs() {
    use alias_free_shadows::gpu::plane_lut::table_cache::KEPT;
    let dir = tempfile::tempdir().unwrap();
    let desc = load_scene("builtin:demo", 24).unwrap();
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, &desc);
    let settings = ShadowSettings::default();
    let run_mapping = |light: &Light, map: bool| {
        let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
        let info = engine.context().info();
        let can_map = info.is_cpu() && info.features.external_memory_host;
        engine.set_table_cache(Some(dir.path().to_path_buf()));
        engine.set_table_mapping(map);
        let r = engine
            .soft_shadows(&desc.scene, eye, &view.samples, light, &settings)
            .unwrap();
        engine.context().check_validation().unwrap();
        let ms = &r.stats.ms;
        let how = ["lut_build", "lut_read", "lut_mapped"].map(|k| ms.contains_key(k));
        assert_eq!(how.iter().filter(|&&h| h).count(), 1, "{ms:?}");
        (r, how, can_map)
    };
    let light = bench_light(&desc, 64).unwrap();
    let (first, how, _) = run_mapping(&light, true);
    assert!(how[0], "a fresh cache has no table");
    let (second, how, can_map) = run_mapping(&light, true);
    assert_eq!(
        how,
        [false, !can_map, can_map],
        "the second run maps the kept table where it can, else reads it"
    );
    assert_eq!(first.visible, second.visible);
    let (read, how, _) = run_mapping(&light, false);
    assert!(how[1], "mapping off: the kept table is read");
    assert_eq!(first.visible, read.visible);
    let run = |light: &Light| {
        let (r, how, _) = run_mapping(light, true);
        (r, how[1] || how[2])
    };
    // A corrupted file is rebuilt, with the same masks.
    let file = std::fs::read_dir(dir.path())
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let mut bytes = std::fs::read(&file).unwrap();
    bytes[20] ^= 1;
    std::fs::write(&file, &bytes).unwrap();
    let (third, read) = run(&light);
    assert!(!read, "a file that does not hold the key is not used");
    assert_eq!(first.visible, third.visible);
    // Other lights: new files, the oldest go past KEPT.
    for seed in 0..KEPT as u64 + 2 {
        run(&Light {
            seed: 100 + seed,
            samples: 8,
            ..light.clone()
        });
    }
    let files = std::fs::read_dir(dir.path()).unwrap().count();
    assert_eq!(files, KEPT);
}

/// The unsure list in small ranges (and ranges that overflow and run again)
/// gives the same masks as in the ranges without a limit (the first as long
/// as the worst case fits, the next after the entries seen), and the ranges
/// keep to the limit.
#[test]
fn unsure_list_ranges_equal_one_range() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    // The opaque round tests a common scene's unsure bits in place; the
    // tiny light's pairs pass the in-place budget and are listed: 200 light
    // samples (two blocks) and 1024 view samples list ~1.7 M entries.
    let TinyLight {
        scene,
        eye,
        samples,
        light,
    } = tiny_light(200, 32);
    let settings = ShadowSettings::default();
    let one = engine
        .soft_shadows(&scene, eye, &samples, &light, &settings)
        .unwrap();
    let exact = engine
        .soft_shadows(
            &scene,
            eye,
            &samples,
            &light,
            &ShadowSettings {
                mode: SoftMode::Exact,
                ..Default::default()
            },
        )
        .unwrap();
    assert_eq!(one.visible, exact.visible);
    let soft = one.stats.soft.as_ref().unwrap();
    // More than one unit's bound (64 lanes × a unit's pairs × 2 blocks) in
    // each of the list's segments: the smallest list a limit allows.
    let one_unit =
        64 * UNIT_PAIRS as u64 * 2 * alias_free_shadows::gpu::soft_occlusion::UNSURE_SEGMENTS;
    eprintln!(
        "{} unsure entries in {} range(s) without a limit",
        soft.unsure_entries, soft.unsure_ranges
    );
    assert!(
        soft.unsure_entries > one_unit,
        "the case must list many unsure entries: {}",
        soft.unsure_entries
    );
    for limit in [1u64, 3 * one_unit / 2] {
        engine.set_unsure_list_limit(Some(limit));
        let ranged = engine
            .soft_shadows(&scene, eye, &samples, &light, &settings)
            .unwrap();
        let (a, b): (u32, u32) = (
            one.visible.iter().map(|w| w.count_ones()).sum(),
            ranged.visible.iter().map(|w| w.count_ones()).sum(),
        );
        let differ = words_differ(&one.visible, &ranged.visible);
        assert!(
            differ == 0,
            "list limit {limit}: {differ} words differ, visible bits {a} in one range, {b} in ranges"
        );
        // A range run again starts from the counters before it: the visits
        // count every (sample, unit) once. (The tests vary slightly from
        // run to run of one frame: how the lists' atomics ordered samples
        // and pairs decides the chunks' boxes and when a sample's light
        // is found wholly blocked; the masks do not depend on it.)
        let visits = |s: &alias_free_shadows::stats::ShadowStats| {
            s.soft.as_ref().map_or(0, |soft| soft.sample_unit_visits)
        };
        assert!(visits(&one.stats) > 0, "the visits are counted");
        assert_eq!(
            visits(&one.stats),
            visits(&ranged.stats),
            "ranges run again from the counters before them"
        );
        // The list held at most the limit (raised to its floor) per range,
        // so the entries took at least that many ranges: more than one.
        let ranged_soft = ranged.stats.soft.as_ref().unwrap();
        let capacity = limit.max(one_unit);
        let fewest = ranged_soft.unsure_entries.div_ceil(capacity);
        assert!(
            fewest >= 2 && ranged_soft.unsure_ranges as u64 >= fewest,
            "list limit {limit}: {} entries in {} range(s), {} without a limit",
            ranged_soft.unsure_entries,
            ranged_soft.unsure_ranges,
            soft.unsure_ranges
        );
    }
    engine.context().check_validation().unwrap();
}

/// A light tiny for its distance (radius 1e-5 at 2 units): each pair's
/// rounding bound (64 f32 ulps of the test's magnitudes, per light radius)
/// passes the largest allowance, so every bit a pair leaves is unsure and
/// tested exactly. Hundreds of casters pass the sphere rules (their cones
/// miss the light by less than the rules' rounding allowance) and block
/// nothing, so one invocation meets more unsure bits than lavapipe's 65535
/// loop iterations allow; past its budget it lists them for the unsure
/// pass instead. A few casters block a few light samples each; they come
/// near the end of the first unit's pairs (`UNIT_PAIRS`; at 512 pairs a
/// unit, after ~500 others), where an invocation whose loops were cut lost them (32
/// and 43 mask words differed in two of three runs without the budget, and
/// nothing was listed). The masks must be exact mode's.
#[test]
fn tiny_light_past_the_in_place_budget_stays_exact() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    // One block of light samples (tested in place bit by bit) and eight
    // (block by block).
    for samples in [128, 1024] {
        tiny_light_case(&mut engine, samples);
    }
    engine.context().check_validation().unwrap();
}

/// The tiny-light case: its scene, eye, view samples and light.
struct TinyLight {
    scene: alias_free_shadows::scene::Scene,
    eye: DVec3,
    samples: Vec<Option<alias_free_shadows::oracle::ViewSample>>,
    light: Light,
}

/// `light_samples` light samples, a grid of `grid` × `grid` view samples
/// (all in one light texel).
fn tiny_light(light_samples: u32, grid: usize) -> TinyLight {
    use alias_free_shadows::oracle::ViewSample;
    let eye = DVec3::new(0.0, 1.0, 0.01);
    let (light, ls) = tiny_sphere_light(light_samples);
    let radius = TINY_RADIUS;
    let mut tris: Vec<_> = (0..UNIT_PAIRS + 988)
        .map(|k| near_miss_caster(DVec3::ZERO, k))
        .collect();
    for j in 0..12 {
        let k = UNIT_PAIRS - 14 + j;
        tris.insert(
            k,
            caster_towards(
                DVec3::ZERO,
                ls[(j * 11) % ls.len()],
                0.08 * radius,
                1.0,
                j as f64,
            ),
        );
    }
    let scene = open_soup(&tris);
    let samples = (0..grid * grid)
        .map(|i| {
            let p = DVec3::new((i % grid) as f64, 0.0, (i / grid) as f64) * 1e-7;
            Some(ViewSample::user(p, DVec3::Y))
        })
        .collect();
    TinyLight {
        scene,
        eye,
        samples,
        light,
    }
}

/// The tiny light's centre, 2 above the view samples.
const TINY_CENTRE: DVec3 = DVec3::new(0.0, 2.0, 0.0);
/// The tiny light's radius: f32 rounding at its distance is a good part of
/// a radius.
const TINY_RADIUS: f64 = 1e-5;

/// A sphere light of radius [`TINY_RADIUS`] at [`TINY_CENTRE`] with
/// `samples` samples (the demo's light otherwise), and its sample
/// positions.
fn tiny_sphere_light(samples: u32) -> (Light, Vec<DVec3>) {
    use alias_free_shadows::light::LightSamples;
    let demo = load_scene("builtin:demo", 16).unwrap();
    let light = Light {
        shape: LightShape::Sphere {
            position: TINY_CENTRE,
            radius: TINY_RADIUS,
        },
        samples,
        per_pixel_rotation: false,
        ..demo.lights[0].clone()
    };
    let LightSamples::Positions(ls) = light.light_samples() else {
        unreachable!("a sphere has positions")
    };
    (light, ls)
}

/// A horizontal triangle at height h on the cone from x (at height 0) to
/// `target` (near the light), `size` across at the light's height.
fn caster_towards(x: DVec3, target: DVec3, size: f64, h: f64, turn: f64) -> [DVec3; 3] {
    let c = x + (target - x) * (h / target.y);
    let s = size * h / target.y;
    let v = |a: f64| c + s * DVec3::new((turn + a).cos(), 0.0, (turn + a).sin());
    [v(0.0), v(2.1), v(4.2)]
}

/// Caster number k of those that nearly miss the tiny light from x: its
/// cone misses the light by 0.6 radii, within the sphere rules' rounding
/// allowance, so it passes them, blocks nothing and leaves every bit
/// unsure.
fn near_miss_caster(x: DVec3, k: usize) -> [DVec3; 3] {
    use std::f64::consts::TAU;
    let t = k as f64 * 0.618_034;
    let side = DVec3::new((TAU * t).cos(), 0.0, (TAU * t).sin());
    caster_towards(
        x,
        TINY_CENTRE + 1.6 * TINY_RADIUS * side,
        0.3 * TINY_RADIUS,
        0.8 + 0.4 * (t * 7.1).fract(),
        t,
    )
}

/// One open mesh of these triangles.
fn open_soup(tris: &[[DVec3; 3]]) -> alias_free_shadows::scene::Scene {
    use alias_free_shadows::scene::{Mesh, Scene};
    let positions: Vec<DVec3> = tris.iter().flatten().copied().collect();
    let faces = (0..tris.len() as u32)
        .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
        .collect();
    let mut mesh = Mesh::new("casters", positions, faces);
    mesh.closed = false;
    Scene {
        meshes: vec![mesh],
        ..Default::default()
    }
}

/// A tiny-light case in look-up mode and in exact mode, under `settings`
/// otherwise.
fn lut_and_exact(
    engine: &mut Engine,
    case: &TinyLight,
    settings: ShadowSettings,
) -> (
    alias_free_shadows::render::SoftShadowResult,
    alias_free_shadows::render::SoftShadowResult,
) {
    let mut run = |mode| {
        let settings = ShadowSettings { mode, ..settings };
        engine
            .soft_shadows(&case.scene, case.eye, &case.samples, &case.light, &settings)
            .unwrap()
    };
    (run(SoftMode::Lut), run(SoftMode::Exact))
}

fn tiny_light_case(engine: &mut Engine, light_samples: u32) {
    let case = tiny_light(light_samples, 4);
    let (lut, exact) = lut_and_exact(engine, &case, ShadowSettings::default());
    let samples = &case.samples;
    let blocked: u32 = exact.visible.iter().map(|w| (!w).count_ones()).sum();
    let s = lut.stats.soft.as_ref().unwrap();
    let differ = words_differ(&lut.visible, &exact.visible);
    eprintln!(
        "{light_samples} light samples: {} blocked over {} view samples; {} unsure bits, {} listed entries; {differ} mask words differ",
        blocked,
        samples.len(),
        s.unsure_bits,
        s.unsure_entries
    );
    assert!(blocked > 0, "some light samples are blocked");
    assert!(
        exact.visible.iter().any(|&w| w != 0),
        "some light samples are visible"
    );
    assert!(
        s.unsure_bits > 65536,
        "the case must pass an invocation's loop bound: {} unsure bits",
        s.unsure_bits
    );
    assert!(
        s.unsure_entries > 0,
        "past the budget, unsure bits go to the list"
    );
    assert_eq!(differ, 0, "look-up and exact masks differ");
    assert_eq!(lut.visibility, exact.visibility);
}

/// The in-place budget counts a subgroup's loop iterations, not each
/// lane's bits: lavapipe runs a subgroup as one SIMD vector and ends all
/// its loops after 65535 iterations in all (one counter per vector), and
/// the loops over a pair's unsure bits run as long as the busiest lane's.
/// Eight view samples in one light texel (one subgroup) under the tiny
/// light of 1024 samples, each with near-miss casters of its own (every
/// bit unsure from that sample, clear misses from the others): in a window
/// of pairs the lanes have different numbers of them, so the subgroup's
/// loops run well past the bits of any one lane. Each sample's blockers
/// stand near the end of each unit's pairs, where the loops' bound
/// cuts off. With a per-lane budget of 49,152 bits, 46 mask words
/// differed from exact mode (stop 54).
#[test]
fn lanes_with_unsure_bits_of_their_own_stay_exact() {
    use alias_free_shadows::oracle::ViewSample;
    use alias_free_shadows::scene::file::LightTexels;
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let eye = DVec3::new(0.0, 1.0, 0.01);
    let (light, ls) = tiny_sphere_light(1024);
    let radius = TINY_RADIUS;
    // View sample t, 10 light radii from the next: a caster that nearly
    // misses the light from one of them misses it by radii from the others.
    let xs: Vec<DVec3> = (0..8)
        .map(|t| DVec3::new(t as f64 * 10.0 * radius, 0.0, 0.0))
        .collect();
    let units = 3;
    // In runs of 64 per view sample.
    let mut tris: Vec<_> = (0..units * UNIT_PAIRS)
        .map(|k| near_miss_caster(xs[(k / 64) % 8], k))
        .collect();
    // Near the end of each unit: one blocker per view sample, of a light
    // sample or two.
    for u in 0..units {
        for (lane, &x) in xs.iter().enumerate() {
            let j = u * 8 + lane;
            tris[u * UNIT_PAIRS + UNIT_PAIRS - 12 + lane] =
                caster_towards(x, ls[(j * 11) % ls.len()], 0.08 * radius, 1.0, j as f64);
        }
    }
    let case = TinyLight {
        scene: open_soup(&tris),
        eye,
        samples: xs
            .iter()
            .map(|&p| Some(ViewSample::user(p, DVec3::Y)))
            .collect(),
        light,
    };
    let settings = ShadowSettings {
        soft_light_texels: LightTexels::Fixed(1),
        ..Default::default()
    };
    let (lut, exact) = lut_and_exact(&mut engine, &case, settings);
    let s = lut.stats.soft.as_ref().unwrap();
    let differ = words_differ(&lut.visible, &exact.visible);
    let blocked: Vec<u32> = exact
        .visible
        .chunks(32)
        .map(|m| m.iter().map(|w| (!w).count_ones()).sum())
        .collect();
    eprintln!(
        "blocked per view sample {blocked:?}; {} unsure bits, {} listed entries; {differ} mask words differ",
        s.unsure_bits, s.unsure_entries
    );
    assert!(
        blocked.iter().all(|&b| b > 0),
        "every view sample has blockers"
    );
    assert!(
        s.unsure_bits > 8 * 65536,
        "the case must pass the subgroup's loop bound: {} unsure bits",
        s.unsure_bits
    );
    assert!(
        s.unsure_entries > 0,
        "past the budget, unsure bits go to the list"
    );
    engine.context().check_validation().unwrap();
    assert_eq!(differ, 0, "look-up and exact masks differ");
    assert_eq!(lut.visibility, exact.visibility);
}

/// A light small for its distance (a 250th of it): each pair's rounding
/// allowance is its own rounding bound, so the table still decides most
/// bits (with one fixed allowance of 1e-3 light radii every bit of such a
/// light was unsure: 14% of the tested bits on the demo at 256², against
/// 0.2%), and the masks stay exact mode's.
#[test]
fn small_light_leaves_few_bits_unsure() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = load_scene("builtin:demo", 64).unwrap();
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, &desc);
    let sphere = bench_light(&desc, 128).unwrap();
    let LightShape::Sphere { position, radius } = sphere.shape else {
        unreachable!("the bench light is a sphere")
    };
    let light = Light {
        shape: LightShape::Sphere {
            position,
            radius: radius / 25.0,
        },
        ..sphere
    };
    let lut = soft_in_mode(&mut engine, &desc, &view, &light, SoftMode::Lut);
    let exact = soft_in_mode(&mut engine, &desc, &view, &light, SoftMode::Exact);
    let s = lut.stats.soft.as_ref().unwrap();
    let differ = words_differ(&lut.visible, &exact.visible);
    eprintln!(
        "{} unsure bits ({:.2e} of the tested bits); {differ} mask words differ",
        s.unsure_bits, s.unsure_share
    );
    assert!(s.unsure_bits > 0, "the case has planes near light samples");
    assert!(
        s.unsure_share < 0.02,
        "the table leaves {:.3} of the tested bits unsure",
        s.unsure_share
    );
    assert_eq!(differ, 0, "look-up and exact masks differ");
    assert_eq!(lut.visibility, exact.visibility);
    engine.context().check_validation().unwrap();
}
