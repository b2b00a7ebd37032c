#version 450
// Conservative binning of (caster, face) pairs into tiles of
// TILE x TILE light texels: every tile the pair's projection may touch.
// SCATTER = 0 counts pairs per tile; SCATTER = 1 writes them at the
// scanned offsets. A tile's view-sample box drops the casters that cannot
// block any of its samples (clusters_common.glsl: bin_rule); a soft pair
// of many tiles is tested against the boxes of blocks of tiles first
// (BY_BLOCKS). Dispatched over the pairs written (casters_clip_args.comp).
// Twin: cpu::tile_bin::bin_pairs.
#extension GL_GOOGLE_include_directive : require
#include "clusters_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;
layout(constant_id = 1) const uint SCATTER = 0u;
// 1 for soft shadows: the view-sample clusters' code, compiled out for hard
// shadows (they get no boxes: gpu::clusters; lavapipe runs guarded code).
layout(constant_id = 4) const uint CLUSTERS = 0u;
// 1: the soft pairs of more than CLUSTER_BLOCK_PAIR_TILES tiles, by blocks
// of tiles; 0: the others, row by row. (Two pipelines: with both loops in
// one, lavapipe's code for the rows ran slower.)
layout(constant_id = 5) const uint BY_BLOCKS = 0u;

layout(set = 0, binding = 0) readonly buffer Pairs { CasterFace pairs[]; };
layout(set = 0, binding = 1) buffer Counters { uint counters[]; };
layout(set = 0, binding = 2) buffer TileCounts { uint tile_counts[]; }; // counts, or cursors when scattering
layout(set = 0, binding = 3) uniform usamplerBuffer tile_offsets_tb; // scattering: each tile's first slot
layout(set = 0, binding = 4) writeonly buffer TilePairs { uint tile_pairs[]; };
// Texel buffers (on lavapipe ~10x faster gathers than storage buffers).
// The texel count pass's per-tile buffer: longest lists, then the tiles'
// occupancy bits (occupancy_word), which binning reads once per row word.
layout(set = 0, binding = 5) uniform usamplerBuffer tile_occupancy_tb;
layout(set = 0, binding = 6) uniform usamplerBuffer boxes_tb; // per tile: lo (w: valid), hi (clusters_bounds), float bits
// Per pair whose rectangle spans at most 32 tiles: the tiles the count
// kept, bit (ty - t0.y) * columns + (tx - t0.x). The scatter writes those
// without the occupancy look-ups and the rules (the same tiles, so the
// lists equal the count's).
layout(set = 0, binding = 8) buffer PairTiles { uint pair_tiles[]; };
// The large pairs (shadow_common.glsl: large_pair) by index: the BY_BLOCKS
// pipeline's invocations, one each, so that its lanes are all busy (over
// all pairs, most lanes had none).
// (Binning reads no triangles: a soft pair carries its own,
// soft_pair_triangle, and hard pairs need none.)
layout(set = 0, binding = 7) uniform usamplerBuffer large_pairs_tb;

// What binning found for a pair (the count's drops per rule, and the
// tiles kept of a pair of few tiles).
struct PairBins {
    uint light_side, behind_closed, far, outside, kept_tiles;
};

// Pair i into `tile`: counted, or written at the tile's next slot.
void bin_into(uint i, uint tile) {
    if (SCATTER == 0u) {
        atomicAdd(tile_counts[tile], 1u);
    } else {
        uint slot = texelFetch(tile_offsets_tb, int(tile)).x + atomicAdd(tile_counts[tile], 1u);
        // A caller's recording binds a list of fixed capacity: past it,
        // record_args.comp reports the overflow and runs no unit.
        if (slot < uint(tile_pairs.length())) {
            tile_pairs[slot] = i;
        }
    }
}

// `n` tiles dropped by `rule` (none for CLUSTER_KEEP), in the count's
// per-rule drops.
void count_drops(uint rule, uint n, inout PairBins b) {
    b.light_side += rule == CLUSTER_LIGHT_SIDE ? n : 0u;
    b.behind_closed += rule == CLUSTER_BEHIND_CLOSED ? n : 0u;
    b.far += rule == CLUSTER_BEYOND_REACH ? n : 0u;
    b.outside += rule == CLUSTER_OUTSIDE_HULL ? n : 0u;
}

