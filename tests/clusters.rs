//! View-sample clusters (`gpu::clusters`) drop (caster, tile) pairs before
//! occlusion, and soft occlusion's wedge rule skips pairs before their
//! look-ups or per-light-sample tests; neither may ever change a result.
//! The reach rule (a caster farther from the light's centre than a chunk's
//! samples and the light) drops pairs per chunk too, and the reach and
//! hull rules per subgroup.
//! Every case runs with the clusters on and off (and soft ones in exact and
//! look-up modes with the wedge rule off) and the runs must agree bit for
//! bit: hard shadows' lit flags, and soft shadows' masks in every mode. The cases aim at the
//! rules: boxes that straddle a caster's plane (contacts, steps), samples
//! inside the light's bounding sphere, casters thinner than a texel, a
//! light that intersects a closed mesh, directional and point lights. Each
//! rule (per tile in binning, per chunk of 64 samples in soft occlusion,
//! the wedge rule) must have dropped pairs somewhere, or the test proves
//! nothing.

use alias_free_shadows::bench::{bench_light, load_scene};
use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::{LightTexels, SceneDescription, ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;
use glam::DVec3;

mod common;
use common::engine_view_samples;

const SIZE: u32 = 32;

/// Lights with extent aimed at the rules, for `desc`: the bench's sphere
/// (a tenth of its distance across), one whose sphere holds the scene's
/// centre (samples inside it) and one centred on a vertex of the scene's
/// first mesh (it intersects that mesh, closed or not); the bench's sphere
/// again with 256 samples (look-up mode's shader for two 128-sample
/// blocks, the wedge rule's too).
fn soft_lights(desc: &SceneDescription) -> Vec<(&'static str, Light)> {
    let bench = bench_light(desc, 128).unwrap();
    let (lo, hi) = desc.scene.bounds().unwrap();
    let size = (hi - lo).length();
    let vertex = desc.scene.triangles()[0].vertices[0];
    let sphere = |position: DVec3, radius: f64| Light {
        shape: LightShape::Sphere { position, radius },
        ..bench.clone()
    };
    vec![
        ("bench sphere", bench.clone()),
        ("around the centre", sphere((lo + hi) * 0.5, 0.2 * size)),
        ("through a mesh", sphere(vertex, 0.1 * size)),
        (
            "bench sphere, 256 samples",
            Light {
                samples: 256,
                ..bench.clone()
            },
        ),
    ]
}

#[test]
fn clusters_change_no_result() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    // Soft tests by outcome: the caster's plane, an edge's plane, the wedge
    // rule, past all three.
    let mut outcomes = [0u64; 4];
    // The wedge rule's rejections in look-up mode (which compiles the rule
    // out: it cost more than it saved there) and in exact mode.
    let (mut lut_wedge, mut exact_wedge) = (0u64, 0u64);
    let (mut light_side, mut behind_closed, mut penumbra, mut chunk, mut cases) =
        (0u64, 0u64, 0u64, 0u64, 0);
    // The reach rule's (pair, chunk) drops and (sample, pair) culls.
    let (mut chunk_beyond, mut beyond) = (0u64, 0u64);
    // The hull rule's (sample, pair) culls.
    let mut hull = 0u64;
    // Tile binning's (pair, tile) drops by the reach and hull rules.
    let (mut bin_beyond, mut bin_hull) = (0u64, 0u64);
    // (plane_sphere at 128² has chunks whose reach drops a caster that
    // their tile's does not; at 64² it had them while a tile's texels were
    // listed row by row, not since they are in Z order.)
    for (spec, size) in [
        ("builtin:demo", SIZE),
        ("builtin:plane_sphere", SIZE),
        ("builtin:plane_sphere", 4 * SIZE),
        ("builtin:stairs", SIZE),
        ("builtin:hairball", SIZE),
        ("builtin:fence", SIZE),
        ("builtin:torus_knot:3000", SIZE),
    ] {
        let desc = load_scene(spec, size).unwrap();
        let eye = desc.camera.eye;
        let oracle = Oracle::new(&desc.scene.triangles(), eye);
        let view = engine_view_samples(&oracle, &desc);

        // Hard shadows (which get no boxes: gpu::clusters) stay the same
        // too: a point light at the bench light's centre, and a directional
        // light.
        let bench = bench_light(&desc, 1).unwrap();
        let centre = bench.center().unwrap();
        let (lo, hi) = desc.scene.bounds().unwrap();
        for shape in [
            LightShape::Point { position: centre },
            LightShape::Directional {
                direction: ((lo + hi) * 0.5 - centre).normalize(),
            },
        ] {
            let light = Light {
                shape,
                samples: 1,
                ..bench.clone()
            };
            let mut run = |on| {
                engine.set_clusters(on);
                engine
                    .hard_shadows(&desc.scene, eye, &view.samples, &light, 256)
                    .unwrap()
            };
            let (with, without) = (run(true), run(false));
            assert_eq!(with.lit, without.lit, "{spec}, {:?}", light.shape);
            assert_eq!(without.stats.bins_dropped_light_side, 0);
            light_side += with.stats.bins_dropped_light_side as u64;
            cases += 1;
        }

        for (name, light) in soft_lights(&desc) {
            for mode in [SoftMode::Exact, SoftMode::Lut, SoftMode::Approx] {
                // The 256-sample light is there for look-up mode's two-block shader.
                if light.samples > 128 && mode != SoftMode::Lut {
                    continue;
                }
                let run_texels = |engine: &mut Engine, clusters, wedge_rule, soft_light_texels| {
                    let settings = ShadowSettings {
                        mode,
                        clusters,
                        wedge_rule,
                        soft_light_texels,
                        ..Default::default()
                    };
                    engine
                        .soft_shadows(&desc.scene, eye, &view.samples, &light, &settings)
                        .unwrap()
                };
                let run_with = |engine: &mut Engine, clusters, wedge_rule| {
                    run_texels(engine, clusters, wedge_rule, LightTexels::Auto)
                };
                let run = |engine: &mut Engine, clusters| run_with(engine, clusters, true);
                let with = run(&mut engine, true);
                let without = run(&mut engine, false);
                // One tile per face (8 texels a side): its chunks of 64
                // samples are smaller than its box, so the chunks' own
                // rules drop what the tile's leave (at this size a tile of
                // the automatic map holds about one chunk).
                if mode == SoftMode::Lut {
                    let coarse = |engine: &mut Engine, clusters| {
                        run_texels(engine, clusters, true, LightTexels::Fixed(8))
                    };
                    let (with, without) = (coarse(&mut engine, true), coarse(&mut engine, false));
                    assert_eq!(
                        with.visible, without.visible,
                        "{spec}, {name}, {mode:?}, one tile per face: masks differ"
                    );
                    chunk_beyond += with.stats.chunk_pairs_beyond_reach as u64;
                    chunk += with.stats.chunk_pairs_dropped as u64;
                }
                // The wedge rule (run in exact mode, compiled out of look-up
                // mode: both must give the masks they give without it).
                if mode != SoftMode::Approx {
                    let no_wedge = run_with(&mut engine, true, false);
                    assert_eq!(
                        with.visible, no_wedge.visible,
                        "{spec}, {name}, {mode:?}: masks differ without the wedge rule"
                    );
                    let skipped = |r: &alias_free_shadows::render::SoftShadowResult| {
                        r.stats.soft.as_ref().unwrap().wedge_rejected_tests
                    };
                    assert_eq!(skipped(&no_wedge), 0, "{spec}, {name}, {mode:?}");
                    if mode == SoftMode::Lut {
                        lut_wedge += skipped(&with) as u64;
                    } else {
                        exact_wedge += skipped(&with) as u64;
                    }
                }
                assert_eq!(
                    with.visible, without.visible,
                    "{spec}, {name}, {mode:?}: masks differ"
                );
                assert_eq!(with.visibility, without.visibility);
                assert_eq!(
                    (
                        without.stats.bins_dropped_light_side,
                        without.stats.bins_dropped_behind_closed,
                        without.stats.chunk_pairs_outside_penumbra,
                        without.stats.chunk_pairs_dropped,
                        without.stats.chunk_pairs_beyond_reach,
                        without.stats.bins_dropped_beyond_reach,
                        without.stats.bins_dropped_outside_hull,
                    ),
                    (0, 0, 0, 0, 0, 0, 0),
                    "off drops nothing"
                );
                let (a, b, p) = (
                    with.stats.bins_dropped_light_side as u64,
                    with.stats.bins_dropped_behind_closed as u64,
                    with.stats.chunk_pairs_outside_penumbra as u64,
                );
                // (The tests count only pairs past occlusion's own early
                // outs, and depends on the order of a tile's pairs where a
                // full mask stops early: printed, not compared.)
                eprintln!(
                    "{spec}, {name}, {mode:?}: tests {} -> {}; bins dropped {a} (light side) + {b} (behind closed); chunk visits dropped {} ({p} outside penumbra)",
                    without.stats.view_sample_triangle_tests,
                    with.stats.view_sample_triangle_tests,
                    with.stats.chunk_pairs_dropped,
                );
                // Every test ends at the caster's plane, at an edge's plane,
                // at the wedge rule or past all three; only those past all
                // can block.
                for run in [&with, &without] {
                    let (st, soft) = (&run.stats, run.stats.soft.as_ref().unwrap());
                    assert!(
                        soft.plane_rejected_tests as u64
                            + soft.wedge_rejected_tests as u64
                            + soft.past_sphere_tests as u64
                            <= st.view_sample_triangle_tests as u64
                            && soft.blocking_tests <= soft.past_sphere_tests,
                        "{spec}, {name}, {mode:?}: {soft:?}"
                    );
                    outcomes[0] += soft.plane_rejected_tests as u64;
                    outcomes[1] += soft.edge_rejected_tests as u64;
                    outcomes[2] += soft.wedge_rejected_tests as u64;
                    outcomes[3] += soft.past_sphere_tests as u64;
                }
                chunk += with.stats.chunk_pairs_dropped as u64;
                chunk_beyond += with.stats.chunk_pairs_beyond_reach as u64;
                bin_beyond += with.stats.bins_dropped_beyond_reach as u64;
                bin_hull += with.stats.bins_dropped_outside_hull as u64;
                // The reach rule per (sample, pair) runs with the clusters
                // off too (it is occlusion's own early out).
                beyond += with.stats.soft.as_ref().unwrap().beyond_reach_pairs as u64;
                hull += with.stats.soft.as_ref().unwrap().outside_hull_pairs as u64;
                light_side += a;
                behind_closed += b;
                penumbra += p;
                cases += 1;
            }
        }
    }
    eprintln!(
        "{cases} cases; bins dropped: {light_side} light side, {behind_closed} behind closed, {bin_beyond} beyond reach, {bin_hull} outside the hull; chunk visits dropped: {chunk} ({penumbra} outside penumbra, {chunk_beyond} beyond reach); (sample, pair) visits beyond reach: {beyond}, outside the hull: {hull}"
    );
    assert!(
        light_side > 0
            && behind_closed > 0
            && penumbra > 0
            && chunk > 0
            && chunk_beyond > 0
            && bin_beyond > 0
            && bin_hull > 0
            && beyond > 0
            && hull > 0,
        "every rule exercised"
    );
    eprintln!(
        "tests: {} rejected by the caster's plane, {} by an edge's plane, {} by the wedge rule, {} past all three",
        outcomes[0], outcomes[1], outcomes[2], outcomes[3]
    );
    assert!(outcomes.iter().all(|&n| n > 0), "every test outcome seen");
    assert_eq!(
        lut_wedge, 0,
        "the wedge rule is compiled out of look-up mode"
    );
    assert!(exact_wedge > 0, "the wedge rule rejects in exact mode");
    engine.context().check_validation().unwrap();
}
