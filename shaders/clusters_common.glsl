// View-sample clusters (Sintorn et al. 2014, the plane cut of Lehtinen et
// al. 2006): per tile of light texels, the box of its listed samples, and
// the test that a caster cannot block any sample of a box. Both rules are
// the occlusion tests' own early outs, taken for a whole tile with a margin
// far above their rounding, so that a culled pair is one the per-sample
// test would have skipped for every sample: the masks stay bit-identical.
// Twin: cpu::clusters.
#ifndef AFS_CLUSTERS_COMMON_GLSL
#define AFS_CLUSTERS_COMMON_GLSL
#include "shadow_common.glsl"

// Box margins, relative to the magnitudes involved: f32 rounding of the
// per-sample plane tests is ~1e-6 of them.
#define CLUSTER_MARGIN 1e-4
// Tiles with more listed samples than this get no box (no culling): the
// bounds pass loops over a tile's samples in one invocation.
#define CLUSTER_MAX_SAMPLES 16384u

// What the rules found (cull_rule).
#define CLUSTER_KEEP 0u
#define CLUSTER_LIGHT_SIDE 1u
#define CLUSTER_BEHIND_CLOSED 2u

// A caster's supporting plane as the rules see it.
struct ClusterPlane {
    vec3 n;      // unit normal of cross(b - a, c - a)
    vec3 a;      // its first vertex, camera-relative
    float side;  // the light's side of the plane: +1, -1, or 0 (the light straddles it: no light-side rule)
    bool closed;
};

// The supporting plane of triangle (a, b, c) and the light's side of it
// (the whole light's bounding sphere beyond the margin, or a directional
// light's travel direction clearly not in the plane).
ClusterPlane cluster_plane(vec3 a, vec3 b, vec3 c, bool closed) {
    ClusterPlane cp;
    vec3 n = cross(b - a, c - a);
    float len = length(n);
    cp.n = n / len;
    cp.a = a;
    cp.closed = closed;
    cp.side = 0.0;
    if (!(len > 0.0) || isinf(len) || any(isnan(cp.n))) {
        cp.n = vec3(0.0);
        cp.closed = false;
        return cp;
    }
    vec3 o = pc.origin.xyz;
    if (is_soft() || is_point_light()) {
        float r = is_soft() ? pc.soft_light.x : 0.0;
        float s = dot(cp.n, o - a);
        float need = r + CLUSTER_MARGIN * (r + length(a) + length(o) + length(a - o));
        cp.side = s >= need ? 1.0 : s <= -need ? -1.0 : 0.0;
    } else {
        float s = -dot(cp.n, pc.direction.xyz) / length(pc.direction.xyz);
        cp.side = s >= CLUSTER_MARGIN ? 1.0 : s <= -CLUSTER_MARGIN ? -1.0 : 0.0;
    }
    return cp;
}

// The ClusterPlane of triangle i of `triangles` (GpuTriangle: 3 texels,
// camera-relative vertices, TRIANGLE_CLOSED in the first texel's w).
ClusterPlane triangle_cluster_plane(usamplerBuffer triangles, uint i) {
    uvec4 t0 = texelFetch(triangles, int(3u * i));
    vec3 a = uintBitsToFloat(t0.xyz);
    vec3 b = uintBitsToFloat(texelFetch(triangles, int(3u * i + 1u)).xyz);
    vec3 c = uintBitsToFloat(texelFetch(triangles, int(3u * i + 2u)).xyz);
    return cluster_plane(a, b, c, (t0.w & TRIANGLE_CLOSED) != 0u);
}

// Which rule (if any) drops the caster for every sample of the box
// [lo, hi]: every sample on the light's side of its plane (its segments to
// the light never cross it), or, soft shadows, behind a closed caster
// (occlusion's back-face rule).
uint cull_rule(ClusterPlane cp, vec3 lo, vec3 hi) {
    if (cp.n == vec3(0.0)) {
        return CLUSTER_KEEP;
    }
    vec3 c = 0.5 * (lo + hi), h = 0.5 * (hi - lo);
    float dc = dot(cp.n, c - cp.a);
    float r = dot(abs(cp.n), h);
    float r_light = is_soft() ? pc.soft_light.x : 0.0;
    float scale = length(cp.a) + length(pc.origin.xyz) + r_light + length(max(abs(lo), abs(hi)));
    float m = CLUSTER_MARGIN * scale;
    if ((cp.side > 0.0 && dc - r >= m) || (cp.side < 0.0 && dc + r <= -m)) {
        return CLUSTER_LIGHT_SIDE;
    }
    if (is_soft() && cp.closed && dc + r <= -m) {
        return CLUSTER_BEHIND_CLOSED;
    }
    return CLUSTER_KEEP;
}

#endif