// Pair i's occupied tile (tx, ty) of its face: the edge test (hard pairs)
// and the rules for the tile's box (soft pairs), then the count or the
// write.
void bin_tile(uint i, CasterFace cf, ClusterPlane plane, uvec2 rmin, uvec2 rmax, uvec2 t0, uvec2 span,
              bool few, uint base, uint tx, uint ty, inout PairBins b) {
    // The part of the tile inside the rectangle.
    vec2 lo = vec2(max(uvec2(tx, ty) * TILE, rmin));
    vec2 hi = vec2(min(uvec2(tx, ty) * TILE + TILE - 1u, rmax) + 1u);
    // Soft pairs (the CLUSTERS pipeline) carry no edges (soft_caster):
    // their edge test is compiled out, since lavapipe runs an `if` that no
    // lane takes.
    if (CLUSTERS == 0u && cf.e0.w != 0.0
        && !square_overlaps(cf.e0.xyz, cf.e1.xyz, cf.e2.xyz, vec2(cf.e0.w, cf.e1.w), lo, hi)) {
        return;
    }
    uint tile = base + ty * pc.more.y + tx;
    vec4 box_lo = CLUSTERS != 0u ? uintBitsToFloat(texelFetch(boxes_tb, int(2u * tile))) : vec4(0.0);
    if (CLUSTERS != 0u && box_lo.w != 0.0) {
        vec3 box_hi = uintBitsToFloat(texelFetch(boxes_tb, int(2u * tile + 1u)).xyz);
        uint rule = bin_rule(plane, box_lo.xyz, box_hi);
        count_drops(rule, 1u, b);
        if (rule != CLUSTER_KEEP) {
            return;
        }
    }
    b.kept_tiles |= few ? 1u << ((ty - t0.y) * span.x + (tx - t0.x)) : 0u;
    bin_into(i, tile);
}

// The occupied tiles of row ty of the face in columns [first, last] of
// occupancy word w.
uint occupied_tiles(uint face, uint ty, uint w, uint first, uint last) {
    uint columns = (last == 31u ? 0xffffffffu : (1u << (last + 1u)) - 1u) & ~((1u << first) - 1u);
    return texelFetch(tile_occupancy_tb, int(occupancy_word(face, ty, w))).x & columns;
}

