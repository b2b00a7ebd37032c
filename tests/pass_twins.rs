//! Each GPU pass's buffers after a run, against its CPU twin in the module
//! of the same name, fed the same inputs (the GPU's own outputs of the
//! passes before it): the light view's windows (`cpu::light_view`), the
//! texel lists' counts and texels (`cpu::texel_lists`), the tile bins
//! with their view-sample boxes (`cpu::tile_bin`, `cpu::clusters`), the
//! binned pairs' sample groups (`cpu::pair_groups`), the hard resolve and
//! the soft resolve
//! (`cpu::resolve`). The passes keep their buffers across frames, so the
//! test reads them where the run left them.

use alias_free_shadows::cpu::casters::CasterFace;
use alias_free_shadows::cpu::clusters::{
    block_boxes, group_boxes, groups_spanned, tile_boxes, ClusterLight, TileBox, CLUSTER_GROUP_MIN,
};
use alias_free_shadows::cpu::light_view::{fit_windows, LightView};
use alias_free_shadows::cpu::pair_groups::{chunk_needs, pair_groups};
use alias_free_shadows::cpu::resolve::{resolve_hard, resolve_soft};
use alias_free_shadows::cpu::texel_lists::{build_texel_lists, tile_occupancy, NOT_LISTED};
use alias_free_shadows::cpu::tile_bin::{bin_pairs, caster_face_from_gpu, BinClusters, TILE};
use alias_free_shadows::gpu::shared::{
    counter, GpuCasterFace, GpuLightFace, GpuViewSample, TRIANGLE_CLOSED,
};
use alias_free_shadows::gpu::{gpu_inputs, ShadowOutput, ShadowPipeline, SoftLight};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::render;
use alias_free_shadows::scene::file::{self, ShadowSettings, SoftMode};
use alias_free_shadows::vulkan::{ContextOptions, GpuContext, GrowBuffer};
use glam::Vec3;

mod common;

/// A scene's view samples (the oracle's primary hits, camera-relative
/// f32) with their triangles, and the scene's triangles in GPU form.
struct Inputs {
    samples: Vec<Option<(Vec3, Vec3)>>,
    gpu_samples: Vec<GpuViewSample>,
    gpu_triangles: Vec<alias_free_shadows::gpu::shared::GpuTriangle>,
    desc: file::SceneDescription,
}

fn inputs(spec: &str, size: u32) -> Inputs {
    let mut desc = file::load(spec).unwrap();
    desc.camera.width = size;
    desc.camera.height = size;
    let eye = desc.camera.eye;
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = common::engine_view_samples(&oracle, &desc);
    let with_ids: Vec<_> = view
        .samples
        .iter()
        .map(|s| s.map(|s| ((s.position - eye).as_vec3(), s.normal.as_vec3(), s.triangle)))
        .collect();
    let (gpu_samples, gpu_triangles) =
        gpu_inputs(&with_ids, &render::gpu_triangles(&desc.scene, eye));
    Inputs {
        samples: with_ids.iter().map(|s| s.map(|(p, n, _)| (p, n))).collect(),
        gpu_samples,
        gpu_triangles,
        desc,
    }
}

fn read<T: bytemuck::Pod>(ctx: &GpuContext, b: &GrowBuffer, count: usize) -> Vec<T> {
    ctx.read_buffer_staged(b.buffer(), 0, count).unwrap()
}

/// The tile-major list index of texel (tx, ty) of `face` (`texel_index` in
/// shadow_common.glsl): the texels of an 8 x 8 tile in Z order.
fn tile_major(face: u32, tx: u32, ty: u32, tiles_per_row: u32) -> usize {
    let tile = face * tiles_per_row * tiles_per_row + (ty / TILE) * tiles_per_row + tx / TILE;
    let (x, y) = (tx % TILE, ty % TILE);
    let z_order = (0..3).fold(0, |z, bit| {
        z | ((x >> bit) & 1) << (2 * bit) | ((y >> bit) & 1) << (2 * bit + 1)
    });
    (tile * TILE * TILE + z_order) as usize
}

