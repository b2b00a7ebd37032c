#version 450
// Writes every listed sample into the compact list array at its
// texel's offset plus its index, camera-relative position and triangle
// id (what the occlusion test reads); remembers each
// sample's slot. Twin: cpu::texel_lists::build_texel_lists.
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer Samples { GpuViewSample samples[]; };
layout(set = 0, binding = 1) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 2) readonly buffer SampleTexel { uint sample_texel[]; };
layout(set = 0, binding = 3) buffer SampleLocal { uint sample_slot[]; }; // local index in, slot out
layout(set = 0, binding = 4) writeonly buffer ListSamples { vec4 list_samples[]; };
// Per slot: the view sample's index (its pixel: per-pixel rotation).
layout(set = 0, binding = 5) writeonly buffer ListSampleIndex { uint list_sample_index[]; };

void main() {
    uint i = linear_invocation();
    if (i >= pc.sizes.x) {
        return;
    }
    uint texel = sample_texel[i];
    if (texel == NOT_LISTED) {
        return;
    }
    uint slot = offsets[texel] + sample_slot[i];
    GpuViewSample s = samples[i];
    list_samples[slot] = vec4(sample_position(s), uintBitsToFloat(sample_triangle(s)));
    list_sample_index[slot] = i;
    sample_slot[i] = slot;
}
