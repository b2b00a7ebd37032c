#version 450
// Per view sample, visibility = 1 - its shadow flag, and whether
// the shadow passes evaluated it (0 for samples facing away from the light).
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer SampleTexel { uint sample_texel[]; };
layout(set = 0, binding = 1) readonly buffer SampleSlot { uint sample_slot[]; };
layout(set = 0, binding = 2) readonly buffer Shadowed { uint shadowed[]; };
layout(set = 0, binding = 3) writeonly buffer Result { uint result[]; }; // bit 0: lit, bit 1: evaluated

void main() {
    uint i = linear_invocation();
    if (i >= pc.sizes.x) {
        return;
    }
    uint r = 0u;
    if (sample_texel[i] != NOT_LISTED) {
        r = 2u | (shadowed[sample_slot[i]] == 0u ? 1u : 0u);
    }
    result[i] = r;
}
