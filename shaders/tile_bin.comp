#version 450
// Conservative binning of (caster, face) pairs into tiles of
// TILE x TILE light texels: every tile the pair's projection may touch.
// SCATTER = 0 counts pairs per tile; SCATTER = 1 writes them at the
// scanned offsets. A tile's view-sample box drops the casters that cannot
// block any of its samples (clusters_common.glsl: bin_rule). Twin:
// cpu::tile_bin::bin_pairs.
#extension GL_GOOGLE_include_directive : require
#include "clusters_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;
layout(constant_id = 1) const uint SCATTER = 0u;
// 1 for soft shadows: the view-sample clusters' code, compiled out for hard
// shadows (they get no boxes: gpu::clusters; lavapipe runs guarded code).
layout(constant_id = 4) const uint CLUSTERS = 0u;

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
layout(set = 0, binding = 7) uniform usamplerBuffer triangles_tb; // GpuTriangle: 3 texels
// Per pair whose rectangle spans at most 32 tiles: the tiles the count
// kept, bit (ty - t0.y) * columns + (tx - t0.x). The scatter writes those
// without the occupancy look-ups and the rules (the same tiles, so the
// lists equal the count's).
layout(set = 0, binding = 8) buffer PairTiles { uint pair_tiles[]; };

void main() {
    uint i = linear_invocation();
    if (i >= min(counters[COUNTER_PAIRS], pc.more.x)) {
        return;
    }
    CasterFace cf = pairs[i];
    uvec2 rmin = pair_rect_min(cf.ids), rmax = pair_rect_max(cf.ids);
    uvec2 t0 = rmin / TILE, t1 = rmax / TILE;
    bool edges = cf.e0.w != 0.0;
    uint face = cf.ids.y;
    uint base = face * pc.more.z;
    // Boxes exist for soft shadows only (gpu::clusters): hard shadows skip
    // the plane, and every tile's box is invalid.
    ClusterPlane plane;
    plane.n = vec3(0.0);
    if (CLUSTERS != 0u) {
        plane = triangle_cluster_plane(triangles_tb, cf.ids.x);
    }
    uint light_side = 0u, behind_closed = 0u, far = 0u, outside = 0u;
    uvec2 span = t1 - t0 + 1u;
    bool few = span.x * span.y <= 32u;
    if (SCATTER != 0u) {
        // A loop, not an `if`: lavapipe skips a loop no lane enters.
        uint kept = few ? pair_tiles[i] : 0u;
        while (kept != 0u) {
            uint bit = uint(findLSB(kept));
            kept &= kept - 1u;
            uint tile = base + (t0.y + bit / span.x) * pc.more.y + t0.x + bit % span.x;
            uint slot = texelFetch(tile_offsets_tb, int(tile)).x + atomicAdd(tile_counts[tile], 1u);
            if (slot < uint(tile_pairs.length())) {
                tile_pairs[slot] = i;
            }
        }
    }
    uint kept_tiles = 0u;
    // The scatter's pairs of few tiles are done above.
    uint last_row = SCATTER != 0u && few ? 0u : t1.y + 1u;
    for (uint ty = t0.y; ty < last_row; ty++) {
        for (uint w = t0.x / 32u; w <= t1.x / 32u; w++) {
            // This word's occupied tiles inside the rectangle's columns.
            uint first = max(t0.x, w * 32u) - w * 32u, last = min(t1.x, w * 32u + 31u) - w * 32u;
            uint columns = (last == 31u ? 0xffffffffu : (1u << (last + 1u)) - 1u) & ~((1u << first) - 1u);
            uint occupied = texelFetch(tile_occupancy_tb, int(occupancy_word(face, ty, w))).x & columns;
            while (occupied != 0u) {
                uint tx = w * 32u + uint(findLSB(occupied));
                occupied &= occupied - 1u;
                // The part of the tile inside the rectangle.
                vec2 lo = vec2(max(uvec2(tx, ty) * TILE, rmin));
                vec2 hi = vec2(min(uvec2(tx, ty) * TILE + TILE - 1u, rmax) + 1u);
                // Soft pairs (the CLUSTERS pipeline) carry no edges
                // (soft_caster): their edge test is compiled out, since
                // lavapipe runs an `if` that no lane takes.
                if (CLUSTERS == 0u && edges && !square_overlaps(cf.e0.xyz, cf.e1.xyz, cf.e2.xyz, vec2(cf.e0.w, cf.e1.w), lo, hi)) {
                    continue;
                }
                uint tile = base + ty * pc.more.y + tx;
                vec4 box_lo = CLUSTERS != 0u ? uintBitsToFloat(texelFetch(boxes_tb, int(2u * tile))) : vec4(0.0);
                if (CLUSTERS != 0u && box_lo.w != 0.0) {
                    vec3 box_hi = uintBitsToFloat(texelFetch(boxes_tb, int(2u * tile + 1u)).xyz);
                    uint rule = bin_rule(plane, box_lo.xyz, box_hi);
                    light_side += rule == CLUSTER_LIGHT_SIDE ? 1u : 0u;
                    behind_closed += rule == CLUSTER_BEHIND_CLOSED ? 1u : 0u;
                    far += rule == CLUSTER_BEYOND_REACH ? 1u : 0u;
                    outside += rule == CLUSTER_OUTSIDE_HULL ? 1u : 0u;
                    if (rule != CLUSTER_KEEP) {
                        continue;
                    }
                }
                kept_tiles |= few ? 1u << ((ty - t0.y) * span.x + (tx - t0.x)) : 0u;
                if (SCATTER == 0u) {
                    atomicAdd(tile_counts[tile], 1u);
                } else {
                    uint slot = texelFetch(tile_offsets_tb, int(tile)).x + atomicAdd(tile_counts[tile], 1u);
                    // A caller's recording binds a list of fixed capacity: past
                    // it, record_args.comp reports the overflow and runs no unit.
                    if (slot < uint(tile_pairs.length())) {
                        tile_pairs[slot] = i;
                    }
                }
            }
        }
    }
    if (SCATTER == 0u && few) {
        pair_tiles[i] = kept_tiles;
    }
    if (SCATTER == 0u && light_side != 0u) {
        atomicAdd(counters[COUNTER_CLUSTER_LIGHT_SIDE], light_side);
    }
    if (SCATTER == 0u && behind_closed != 0u) {
        atomicAdd(counters[COUNTER_CLUSTER_BEHIND_CLOSED], behind_closed);
    }
    if (SCATTER == 0u && far != 0u) {
        atomicAdd(counters[COUNTER_BIN_BEYOND_REACH], far);
    }
    if (SCATTER == 0u && outside != 0u) {
        atomicAdd(counters[COUNTER_BIN_OUTSIDE_HULL], outside);
    }
}
