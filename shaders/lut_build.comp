#version 450
// Soft pass: the plane look-up texture of one 128-sample block (paper §4.2):
// one invocation per texel, one bit per light sample behind the texel's
// plane. Twin: cpu::soft::build_lut.
#extension GL_GOOGLE_include_directive : require
#define LIGHT_SAMPLES_BINDING 1
#include "soft_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) writeonly buffer Lut { uvec4 lut[]; };

void main() {
    uint t = linear_invocation();
    uint res = pc.soft.z;
    if (t >= res * res * res) {
        return;
    }
    vec3 n;
    float d;
    lut_texel_plane(uvec3(t % res, (t / res) % res, t / (res * res)), res, n, d);
    uint base = pc.soft.x * 128u;
    uint count = min(pc.soft.y - min(base, pc.soft.y), 128u);
    float inv_r = 1.0 / pc.soft_light.x;
    uvec4 bits = uvec4(0u);
    for (uint j = 0u; j < count; j++) {
        vec3 y = (light_samples[base + j].xyz - pc.origin.xyz) * inv_r;
        if (dot(n, y) < d) {
            // No dynamic vector index: lavapipe charges those like arrays.
            uint w = j >> 5u, bit = 1u << (j & 31u);
            bits |= uvec4(w == 0u ? bit : 0u, w == 1u ? bit : 0u, w == 2u ? bit : 0u, w == 3u ? bit : 0u);
        }
    }
    lut[t] = bits;
}