/// The light view, texel lists, tile bins and resolve of the last run
/// against their twins (hard shadows of `light`).
fn check_hard_passes(
    ctx: &GpuContext,
    pipeline: &ShadowPipeline,
    inp: &Inputs,
    light: &LightView,
    res: u32,
) {
    let passes = pipeline.passes();
    let faces = light.face_count();
    let listed: Vec<(Vec3, Vec3)> = inp.samples.iter().flatten().copied().collect();

    // Light view: every face's window, bit for bit.
    let windows = fit_windows(light, &listed, res);
    let gpu_faces: Vec<GpuLightFace> = read(ctx, &passes.light_view.faces, 6);
    for (f, w) in windows.iter().enumerate() {
        let g = &gpu_faces[f];
        assert_eq!(g.right[3] == 1.0, w.valid, "face {f}: validity");
        if w.valid {
            assert_eq!(
                [g.window[0], g.window[1], g.window[2], g.window[3], g.far[0]].map(f32::to_bits),
                [w.x0, w.y0, w.sx, w.sy, w.z_far].map(f32::to_bits),
                "face {f}: window"
            );
        }
    }

    // Texel lists: every texel's count and every sample's texel.
    let lists = build_texel_lists(light, &windows, &inp.samples, res);
    let tpr = res.div_ceil(TILE);
    let texels = faces * (tpr * TILE * tpr * TILE) as usize;
    let counts: Vec<u32> = read(ctx, &passes.texel_lists.counts, texels);
    for f in 0..faces as u32 {
        for ty in 0..res {
            for tx in 0..res {
                let cpu = lists.counts[(f * res * res + ty * res + tx) as usize];
                assert_eq!(
                    counts[tile_major(f, tx, ty, tpr)],
                    cpu,
                    "texel ({f}, {tx}, {ty})"
                );
            }
        }
    }
    // The tiles' occupancy bits, after the per-tile longest lengths.
    let tiles = faces * (tpr * tpr) as usize;
    let occupancy = tile_occupancy(&lists.counts, res, faces as u32);
    let words: Vec<u32> = read(
        ctx,
        &passes.texel_lists.tile_max_len,
        tiles + occupancy.len(),
    );
    assert_eq!(&words[tiles..], &occupancy[..], "tile occupancy");
    assert!(
        occupancy.iter().any(|&w| w != 0),
        "the case must occupy tiles"
    );
    let n = inp.samples.len();
    let sample_texel: Vec<u32> = read(ctx, &passes.texel_lists.sample_texel, n);
    for (i, (&g, &c)) in sample_texel.iter().zip(&lists.sample_texel).enumerate() {
        let want = match c {
            NOT_LISTED => NOT_LISTED,
            t => {
                let (f, rest) = (t / (res * res), t % (res * res));
                tile_major(f, rest % res, rest / res, tpr) as u32
            }
        };
        assert_eq!(g, want, "sample {i}: texel");
    }

    // Tile bins: the GPU's pairs binned by the twin, per tile as sets.
    let cluster_light = match *light {
        LightView::Point { position } => ClusterLight::Point(position),
        LightView::Directional { direction } => ClusterLight::Directional(direction),
    };
    let (pair_count, total, _, _) = check_bins(ctx, pipeline, inp, faces, tpr, cluster_light);

    // Hard resolve: the shadow flags per list slot to lit per sample.
    let slots: Vec<u32> = read(ctx, &passes.texel_lists.sample_slot, n);
    let shadowed: Vec<u32> = read(ctx, &passes.occlusion.shadowed, n);
    let result: Vec<u32> = read(ctx, &passes.resolve.result, n);
    let gpu_lit: Vec<Option<bool>> = result
        .iter()
        .map(|&r| (r & 2 != 0).then_some(r & 1 != 0))
        .collect();
    assert_eq!(gpu_lit, resolve_hard(&sample_texel, &slots, &shadowed));
    eprintln!(
        "{}: {} faces, {} listed samples, {pair_count} pairs, {total} binned",
        inp.desc.name,
        windows.iter().filter(|w| w.valid).count(),
        lists.list.len()
    );
    assert!(
        total > 0 && !lists.list.is_empty(),
        "the case must exercise the passes"
    );
}

