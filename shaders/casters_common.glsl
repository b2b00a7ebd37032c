// Shared by casters_setup (every triangle, the common case) and casters_clip
// (the few (triangle, face) pairs that cross the face's window pyramid):
// the bindings and the per-face conservative rectangle and edges of a
// caster's projection. Twin: cpu::casters::caster_face.
//
// The split exists for lavapipe: a shader that declares a dynamically
// indexed private array (the clip polygon) pays for it on every invocation,
// used or not (measured: 100k triangles took 105 ms with an immediate
// return, 7 ms without the array). Only casters_clip declares one.
#ifndef AFS_CASTER_COMMON_GLSL
#define AFS_CASTER_COMMON_GLSL
#include "shadow_common.glsl"

layout(set = 0, binding = 0) uniform usamplerBuffer triangles_tb; // GpuTriangle: 3 texels
layout(set = 0, binding = 1) uniform Faces { LightFace faces[6]; }; // read alike: a uniform buffer
layout(set = 0, binding = 2) writeonly buffer Planes { CasterPlanes planes[]; };
layout(set = 0, binding = 3) writeonly buffer Pairs { CasterFace pairs[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };
// (triangle, face mask | CLIP_ITEM_RASTERIZED): the pairs left to casters_clip.
layout(set = 0, binding = 5) buffer ClipItems { uvec2 clip_items[]; };
// The soft pairs that are large (large_pair), by their slot in `pairs`.
layout(set = 0, binding = 6) writeonly buffer LargePairs { uint large_pairs[]; };

// Clip item flag: the triangle already has a pair from casters_setup.
#define CLIP_ITEM_RASTERIZED 0x100u

// Camera-relative vertex k of triangle i.
vec3 triangle_vertex(uint i, uint k) {
    return uintBitsToFloat(texelFetch(triangles_tb, int(3u * i + k)).xyz);
}

// Face coordinates (right, up, forward) of light-relative q.
vec3 to_face(LightFace lf, vec3 q) {
    return vec3(dot(q, lf.right.xyz), dot(q, lf.up.xyz), dot(q, lf.forward.xyz));
}

// The window's far x and y (face units).
vec2 window_end(LightFace lf) {
    return lf.window.xy + vec2(float(pc.sizes.z)) / lf.window.zw;
}

// The magnitude of a face's projected coordinates, whose f32 rounding
// (ulps of it, times texels per unit) the texel margins absorb: the
// window's corners, plus 1 for a perspective face (x = X/Z carries the
// error of X and of Z) or the depth for an orthographic one (X = q·right
// carries the error of all of q). Without it a window zoomed onto a tight
// cluster of samples (a texel a few ulps wide) misses casters.
float face_scale(LightFace lf, bool point) {
    vec2 e = window_end(lf);
    return max(max(abs(lf.window.x), abs(e.x)), max(abs(lf.window.y), abs(e.y)))
        + (point ? 1.0 : abs(lf.far.x));
}

// The texel margin for projected coordinates of magnitude `scale`.
vec2 texel_margin(vec4 window, float scale) {
    return vec2(TEXEL_MARGIN) + (ROUNDING_ULPS * 1.1920929e-7 * scale) * window.zw;
}

// How far clipping widens a window side `plane` (a, b, c: a*X + b*Y + c*w)
// for a triangle whose face coordinates are at most t_max: the rounding of
// evaluating the plane and of the vertices earlier clips made. A window
// fitted to one sample is a pyramid thinner than that rounding; clipped
// exactly, a triangle covering the sample could come out empty.
// Twin: cpu::casters::clip_slack.
float clip_slack(vec3 plane, bool ortho, float t_max) {
    float terms = ortho ? t_max * (abs(plane.x) + abs(plane.y)) + abs(plane.z)
                        : t_max * (abs(plane.x) + abs(plane.y) + abs(plane.z));
    return ROUNDING_ULPS * 1.1920929e-7 * terms;
}

// The largest face coordinate of a triangle's vertices.
float face_extent(vec3 t0, vec3 t1, vec3 t2) {
    vec3 m = max(abs(t0), max(abs(t1), abs(t2)));
    return max(m.x, max(m.y, m.z));
}

// Texel-space coordinates of a projected face point (cpu::light_view::texel_of, unfloored).
vec2 to_texel(vec4 window, vec2 pr) {
    return vec2((pr.x - window.x) * window.z, (pr.y - window.y) * window.w);
}

// Folds one polygon vertex (face coordinates) into the depth minimum and
// the texel-space bounds (cpu::casters::caster_face).
void accumulate(vec3 p, bool point, float z_eps, vec4 window, inout float z_min, inout vec2 lo,
                inout vec2 hi, inout bool touches_light) {
    z_min = min(z_min, p.z);
    if (point && !(p.z > z_eps)) {
        touches_light = true;
        return;
    }
    vec2 tt = to_texel(window, point ? p.xy / p.z : p.xy);
    lo = min(lo, tt);
    hi = max(hi, tt);
}

// Appends one (caster, face) pair: texel rectangle and optional edges (w =
// 1); its slot in `pairs` (written only below the capacity, pc.more.x).
uint append_pair(uint i, uint f, uvec4 rect, vec4 e0, vec4 e1, vec4 e2) {
    uint slot = atomicAdd(counters[COUNTER_PAIRS], 1u);
    if (slot < pc.more.x) {
        CasterFace cf;
        cf.ids = uvec4(i, f, rect.x | (rect.y << 16), rect.z | (rect.w << 16));
        cf.e0 = e0;
        cf.e1 = e1;
        cf.e2 = e2;
        pairs[slot] = cf;
    }
    return slot;
}

// Appends the (caster i, face f) pair from its clipped polygon's bounds
// (z_min, lo, hi, touches_light) and its unclipped projection t0..t2;
// false when the polygon lies beyond the farthest view sample. `scale`:
// the magnitude of the polygon's projected coordinates beyond the face's
// (casters_clip: what clipping far vertices adds).
bool emit_pair(uint i, uint f, LightFace lf, vec3 t0, vec3 t1, vec3 t2, float z_min, vec2 lo,
               vec2 hi, bool touches_light, float scale) {
    bool point = is_point_light();
    float z_far = lf.far.x;
    float z_eps = z_far * 1e-6;
    if (z_min > z_far * (1.0 + 1e-5) + 1e-30) {
        return false;
    }
    uint res = pc.sizes.z;
    float max_t = float(res) - 1.0;
    uvec4 rect;
    vec2 m = texel_margin(lf.window, face_scale(lf, point) + scale);
    if (touches_light || any(isinf(lo)) || any(isinf(hi)) || any(isnan(lo)) || any(isnan(hi))
        || any(isinf(m)) || any(isnan(m))) {
        rect = uvec4(0u, 0u, res - 1u, res - 1u);
    } else {
        rect = uvec4(clamp(floor(lo.x - m.x), 0.0, max_t), clamp(floor(lo.y - m.y), 0.0, max_t),
                     clamp(floor(hi.x + m.x), 0.0, max_t), clamp(floor(hi.y + m.y), 0.0, max_t));
    }
    // Edge functions of the unclipped projection when all of it is in front of the light.
    vec4 pe[3] = vec4[3](vec4(0.0), vec4(0.0), vec4(0.0));
    bool front = !point || (t0.z > z_eps && t1.z > z_eps && t2.z > z_eps);
    if (front) {
        vec3 tri[3] = vec3[3](t0, t1, t2);
        vec2 tt[3];
        float reach = 0.0; // the vertices' projected magnitude
        for (int k = 0; k < 3; k++) {
            vec2 pr = point ? tri[k].xy / tri[k].z : tri[k].xy;
            reach = max(reach, max(abs(pr.x), abs(pr.y)));
            tt[k] = to_texel(lf.window, pr);
        }
        vec2 ab = tt[1] - tt[0], ac = tt[2] - tt[0];
        float area = ab.x * ac.y - ab.y * ac.x;
        vec2 em = texel_margin(lf.window, face_scale(lf, point) + reach);
        if (!isinf(area) && !isnan(area) && abs(area) >= 1e-6 && !any(isinf(em)) && !any(isnan(em))) {
            float s = sign(area);
            for (int k = 0; k < 3; k++) {
                vec2 a = tt[k], b = tt[(k + 1) % 3];
                float ea = -(b.y - a.y) * s;
                float eb = (b.x - a.x) * s;
                pe[k] = vec4(ea, eb, -(ea * a.x + eb * a.y), 0.0);
            }
            // The edges' test margin rides in e0.w and e1.w (> 0: edges valid).
            pe[0].w = em.x;
            pe[1].w = em.y;
            pe[2].w = 1.0;
        }
    }
    append_pair(i, f, rect, pe[0], pe[1], pe[2]);
    return true;
}

#endif
