#version 450
// Per tile, its occlusion work units: chunks of OCC_PAIR_CHUNK
// binned pairs times chunks of OCC_SAMPLE_CHUNK entries of its longest
// texel list (0 when either is empty). Scanned, they map occlusion
// workgroups to (tile, pair chunk, sample chunk).
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer TileCounts { uint tile_counts[]; };
#ifdef SAMPLE_LANES
// Soft occlusion: one lane per listed sample of the tile (its samples are
// contiguous: tile-major texel order), OCC_SAMPLE_CHUNK = 64 per unit.
layout(set = 0, binding = 1) readonly buffer Offsets { uint offsets[]; };
#else
layout(set = 0, binding = 1) readonly buffer TileMaxLen { uint tile_max_len[]; };
#endif
layout(set = 0, binding = 2) writeonly buffer TileUnits { uint tile_units[]; };

void main() {
    uint i = linear_invocation();
    if (i >= pc.more.z * pc.sizes.w) {
        return;
    }
    uint pair_chunks = (tile_counts[i] + OCC_PAIR_CHUNK - 1u) / OCC_PAIR_CHUNK;
#ifdef SAMPLE_LANES
    uint tile_samples = offsets[(i + 1u) * TILE * TILE] - offsets[i * TILE * TILE];
    uint sample_chunks = (tile_samples + 63u) / 64u;
#else
    uint sample_chunks = (tile_max_len[i] + OCC_SAMPLE_CHUNK - 1u) / OCC_SAMPLE_CHUNK;
#endif
    tile_units[i] = pair_chunks * sample_chunks;
}