/// The view-sample boxes and tile bins of the last run against their
/// twins (fed the GPU's lists and pairs), and for soft shadows the binned
/// pairs' group bits; returns (pairs, binned pairs, bins the twin dropped
/// by blocks of tiles, and the (pair, chunk) visits that the twin's bits
/// rule out per pass over the units with the number soft occlusion
/// counted).
/// Hard shadows (`light` not a sphere) get no boxes.
/// The GPU's boxes (lo with w = 1 when valid, hi) against the twin's, bit
/// for bit; `what` names them in the messages.
fn assert_boxes_equal(gpu: &[[f32; 4]], twin: &[Option<TileBox>], what: &str) {
    for (k, b) in twin.iter().enumerate() {
        let (lo, hi) = (gpu[2 * k], gpu[2 * k + 1]);
        assert_eq!(lo[3] == 1.0, b.is_some(), "{what} {k}: box validity");
        if let Some(b) = b {
            assert_eq!(
                [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits),
                [b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z].map(f32::to_bits),
                "{what} {k}: box"
            );
        }
    }
}

fn check_bins(
    ctx: &GpuContext,
    pipeline: &ShadowPipeline,
    inp: &Inputs,
    faces: usize,
    tpr: u32,
    light: ClusterLight,
) -> (usize, usize, u32, (u32, u32)) {
    let soft = matches!(light, ClusterLight::Sphere(..));
    let passes = pipeline.passes();
    let tiles = faces * (tpr * tpr) as usize;
    let texels = tiles * 64;
    let counts: Vec<u32> = read(ctx, &passes.texel_lists.counts, texels);
    let offsets: Vec<u32> = read(ctx, &passes.texel_lists.offsets, texels + 1);
    let listed = offsets[texels] as usize;
    let list: Vec<[f32; 4]> = read(ctx, &passes.texel_lists.list_samples, listed);
    let positions: Vec<Vec3> = list.iter().map(|q| Vec3::new(q[0], q[1], q[2])).collect();
    let tile_offsets: Vec<u32> = (0..=tiles).map(|t| offsets[t * 64]).collect();
    let boxes = match soft {
        true => tile_boxes(&tile_offsets, &positions),
        false => vec![None; tiles],
    };
    let gpu_boxes: Vec<[f32; 4]> = read(ctx, &passes.clusters.boxes, 2 * tiles);
    assert_boxes_equal(&gpu_boxes, &boxes, "tile");
    let occupied: Vec<bool> = (0..tiles)
        .map(|t| counts[t * 64..(t + 1) * 64].iter().any(|&c| c > 0))
        .collect();
    let blocks = block_boxes(&boxes, &occupied, tpr);
    if soft {
        let gpu_blocks: Vec<[f32; 4]> =
            read(ctx, &passes.clusters.boxes, 2 * (tiles + blocks.len()));
        assert_boxes_equal(&gpu_blocks[2 * tiles..], &blocks, "block");
    }
    let c: Vec<u32> = read(ctx, &passes.counters, counter::COUNT);
    let pair_count = c[counter::PAIRS] as usize;
    let gpu_pairs: Vec<GpuCasterFace> = read(ctx, &passes.casters.pairs, pair_count);
    if soft {
        // A soft pair carries its triangle bit for bit (shadow_common.glsl,
        // CasterFace), which binning and occlusion read instead of the
        // triangles.
        let bits = |v: [f32; 3], w: u32| [v[0].to_bits(), v[1].to_bits(), v[2].to_bits(), w];
        for (k, p) in gpu_pairs.iter().enumerate() {
            let t = &inp.gpu_triangles[p.ids[0] as usize];
            let want = [
                bits(t.v0, 0),
                bits(t.v1, t.flags),
                bits(t.v2, t.alpha_record),
            ];
            assert_eq!(
                p.edges.map(|e| e.map(f32::to_bits)),
                want,
                "pair {k}: its triangle"
            );
        }
    }
    let pairs: Vec<_> = gpu_pairs.iter().map(caster_face_from_gpu).collect();
    let triangles: Vec<([Vec3; 3], bool)> = inp
        .gpu_triangles
        .iter()
        .map(|t| {
            let v = [t.v0, t.v1, t.v2].map(Vec3::from);
            (v, t.flags & TRIANGLE_CLOSED != 0)
        })
        .collect();
    let clusters = BinClusters {
        boxes: &boxes,
        blocks: &blocks,
        light,
        triangles: &triangles,
    };
    let bins = bin_pairs(&pairs, tpr, &occupied, Some(&clusters));
    let offsets: Vec<u32> = read(ctx, &passes.tile_bin.tile_offsets, tiles + 1);
    let total = offsets[tiles] as usize;
    let tile_pairs: Vec<u32> = read(ctx, &passes.tile_bin.tile_pairs, total);
    let mut binned = 0;
    for (t, want) in bins.tiles.iter().enumerate() {
        let mut got = tile_pairs[offsets[t] as usize..offsets[t + 1] as usize].to_vec();
        got.sort_unstable();
        assert_eq!(&got, want, "tile {t}: binned pairs");
        binned += got.len();
    }
    assert_eq!(binned, total);
    assert_eq!(
        [
            c[counter::CLUSTER_LIGHT_SIDE],
            c[counter::CLUSTER_BEHIND_CLOSED],
            c[counter::BIN_BEYOND_REACH],
            c[counter::BIN_OUTSIDE_HULL],
        ],
        [
            bins.dropped_light_side,
            bins.dropped_behind_closed,
            bins.dropped_beyond_reach,
            bins.dropped_outside_hull,
        ],
        "bins dropped per rule (light side, behind closed, beyond reach, outside hull)"
    );
    let dropped = bins.dropped_light_side
        + bins.dropped_behind_closed
        + bins.dropped_beyond_reach
        + bins.dropped_outside_hull;
    eprintln!(
        "{}: {} boxes, dropped {} (light side) + {} (behind closed) + {} (beyond reach) + {} (outside hull) of {} bins",
        inp.desc.name,
        boxes.iter().flatten().count(),
        bins.dropped_light_side,
        bins.dropped_behind_closed,
        bins.dropped_beyond_reach,
        bins.dropped_outside_hull,
        total as u32 + dropped
    );
    let group_dropped = match soft {
        true => {
            let samples = (&positions[..], &tile_offsets[..], &boxes[..], blocks.len());
            let binned = (&offsets[..], &tile_pairs[..], &pairs[..], &triangles[..]);
            check_pair_groups(ctx, pipeline, samples, binned, light)
        }
        false => 0,
    };
    let counted = c[counter::CLUSTER_GROUPS];
    (
        pair_count,
        total,
        bins.dropped_by_blocks,
        (group_dropped, counted),
    )
}

