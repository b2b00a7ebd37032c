#version 450
// Per tile of light texels, the box of its listed view samples (one
// invocation per tile; its samples are contiguous, tile-major lists):
// lo.w = 1 when the box is valid, 0 when the tile has no samples, too many
// (CLUSTER_MAX_SAMPLES) or a non-finite one (no culling there).
// Twin: cpu::clusters::tile_boxes.
#extension GL_GOOGLE_include_directive : require
#include "clusters_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 1) uniform usamplerBuffer list_samples_tb;
layout(set = 0, binding = 2) writeonly buffer Boxes { vec4 boxes[]; }; // per tile: lo, hi

void main() {
    uint t = linear_invocation();
    if (t >= pc.more.z * pc.sizes.w) {
        return;
    }
    uint begin = offsets[t * TILE * TILE], end = offsets[(t + 1u) * TILE * TILE];
    vec3 lo = vec3(1.0 / 0.0), hi = vec3(-1.0 / 0.0);
    bool valid = end > begin && end - begin <= CLUSTER_MAX_SAMPLES;
    if (valid) {
        for (uint s = begin; s < end; s++) {
            vec3 x = uintBitsToFloat(texelFetch(list_samples_tb, int(s)).xyz);
            valid = valid && !any(isnan(x)) && !any(isinf(x));
            lo = min(lo, x);
            hi = max(hi, x);
        }
    }
    boxes[2u * t] = vec4(lo, valid ? 1.0 : 0.0);
    boxes[2u * t + 1u] = vec4(hi, 0.0);
}
