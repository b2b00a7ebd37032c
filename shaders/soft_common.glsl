// Soft shadows (paper §4): the plane look-up texture and the light samples.
// A plane is (n, d) in the light's normalized frame y = (l - origin) / R
// (every light sample has |y| <= 1); a LUT texel holds, for the plane at its
// centre, the bits of the light samples with dot(n, y) < d ("behind"), one
// uvec4 per 128-sample block, the blocks of a texel side by side (one
// index serves every block). Texel (i, j, k): n in octahedral coordinates
// (i, j over [-1, 1]^2: no trigonometry, cells within a factor ~2 of equal
// area) and d over [-1, 1].
// Twin: cpu::plane_lut (lut_texel_plane, lut_index, build_lut).
#ifndef AFS_SOFT_COMMON_GLSL
#define AFS_SOFT_COMMON_GLSL
#include "shadow_common.glsl"

#define MAX_LIGHT_SAMPLES 1024
#define MAX_LIGHT_BLOCKS 8

// Light samples (xyz), read alike by every invocation: camera-relative, or
// normalized (plane_lut_build); each shader defines LIGHT_SAMPLES_BINDING before
// including this file.
layout(set = 0, binding = LIGHT_SAMPLES_BINDING, std140) uniform LightSamples { vec4 light_samples[MAX_LIGHT_SAMPLES]; };

uint light_blocks() { return (pc.soft.y + 127u) / 128u; }

float sign_not_zero(float v) { return v >= 0.0 ? 1.0 : -1.0; }

// Unit vector n -> octahedral coordinates in [-1, 1]^2.
vec2 oct_encode(vec3 n) {
    vec3 p = n / (abs(n.x) + abs(n.y) + abs(n.z));
    if (p.z < 0.0) {
        return (1.0 - abs(p.yx)) * vec2(sign_not_zero(p.x), sign_not_zero(p.y));
    }
    return p.xy;
}

vec3 oct_decode(vec2 e) {
    vec3 n = vec3(e, 1.0 - abs(e.x) - abs(e.y));
    if (n.z < 0.0) {
        n.xy = (1.0 - abs(n.yx)) * vec2(sign_not_zero(n.x), sign_not_zero(n.y));
    }
    return normalize(n);
}

// The plane at the centre of LUT texel (i, j, k) of a res^3 table.
void lut_texel_plane(uvec3 ijk, uint res, out vec3 n, out float d) {
    vec3 c = -1.0 + (vec3(ijk) + 0.5) * (2.0 / float(res));
    n = oct_decode(c.xy);
    d = c.z;
}

// The LUT texel (linear index, without the block) nearest to plane (n, d),
// n unit; d is clamped to [-1, 1].
uint lut_index(vec3 n, float d, uint res) {
    float r = float(res);
    vec3 c = clamp(floor((vec3(oct_encode(n), d) + 1.0) * (0.5 * r)), vec3(0.0), vec3(r - 1.0));
    return (uint(c.z) * res + uint(c.y)) * res + uint(c.x);
}

#endif