/// The listed samples, their offsets per tile, the tiles' boxes and the
/// number of blocks' boxes.
type ListedSamples<'a> = (&'a [Vec3], &'a [u32], &'a [Option<TileBox>], usize);
/// The tile lists' offsets and pairs, the pairs, and the triangles.
type BinnedPairs<'a> = (
    &'a [u32],
    &'a [u32],
    &'a [CasterFace],
    &'a [([Vec3; 3], bool)],
);

/// The group boxes (after the tiles' and blocks' boxes) and each binned
/// pair's group bits against their twins; returns the (pair, chunk) visits
/// that the twin's bits rule out, per pass over the units.
fn check_pair_groups(
    ctx: &GpuContext,
    pipeline: &ShadowPipeline,
    (positions, sample_offsets, boxes, blocks): ListedSamples,
    (pair_offsets, tile_pairs, pairs, triangles): BinnedPairs,
    light: ClusterLight,
) -> u32 {
    let passes = pipeline.passes();
    let groups = group_boxes(positions);
    let at = boxes.len() + blocks;
    let gpu_boxes: Vec<[f32; 4]> = read(ctx, &passes.clusters.boxes, 2 * (at + groups.len()));
    assert_boxes_equal(&gpu_boxes[2 * at..], &groups, "group");
    let pair_triangles: Vec<_> = pairs
        .iter()
        .map(|p| triangles[p.triangle as usize])
        .collect();
    let want = pair_groups(
        pair_offsets,
        tile_pairs,
        &pair_triangles,
        sample_offsets,
        &groups,
        &light,
    );
    let got: Vec<u32> = read(ctx, &passes.pair_groups.groups, tile_pairs.len());
    for (t, w) in pair_offsets.windows(2).enumerate() {
        let (first, end) = (sample_offsets[t], sample_offsets[t + 1]);
        if groups_spanned(first, end) < CLUSTER_GROUP_MIN {
            continue; // few groups: no bits written (every pair kept)
        }
        for k in w[0] as usize..w[1] as usize {
            assert_eq!(
                got[k], want[k],
                "slot {k} (pair {}): group bits",
                tile_pairs[k]
            );
        }
    }
    // Per tile with a box: each chunk of 64 of its samples against each
    // of its pairs.
    let mut dropped = 0u32;
    for (t, w) in pair_offsets.windows(2).enumerate() {
        let (first, end) = (sample_offsets[t], sample_offsets[t + 1]);
        if boxes[t].is_none() {
            continue;
        }
        for chunk in (first..end).step_by(64) {
            dropped += want[w[0] as usize..w[1] as usize]
                .iter()
                .filter(|&&bits| !chunk_needs(bits, chunk, first, end))
                .count() as u32;
        }
    }
    dropped
}