void main() {
    uint k = spread_workgroup() * WORKGROUP_1D + gl_LocalInvocationID.x;
    uint listed = BY_BLOCKS != 0u ? counters[COUNTER_LARGE_PAIRS] : counters[COUNTER_PAIRS];
    if (k >= min(listed, pc.more.x)) {
        return;
    }
    uint i = BY_BLOCKS != 0u ? texelFetch(large_pairs_tb, int(k)).x : k;
    CasterFace cf = pairs[i];
    uvec2 rmin = pair_rect_min(cf.ids), rmax = pair_rect_max(cf.ids);
    uvec2 t0 = rmin / TILE, t1 = rmax / TILE;
    uint face = cf.ids.y;
    uint base = face * pc.more.z;
    // Boxes exist for soft shadows only (gpu::clusters): hard shadows skip
    // the plane, and every tile's box is invalid.
    ClusterPlane plane;
    plane.n = vec3(0.0);
    if (CLUSTERS != 0u) {
        uvec4 t0, t1, t2;
        soft_pair_triangle(floatBitsToUint(cf.e0), floatBitsToUint(cf.e1), floatBitsToUint(cf.e2), t0, t1, t2);
        plane = triangle_cluster_plane(t0, t1, t2);
    }
    PairBins b = PairBins(0u, 0u, 0u, 0u, 0u);
    uvec2 span = t1 - t0 + 1u;
    bool few = span.x * span.y <= 32u;
    if (BY_BLOCKS == 0u && CLUSTERS != 0u && large_pair(rmin, rmax)) {
        return; // the BY_BLOCKS pipeline's pair (its list holds only those)
    }
    if (SCATTER != 0u) {
        // A loop, not an `if`: lavapipe skips a loop no lane enters.
        uint kept = few ? pair_tiles[i] : 0u;
        while (kept != 0u) {
            uint bit = uint(findLSB(kept));
            kept &= kept - 1u;
            bin_into(i, base + (t0.y + bit / span.x) * pc.more.y + t0.x + bit % span.x);
        }
    }
    // Row by row (the scatter's pairs of few tiles are done above).
    uint last_row = (SCATTER != 0u && few) || BY_BLOCKS != 0u ? 0u : t1.y + 1u;
    for (uint ty = t0.y; ty < last_row; ty++) {
        for (uint w = t0.x / 32u; w <= t1.x / 32u; w++) {
            uint occupied = occupied_tiles(face, ty, w, max(t0.x, w * 32u) - w * 32u, min(t1.x, w * 32u + 31u) - w * 32u);
            while (occupied != 0u) {
                uint tx = w * 32u + uint(findLSB(occupied));
                occupied &= occupied - 1u;
                bin_tile(i, cf, plane, rmin, rmax, t0, span, few, base, tx, ty, b);
            }
        }
    }
    // By blocks (clusters_common.glsl, CLUSTER_BLOCK): a row of blocks at a
    // time, each occupancy word's four rows fetched once, and only the
    // blocks with occupied tiles in the rectangle visited. The rules for
    // the block's box come first where it holds enough occupied tiles; a
    // block they drop drops each of those tiles (and counts them so).
    uint last_block_row = BY_BLOCKS != 0u ? t1.y / CLUSTER_BLOCK + 1u : 0u;
    for (uint by = t0.y / CLUSTER_BLOCK; by < last_block_row; by++) {
        uint r0 = max(t0.y, by * CLUSTER_BLOCK), r1 = min(t1.y, by * CLUSTER_BLOCK + CLUSTER_BLOCK - 1u);
        for (uint w = t0.x / 32u; w <= t1.x / 32u; w++) {
            uint first = max(t0.x, w * 32u) - w * 32u, last = min(t1.x, w * 32u + 31u) - w * 32u;
            // The rectangle's occupied tiles of the block row's four rows
            // (rows past the rectangle: none).
            uint occ0 = occupied_tiles(face, r0, w, first, last);
            uint occ1 = occupied_tiles(face, min(r0 + 1u, r1), w, first, last);
            uint occ2 = occupied_tiles(face, min(r0 + 2u, r1), w, first, last);
            uint occ3 = occupied_tiles(face, min(r0 + 3u, r1), w, first, last);
            occ1 = r0 + 1u <= r1 ? occ1 : 0u;
            occ2 = r0 + 2u <= r1 ? occ2 : 0u;
            occ3 = r0 + 3u <= r1 ? occ3 : 0u;
            uint blocks = occ0 | occ1 | occ2 | occ3;
            while (blocks != 0u) {
                uint shift = uint(findLSB(blocks)) & ~(CLUSTER_BLOCK - 1u);
                uint columns = ((1u << CLUSTER_BLOCK) - 1u) << shift;
                blocks &= ~columns;
                uint o0 = occ0 & columns, o1 = occ1 & columns, o2 = occ2 & columns, o3 = occ3 & columns;
                uint n = uint(bitCount(o0) + bitCount(o1) + bitCount(o2) + bitCount(o3));
                uint at = cluster_block_box(face, uvec2((w * 32u + shift) / CLUSTER_BLOCK, by));
                vec4 block_lo = uintBitsToFloat(texelFetch(boxes_tb, int(at)));
                bool test = n >= CLUSTER_BLOCK_MIN_TILES && block_lo.w != 0.0;
                vec3 block_hi = uintBitsToFloat(texelFetch(boxes_tb, int(at + 1u)).xyz);
                uint block_rule = bin_rule(plane, block_lo.xyz, block_hi);
                uint rule = test ? block_rule : CLUSTER_KEEP;
                count_drops(rule, n, b);
                uint keep = rule == CLUSTER_KEEP ? 0xffffffffu : 0u;
                for (uint dy = 0u; dy < CLUSTER_BLOCK; dy++) {
                    uint occupied = keep & (dy == 0u ? o0 : (dy == 1u ? o1 : (dy == 2u ? o2 : o3)));
                    while (occupied != 0u) {
                        uint tx = w * 32u + uint(findLSB(occupied));
                        occupied &= occupied - 1u;
                        bin_tile(i, cf, plane, rmin, rmax, t0, span, few, base, tx, r0 + dy, b);
                    }
                }
            }
        }
    }
    if (SCATTER == 0u && few) {
        pair_tiles[i] = b.kept_tiles;
    }
    if (SCATTER == 0u && b.light_side != 0u) {
        atomicAdd(counters[COUNTER_CLUSTER_LIGHT_SIDE], b.light_side);
    }
    if (SCATTER == 0u && b.behind_closed != 0u) {
        atomicAdd(counters[COUNTER_CLUSTER_BEHIND_CLOSED], b.behind_closed);
    }
    if (SCATTER == 0u && b.far != 0u) {
        atomicAdd(counters[COUNTER_BIN_BEYOND_REACH], b.far);
    }
    if (SCATTER == 0u && b.outside != 0u) {
        atomicAdd(counters[COUNTER_BIN_OUTSIDE_HULL], b.outside);
    }
}
