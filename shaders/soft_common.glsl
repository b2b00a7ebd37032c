// Soft shadows (paper §4): the plane look-up texture and the light samples.
// A plane is (n, d) in the light's normalized frame y = (l - origin) / R
// (every light sample has |y| <= 1); a LUT texel holds, for the plane at its
// centre, the bits of the block's 128 light samples with dot(n, y) < d
// ("behind"). Texel (i, j, k): azimuth of n, its z (uniform in z: equal
// area), and d, each over [-pi, pi), [-1, 1], [-1, 1].
// Twin: cpu::soft (lut_texel_plane, lut_index, behind).
#ifndef AFS_SOFT_COMMON_GLSL
#define AFS_SOFT_COMMON_GLSL
#include "hard_common.glsl"

#define PI 3.14159265358979
#define MAX_LIGHT_SAMPLES 1024

// Light samples, camera-relative (xyz), read alike by every invocation; each
// shader defines LIGHT_SAMPLES_BINDING before including this file.
layout(set = 0, binding = LIGHT_SAMPLES_BINDING, std140) uniform LightSamples { vec4 light_samples[MAX_LIGHT_SAMPLES]; };

// The plane at the centre of LUT texel (i, j, k) of a res^3 table.
void lut_texel_plane(uvec3 ijk, uint res, out vec3 n, out float d) {
    float r = float(res);
    float phi = -PI + (float(ijk.x) + 0.5) * (2.0 * PI / r);
    float z = -1.0 + (float(ijk.y) + 0.5) * (2.0 / r);
    d = -1.0 + (float(ijk.z) + 0.5) * (2.0 / r);
    float s = sqrt(max(1.0 - z * z, 0.0));
    n = vec3(s * cos(phi), s * sin(phi), z);
}

// The LUT texel (linear index) nearest to plane (n, d), n unit, |d| < 1.
uint lut_index(vec3 n, float d, uint res) {
    float r = float(res);
    float m = r - 1.0;
    float i = clamp(floor((atan(n.y, n.x) + PI) * (r / (2.0 * PI))), 0.0, m);
    float j = clamp(floor((n.z + 1.0) * (0.5 * r)), 0.0, m);
    float k = clamp(floor((d + 1.0) * (0.5 * r)), 0.0, m);
    return (uint(k) * res + uint(j)) * res + uint(i);
}

#endif