#[test]
fn hard_passes_match_their_twins() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut pipeline = ShadowPipeline::new(&ctx).unwrap();
    // A point light (six faces, most of them empty) and several texel maps.
    for (spec, res) in [
        ("builtin:plane_sphere", 64),
        ("builtin:columns", 20),
        ("builtin:torus_knot:2000", 128),
    ] {
        let inp = inputs(spec, 80);
        let eye = inp.desc.camera.eye;
        let light = render::light_view(&inp.desc.lights[0], eye).unwrap();
        pipeline
            .run(
                &ctx,
                &inp.gpu_samples,
                &inp.gpu_triangles,
                &light,
                res,
                None,
            )
            .unwrap();
        check_hard_passes(&ctx, &pipeline, &inp, &light, res);
    }
    ctx.check_validation().unwrap();
}

/// Runs the soft passes on `inp` for the bench's sphere light with
/// `samples` light samples at `texels` light texels per face side, and
/// checks the boxes, bins and group bits against their twins, and the
/// (pair, chunk) visits occlusion dropped by those bits against the
/// twin's; returns the output, the light, the bins the twin dropped by
/// blocks of tiles, and those visits.
fn run_soft_checked(
    ctx: &GpuContext,
    pipeline: &mut ShadowPipeline,
    inp: &Inputs,
    settings: &ShadowSettings,
    samples: u32,
    texels: u32,
) -> (ShadowOutput, SoftLight, u32, u32) {
    let light = common::sphere_light(&inp.desc, samples);
    let eye = inp.desc.camera.eye;
    let (sl, lv): (SoftLight, LightView) = render::soft_light(&light, eye, settings).unwrap();
    let out = pipeline
        .run(
            ctx,
            &inp.gpu_samples,
            &inp.gpu_triangles,
            &lv,
            texels,
            Some(&sl),
        )
        .unwrap();
    let LightView::Point { position } = lv else {
        panic!("a light with extent is seen from its centre")
    };
    let sphere = ClusterLight::Sphere(position, sl.bounds().1);
    let tpr = texels.div_ceil(TILE);
    let (_, _, dropped, (by_groups, counted)) =
        check_bins(ctx, pipeline, inp, lv.face_count(), tpr, sphere);
    // Exact mode runs every unit once per block of light samples.
    let runs = match settings.mode {
        SoftMode::Exact => sl.blocks() as u32,
        _ => 1,
    };
    assert_eq!(
        counted,
        runs * by_groups,
        "(pair, chunk) visits dropped by the groups' bits"
    );
    (out, sl, dropped, by_groups)
}

