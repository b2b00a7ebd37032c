#version 450
// Soft pass: the plane look-up texture (paper §4.2), every 128-sample block
// at once: one invocation per texel, one bit per light sample behind the
// texel's plane. Built once per light shape and resolution (the host caches
// it across frames: it depends only on the normalized samples).
// Twin: cpu::plane_lut::build_lut.
#extension GL_GOOGLE_include_directive : require
#define LIGHT_SAMPLES_BINDING 1
#include "soft_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

// A storage texel buffer: the LUT may pass maxStorageBufferRange.
layout(set = 0, binding = 0, rgba32ui) writeonly uniform uimageBuffer lut;

// light_samples here are the normalized samples y = (l - origin) / R.
void main() {
    uint t = linear_invocation();
    uint res = pc.soft.z;
    if (t >= res * res * res) {
        return;
    }
    vec3 n;
    float d;
    lut_texel_plane(uvec3(t % res, (t / res) % res, t / (res * res)), res, n, d);
    uint count = pc.soft.y;
    uint blocks = light_blocks();
    uvec4 bits = uvec4(0u);
    for (uint j = 0u; j < count; j++) {
        if (dot(n, light_samples[j].xyz) < d) {
            // No dynamic vector index: lavapipe charges those like arrays.
            uint w = (j >> 5u) & 3u, bit = 1u << (j & 31u);
            bits |= uvec4(w == 0u ? bit : 0u, w == 1u ? bit : 0u, w == 2u ? bit : 0u, w == 3u ? bit : 0u);
        }
        if ((j & 127u) == 127u || j + 1u == count) {
            imageStore(lut, int(t * blocks + (j >> 7u)), bits);
            bits = uvec4(0u);
        }
    }
}
