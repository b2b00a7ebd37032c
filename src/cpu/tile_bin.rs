//! CPU twin of the conservative rasterization's binning (`tile_bin.comp`,
//! paper §3.2): every (caster, face) pair goes into the list of each tile
//! of [`TILE`]² light texels that its texel rectangle and edge functions
//! may touch, unless the tile holds no view sample or the tile's
//! view-sample box drops the caster ([`crate::cpu::clusters::bin_rule`]).
//! With boxes, a pair whose rectangle spans more than
//! [`CLUSTER_BLOCK_PAIR_TILES`] tiles is first tested against the box of
//! each block of [`CLUSTER_BLOCK`]² tiles that holds at least
//! [`CLUSTER_BLOCK_MIN_TILES`] of the rectangle's occupied tiles: a block
//! the rules drop drops each of those (and counts each so).
//!
//! The GPU appends pairs to a tile's list in atomic order, so its lists
//! equal the twin's as sets. [`crate::cpu::occlusion`] visits the touched
//! texels directly, without tiles: a reference for the binning too.

use super::casters::{square_overlaps, CasterFace};
use super::clusters::{
    bin_rule, cluster_plane, ClusterLight, ClusterRule, TileBox, CLUSTER_BLOCK,
    CLUSTER_BLOCK_MIN_TILES, CLUSTER_BLOCK_PAIR_TILES,
};
use crate::gpu::shared::GpuCasterFace;

/// Texels per side of a rasterization tile (`TILE` in `shadow_common.glsl`).
pub const TILE: u32 = 8;

/// Whether texel (tx, ty) is touched by the pair's projection (conservative).
pub fn texel_touched(cf: &CasterFace, tx: u32, ty: u32) -> bool {
    match &cf.edges {
        Some((e, m)) => square_overlaps(
            e,
            *m,
            tx as f32,
            ty as f32,
            tx as f32 + 1.0,
            ty as f32 + 1.0,
        ),
        None => true,
    }
}

/// The tiles (x, y) of its face that the pair's rectangle and edges may
/// touch: for each tile the rectangle meets, the part of the tile inside
/// the rectangle against the edges.
pub fn tiles_touched(cf: &CasterFace) -> Vec<(u32, u32)> {
    let [x0, y0, x1, y1] = cf.rect;
    let mut out = Vec::new();
    for ty in y0 / TILE..=y1 / TILE {
        for tx in x0 / TILE..=x1 / TILE {
            let lo = [(tx * TILE).max(x0), (ty * TILE).max(y0)];
            let hi = [
                (tx * TILE + TILE - 1).min(x1) + 1,
                (ty * TILE + TILE - 1).min(y1) + 1,
            ];
            let touched = match &cf.edges {
                Some((e, m)) => square_overlaps(
                    e,
                    *m,
                    lo[0] as f32,
                    lo[1] as f32,
                    hi[0] as f32,
                    hi[1] as f32,
                ),
                None => true,
            };
            if touched {
                out.push((tx, ty));
            }
        }
    }
    out
}

/// The view-sample clusters the binning tests casters against.
pub struct BinClusters<'a> {
    /// Per tile, the box of its listed samples.
    pub boxes: &'a [Option<TileBox>],
    /// Per block of tiles, the union of its tiles' boxes
    /// ([`crate::cpu::clusters::block_boxes`]).
    pub blocks: &'a [Option<TileBox>],
    /// The light the rules test the boxes against.
    pub light: ClusterLight,
    /// Per triangle of the run: vertices (camera-relative) and whether it
    /// belongs to a closed mesh.
    pub triangles: &'a [([glam::Vec3; 3], bool)],
}

/// What binning kept and dropped.
#[derive(Clone, Debug, Default)]
pub struct Bins {
    /// Per tile (index `face · tiles_per_row² + y · tiles_per_row + x`), the
    /// indices into the pairs of the pairs binned there.
    pub tiles: Vec<Vec<u32>>,
    /// (Pair, tile) bins dropped because every sample of the tile's box is
    /// on the light's side of the caster's plane.
    pub dropped_light_side: u32,
    /// (Pair, tile) bins dropped because every sample of the tile's box is
    /// behind a closed caster (soft shadows).
    pub dropped_behind_closed: u32,
    /// (Pair, tile) bins dropped because the caster lies beyond the reach
    /// of every sample of the tile's box (soft shadows).
    pub dropped_beyond_reach: u32,
    /// (Pair, tile) bins dropped because the caster's ball lies outside the
    /// hull of the box's ball and the light's sphere (soft shadows).
    pub dropped_outside_hull: u32,
    /// Of the dropped bins, those dropped by their block's box (each is
    /// also counted under its rule).
    pub dropped_by_blocks: u32,
}