/// Few light texels for the view, so that a tile holds several groups of
/// samples (`CLUSTER_GROUP_SAMPLES`): the group boxes and each binned
/// pair's group bits against the twin's, and the visits they drop, in each
/// mode (the clusters' tests check that the masks stay those of a run
/// without them).
#[test]
fn soft_pair_groups_match_their_twin() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut pipeline = ShadowPipeline::new(&ctx).unwrap();
    let mut by_groups = 0;
    for (spec, texels) in [("builtin:torus_knot:2000", 8), ("builtin:demo", 16)] {
        let inp = inputs(spec, 96);
        for (mode, samples) in [
            (SoftMode::Lut, 128),
            (SoftMode::Exact, 200),
            (SoftMode::Approx, 128),
        ] {
            let settings = ShadowSettings {
                mode,
                ..Default::default()
            };
            let (_, _, _, dropped) =
                run_soft_checked(&ctx, &mut pipeline, &inp, &settings, samples, texels);
            eprintln!("{spec}, {mode:?}: {dropped} (pair, chunk) visits dropped by groups");
            by_groups += dropped;
        }
    }
    assert!(by_groups > 0, "some group must drop a pair");
    ctx.check_validation().unwrap();
}

/// Soft casters whose rectangles span many tiles are binned by blocks of
/// tiles first (the light-texel maps here are large for the view, so that
/// many do): the blocks' boxes and the bins against the twin's.
#[test]
fn soft_bins_by_blocks_match_their_twin() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut pipeline = ShadowPipeline::new(&ctx).unwrap();
    let mut by_blocks = 0;
    for (spec, texels) in [
        ("builtin:torus_knot:2000", 256),
        ("builtin:plane_sphere", 192),
    ] {
        let inp = inputs(spec, 48);
        let settings = ShadowSettings::default();
        let (_, _, dropped, _) =
            run_soft_checked(&ctx, &mut pipeline, &inp, &settings, 128, texels);
        eprintln!("{spec}: {dropped} bins dropped by blocks");
        by_blocks += dropped;
    }
    assert!(by_blocks > 0, "some block must drop its tiles");
    ctx.check_validation().unwrap();
}

#[test]
fn soft_resolve_matches_its_twin() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let mut pipeline = ShadowPipeline::new(&ctx).unwrap();
    let inp = inputs("builtin:demo", 64);
    for (mode, samples) in [(SoftMode::Exact, 200), (SoftMode::Lut, 128)] {
        let settings = ShadowSettings {
            mode,
            ..Default::default()
        };
        let texels = settings.soft_light_texels.resolve(
            inp.gpu_samples.len(),
            inp.gpu_triangles.len(),
            true,
        );
        let (out, sl, _, _) =
            run_soft_checked(&ctx, &mut pipeline, &inp, &settings, samples, texels);
        let passes = pipeline.passes();
        let n = inp.samples.len();
        let words = sl.mask_words();
        let sample_texel: Vec<u32> = read(&ctx, &passes.texel_lists.sample_texel, n);
        let slots: Vec<u32> = read(&ctx, &passes.texel_lists.sample_slot, n);
        let listed = sample_texel.iter().filter(|&&t| t != NOT_LISTED).count();
        let blocked: Vec<u32> = read(&ctx, &passes.soft_occlusion.blocked, listed * words);
        let soft = out.soft.unwrap();
        let mut partly = 0;
        for i in 0..n {
            let got = &soft.visible[i * words..(i + 1) * words];
            if sample_texel[i] == NOT_LISTED {
                assert!(got.iter().all(|&w| w == 0) && soft.visibility[i].is_none());
                continue;
            }
            let (p, nrm) = inp.samples[i].unwrap();
            let s = slots[i] as usize;
            let (want, v) = resolve_soft(p, nrm, &blocked[s * words..(s + 1) * words], &sl.samples);
            assert_eq!(
                got,
                &want[..],
                "{mode:?}: sample {i}: visible light samples"
            );
            assert_eq!(
                soft.visibility[i],
                Some(v),
                "{mode:?}: sample {i}: visibility"
            );
            partly += usize::from(v > 0.0 && v < 1.0);
        }
        eprintln!("{mode:?} {samples}: {listed} listed samples, {partly} in penumbra");
        assert!(partly > 0, "the case must have a penumbra");
    }
    ctx.check_validation().unwrap();
}
