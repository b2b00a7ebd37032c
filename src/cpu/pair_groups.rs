//! CPU twin of `pair_groups.comp`: per binned pair of a tile, the groups of
//! the tile's listed samples ([`CLUSTER_GROUP_SAMPLES`] each, counted from
//! the group its first sample falls in) that the pair may shadow. Bit `j`
//! is clear where soft occlusion's chunk rule
//! ([`crate::cpu::clusters::chunk_rule`]) drops the pair for group `j`'s box
//! ([`crate::cpu::clusters::group_boxes`]); a group without a box keeps
//! every pair. A tile whose samples span fewer than [`CLUSTER_GROUP_MIN`]
//! groups gets no bits (the GPU writes none there, and its chunks' own
//! rules decide; the twin gives `u32::MAX`). Soft occlusion skips a pair
//! for a chunk of 64 samples when the bits of both groups the chunk lies
//! in are clear: the pair is then one that each of its samples culls, so
//! the masks do not change.

use super::clusters::{
    chunk_rule, cluster_plane, groups_spanned, ClusterLight, TileBox, CLUSTER_GROUP_BITS,
    CLUSTER_GROUP_MIN, CLUSTER_GROUP_SAMPLES,
};
use glam::Vec3;

/// The group bits of the pair in each slot of the tile lists:
/// `tile_offsets` (one entry per tile and the total) splits `tile_pairs`
/// (pair indices into `pair_triangles`, each a triangle's vertices and
/// whether it is closed) into tiles; `sample_offsets` (one entry per tile
/// and the total) splits the listed samples into tiles.
pub fn pair_groups(
    tile_offsets: &[u32],
    tile_pairs: &[u32],
    pair_triangles: &[([Vec3; 3], bool)],
    sample_offsets: &[u32],
    group_boxes: &[Option<TileBox>],
    light: &ClusterLight,
) -> Vec<u32> {
    let mut out = vec![0u32; tile_pairs.len()];
    for (t, w) in tile_offsets.windows(2).enumerate() {
        let (begin, end) = (sample_offsets[t], sample_offsets[t + 1]);
        let g0 = begin / CLUSTER_GROUP_SAMPLES;
        let groups = groups_spanned(begin, end);
        for k in w[0] as usize..w[1] as usize {
            out[k] = match groups < CLUSTER_GROUP_MIN {
                true => u32::MAX,
                false => {
                    let (v, closed) = pair_triangles[tile_pairs[k] as usize];
                    let plane = cluster_plane(v, closed, light);
                    (0..groups.min(CLUSTER_GROUP_BITS))
                        .filter(|&j| match group_boxes[(g0 + j) as usize] {
                            Some(b) => chunk_rule(&plane, &b, light).is_none(),
                            None => true,
                        })
                        .fold(0, |bits, j| bits | 1 << j)
                }
            };
        }
    }
    out
}

/// Whether a chunk of 64 listed samples from `chunk_first` (in a tile whose
/// samples span `tile_first..tile_end`) needs a pair with group bits
/// `bits` (`soft_occlusion.comp`, `keep_pairs`; every pair in a tile of
/// fewer than [`CLUSTER_GROUP_MIN`] groups, whose bits are not written).
pub fn chunk_needs(bits: u32, chunk_first: u32, tile_first: u32, tile_end: u32) -> bool {
    let last = (chunk_first + 63).min(tile_end.max(1) - 1);
    let base = tile_first / CLUSTER_GROUP_SAMPLES;
    let (ga, gb) = (
        chunk_first / CLUSTER_GROUP_SAMPLES - base,
        last / CLUSTER_GROUP_SAMPLES - base,
    );
    let few_groups = groups_spanned(tile_first, tile_end) < CLUSTER_GROUP_MIN;
    few_groups || gb >= CLUSTER_GROUP_BITS || bits & (1 << ga | 1 << gb) != 0
}