/// Bins every pair into the tiles it touches; `occupied[tile]`: whether the
/// tile holds any view sample.
pub fn bin_pairs(
    pairs: &[CasterFace],
    tiles_per_row: u32,
    occupied: &[bool],
    clusters: Option<&BinClusters>,
) -> Bins {
    let per_face = tiles_per_row * tiles_per_row;
    let mut bins = Bins {
        tiles: vec![Vec::new(); occupied.len()],
        ..Bins::default()
    };
    let per_row = tiles_per_row.div_ceil(CLUSTER_BLOCK);
    for (i, cf) in pairs.iter().enumerate() {
        let plane = clusters.map(|c| {
            let (v, closed) = c.triangles[cf.triangle as usize];
            cluster_plane(v, closed, &c.light)
        });
        let [x0, y0, x1, y1] = cf.rect.map(|t| t / TILE);
        let by_blocks =
            clusters.is_some() && (x1 - x0 + 1) * (y1 - y0 + 1) > CLUSTER_BLOCK_PAIR_TILES;
        // Per block of a pair binned by blocks: the rule that dropped it.
        let mut block_rules = std::collections::HashMap::new();
        if let (true, Some(c), Some(p)) = (by_blocks, clusters, &plane) {
            for by in y0 / CLUSTER_BLOCK..=y1 / CLUSTER_BLOCK {
                for bx in x0 / CLUSTER_BLOCK..=x1 / CLUSTER_BLOCK {
                    let tiles: Vec<_> = (by * CLUSTER_BLOCK..(by + 1) * CLUSTER_BLOCK)
                        .filter(|ty| (y0..=y1).contains(ty))
                        .flat_map(|ty| {
                            (bx * CLUSTER_BLOCK..(bx + 1) * CLUSTER_BLOCK)
                                .filter(|tx| (x0..=x1).contains(tx))
                                .map(move |tx| {
                                    (cf.face * per_face + ty * tiles_per_row + tx) as usize
                                })
                        })
                        .filter(|&t| occupied[t])
                        .collect();
                    let block = ((cf.face * per_row + by) * per_row + bx) as usize;
                    let rule = match c.blocks[block] {
                        Some(b) if tiles.len() as u32 >= CLUSTER_BLOCK_MIN_TILES => {
                            bin_rule(p, &b, &c.light)
                        }
                        _ => None,
                    };
                    if let Some(rule) = rule {
                        block_rules.insert((bx, by), rule);
                    }
                }
            }
        }
        for (tx, ty) in tiles_touched(cf) {
            let tile = (cf.face * per_face + ty * tiles_per_row + tx) as usize;
            if !occupied[tile] {
                continue;
            }
            let block_rule = block_rules.get(&(tx / CLUSTER_BLOCK, ty / CLUSTER_BLOCK));
            bins.dropped_by_blocks += u32::from(block_rule.is_some());
            let rule = match (clusters, &plane) {
                (Some(c), Some(p)) => block_rule
                    .copied()
                    .or_else(|| c.boxes[tile].and_then(|b| bin_rule(p, &b, &c.light))),
                _ => None,
            };
            match rule {
                Some(ClusterRule::LightSide) => bins.dropped_light_side += 1,
                Some(ClusterRule::BehindClosed) => bins.dropped_behind_closed += 1,
                Some(ClusterRule::BeyondReach) => bins.dropped_beyond_reach += 1,
                Some(ClusterRule::OutsideHull) => bins.dropped_outside_hull += 1,
                // (bin_rule has no penumbra rule: soft occlusion's chunks
                // apply it.)
                Some(ClusterRule::OutsidePenumbra) | None => bins.tiles[tile].push(i as u32),
            }
        }
    }
    bins
}

/// A pair as the GPU wrote it (`CasterFace` of `shadow_common.glsl`):
/// the edges are valid when the x margin (`e0.w`) is not 0.
pub fn caster_face_from_gpu(g: &GpuCasterFace) -> CasterFace {
    let [triangle, face, min, max] = g.ids;
    let e = |k: usize| [g.edges[k][0], g.edges[k][1], g.edges[k][2]];
    CasterFace {
        triangle,
        face,
        rect: [min & 0xffff, min >> 16, max & 0xffff, max >> 16],
        edges: (g.edges[0][3] != 0.0).then(|| ([e(0), e(1), e(2)], [g.edges[0][3], g.edges[1][3]])),
    }
}
