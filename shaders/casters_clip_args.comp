#version 450
// The indirect workgroup counts of casters_clip (one invocation per clip
// item), or with PAIRS = 1 of tile binning (one per caster-face pair: its
// dispatches over the pairs written, not over their capacity, which is
// triangles x faces), or with PAIRS = 2 of its BY_BLOCKS pipeline (one
// per large pair listed).
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
layout(local_size_x = 1) in;

layout(set = 0, binding = 0) readonly buffer Counters { uint counters[]; };
layout(set = 0, binding = 1) writeonly buffer Args { uint args[]; };
layout(constant_id = 1) const uint PAIRS = 0u;

void main() {
    uint items = PAIRS == 2u ? min(counters[COUNTER_LARGE_PAIRS], pc.more.x)
        : PAIRS != 0u ? min(counters[COUNTER_PAIRS], pc.more.x) : min(counters[COUNTER_CLIP_ITEMS], pc.sizes.y);
    uint g = (items + WORKGROUP_1D - 1u) / WORKGROUP_1D;
    args[0] = min(g, 65535u);
    args[1] = g == 0u ? 1u : (g + 65534u) / 65535u;
    args[2] = 1u;
}
