#version 450
// Per binned pair of a tile (slot k of the tile lists) whose samples span
// at least CLUSTER_GROUP_MIN groups (clusters_common.glsl,
// CLUSTER_GROUP_SAMPLES): which of those groups the pair may shadow, bit j
// for the tile's j-th group (the first is the one its first sample falls
// in), clear where soft occlusion's chunk rule (chunk_rule) drops the pair
// for the group's box, set for a group without a valid box. Other tiles
// get no bits (their chunks' own rules decide). A work unit's chunk of 64
// samples lies in one or two groups; it skips a pair whose bits for both
// are clear (soft_occlusion.comp, keep_pairs): the pair is then one that
// each of its samples culls. Twin: cpu::pair_groups::pair_groups.
#extension GL_GOOGLE_include_directive : require
#include "clusters_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

// A soft pair's record (CasterFace, four texels: soft_pair_triangle).
layout(set = 0, binding = 0) uniform usamplerBuffer pairs_tb;
layout(set = 0, binding = 1) readonly buffer TileOffsets { uint tile_offsets[]; };
layout(set = 0, binding = 2) uniform usamplerBuffer tile_pairs_tb;
// The texel lists' offsets (tile-major: a tile's samples are contiguous).
layout(set = 0, binding = 3) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 4) uniform usamplerBuffer boxes_tb;
layout(set = 0, binding = 5) writeonly buffer PairGroups { uint pair_groups[]; };

// Slots per workgroup: several per lane (on lavapipe a workgroup costs
// about a microsecond before it does anything), which skip the slots of
// tiles without bits (ToyCar in the Embree bench's view: 4.7 ms for the
// pass when every slot was visited, most of them in such tiles).
#define SLOTS_PER_LANE 16u

void main() {
    uint first = spread_workgroup() * WORKGROUP_1D * SLOTS_PER_LANE;
    uint tiles = pc.more.z * pc.sizes.w;
    uint total = tile_offsets[tiles];
    if (first >= total) {
        return;
    }
    // The tile of the workgroup's first slot (the last one whose list
    // starts at or before it), searched once for the workgroup (the same
    // loads for every lane); each lane then walks on from it.
    uint lo = 0u, hi = tiles;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) / 2u;
        if (tile_offsets[mid] <= first) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    uint end = min(total, first + WORKGROUP_1D * SLOTS_PER_LANE);
    for (uint k = first + gl_LocalInvocationID.x; k < end;) {
        while (tile_offsets[lo + 1u] <= k) {
            lo++;
        }
        uint begin = offsets[lo * TILE * TILE];
        uint groups = cluster_groups_spanned(begin, offsets[(lo + 1u) * TILE * TILE]);
        if (groups < CLUSTER_GROUP_MIN) {
            // No bits for a tile of few groups: on to this lane's first
            // slot past it.
            k += (tile_offsets[lo + 1u] - k + WORKGROUP_1D - 1u) / WORKGROUP_1D * WORKGROUP_1D;
            continue;
        }
        uint pi = texelFetch(tile_pairs_tb, int(k)).x;
        uvec4 t0, t1, t2;
        soft_pair_triangle(texelFetch(pairs_tb, int(4u * pi + 1u)), texelFetch(pairs_tb, int(4u * pi + 2u)),
                           texelFetch(pairs_tb, int(4u * pi + 3u)), t0, t1, t2);
        ClusterPlane plane = triangle_cluster_plane(t0, t1, t2);
        uint g0 = begin / CLUSTER_GROUP_SAMPLES;
        uint bits = 0u;
        for (uint j = 0u; j < min(groups, CLUSTER_GROUP_BITS); j++) {
            uint at = cluster_group_box(g0 + j);
            vec4 box_lo = uintBitsToFloat(texelFetch(boxes_tb, int(at)));
            vec3 box_hi = uintBitsToFloat(texelFetch(boxes_tb, int(at + 1u)).xyz);
            bool keep = box_lo.w == 0.0 || chunk_rule(plane, box_lo.xyz, box_hi) == CLUSTER_KEEP;
            bits |= keep ? 1u << j : 0u;
        }
        pair_groups[k] = bits;
        k += WORKGROUP_1D;
    }
}
