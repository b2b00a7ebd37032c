#version 450
// Pass 8: per tile, its occlusion work units: chunks of OCC_PAIR_CHUNK
// binned pairs times chunks of OCC_SAMPLE_CHUNK entries of its longest
// texel list (0 when either is empty). Scanned, they map occlusion
// workgroups to (tile, pair chunk, sample chunk).
#extension GL_GOOGLE_include_directive : require
#include "hard_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer TileCounts { uint tile_counts[]; };
layout(set = 0, binding = 1) readonly buffer TileMaxLen { uint tile_max_len[]; };
layout(set = 0, binding = 2) writeonly buffer TileUnits { uint tile_units[]; };

void main() {
    uint i = linear_invocation();
    if (i >= pc.more.z * pc.sizes.w) {
        return;
    }
    uint pair_chunks = (tile_counts[i] + OCC_PAIR_CHUNK - 1u) / OCC_PAIR_CHUNK;
    uint sample_chunks = (tile_max_len[i] + OCC_SAMPLE_CHUNK - 1u) / OCC_SAMPLE_CHUNK;
    tile_units[i] = pair_chunks * sample_chunks;
}
