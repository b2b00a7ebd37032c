#version 450
// A caller's recording (Engine::record_frame) cannot read the binned pairs
// back: one invocation turns the scans' totals into the occlusion passes'
// indirect workgroup counts, none when the pairs overflowed the list's
// fixed capacity, and reports both in the light's status words.
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
layout(local_size_x = 1) in;

layout(set = 0, binding = 0) readonly buffer TileOffsets { uint tile_offsets[]; };
layout(set = 0, binding = 1) readonly buffer UnitOffsets { uint unit_offsets[]; };
// Capacity of the binned-pair list in entries.
layout(set = 0, binding = 2) writeonly buffer TilePairs { uint tile_pairs[]; };
layout(set = 0, binding = 3) writeonly buffer Args { uint args[]; };
// Zeroed by the host per frame; over a light's rounds (opaque, then
// alpha-tested casters): x the most binned pairs, y the most work units,
// z 1 when any round's pairs overflowed. w is set after the light's last
// pass (RecordedFrame::record_light).
layout(set = 0, binding = 4) buffer Status { uvec4 status; };

void main() {
    uint tiles = pc.more.z * pc.sizes.w;
    uint pairs = tile_offsets[tiles];
    uint units = unit_offsets[tiles];
    bool overflow = pairs > uint(tile_pairs.length());
    uint g = overflow ? 0u : units;
    args[0] = min(g, 65535u);
    args[1] = g == 0u ? 1u : (g + 65534u) / 65535u;
    args[2] = 1u;
    if (g == 0u) {
        args[0] = 0u;
    }
    uvec4 before = status;
    status.xyz = uvec3(max(before.x, pairs), max(before.y, units),
                       before.z | (overflow ? 1u : 0u));
}
