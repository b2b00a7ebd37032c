#version 450
// Pass 6: per triangle, whether it casts and its four planes (paper §3.3);
// per light face, its projection clipped to the face's window pyramid, as a
// conservative texel rectangle plus texel-space edge functions, appended to
// the (caster, face) pairs. Twin: cpu::casters::setup_casters.
#extension GL_GOOGLE_include_directive : require
#include "hard_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) uniform usamplerBuffer triangles_tb; // GpuTriangle: 3 texels
layout(set = 0, binding = 1) uniform Faces { LightFace faces[6]; }; // read alike: a uniform buffer
layout(set = 0, binding = 2) writeonly buffer Planes { CasterPlanes planes[]; };
layout(set = 0, binding = 3) writeonly buffer Pairs { CasterFace pairs[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };

#define MAX_POLY 9
vec3 poly[MAX_POLY];
vec3 tmp[MAX_POLY];
int poly_n;

// Sutherland-Hodgman: keep a*X + b*Y + c*Z + d >= 0 (Z = 1 for orthographic
// clipping is folded into d by the caller).
void clip(vec4 plane, bool ortho) {
    int n = 0;
    for (int i = 0; i < poly_n; i++) {
        vec3 p = poly[i];
        vec3 q = poly[(i + 1) % poly_n];
        float dp = ortho ? plane.x * p.x + plane.y * p.y + plane.z : dot(plane.xyz, p);
        float dq = ortho ? plane.x * q.x + plane.y * q.y + plane.z : dot(plane.xyz, q);
        if (dp >= 0.0 && n < MAX_POLY) {
            tmp[n++] = p;
        }
        if ((dp >= 0.0) != (dq >= 0.0) && n < MAX_POLY) {
            tmp[n++] = p + (q - p) * (dp / (dp - dq));
        }
    }
    for (int i = 0; i < n; i++) {
        poly[i] = tmp[i];
    }
    poly_n = n;
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
    vec2 pr = point ? p.xy / p.z : p.xy;
    vec2 tt = vec2((pr.x - window.x) * window.z, (pr.y - window.y) * window.w);
    lo = min(lo, tt);
    hi = max(hi, tt);
}

void main() {
    uint i = linear_invocation();
    if (i >= pc.sizes.y) {
        return;
    }
    GpuTriangle t;
    t.v0_flags = uintBitsToFloat(texelFetch(triangles_tb, int(3u * i)));
    t.v1_mesh = uintBitsToFloat(texelFetch(triangles_tb, int(3u * i + 1u)));
    t.v2_pad = uintBitsToFloat(texelFetch(triangles_tb, int(3u * i + 2u)));
    bool closed = (triangle_flags(t) & TRIANGLE_CLOSED) != 0u;
    vec3 o = pc.origin.xyz;
    // Camera-relative vertices; every normal is a cross product with one
    // short edge vector so small triangles far from the light keep
    // f32-accurate planes (cpu::casters::caster_planes).
    vec3 v[3] = vec3[3](t.v0_flags.xyz, t.v1_mesh.xyz, t.v2_pad.xyz);
    vec3 n = cross(v[1] - v[0], v[2] - v[0]);
    CasterPlanes cp;
    cp.support = vec4(0.0);
    cp.edge0 = vec4(0.0);
    cp.edge1 = vec4(0.0);
    cp.edge2 = vec4(0.0);
    cp.side = vec4(0.0);
    bool point = is_point_light();
    float s_light = point ? dot(n, o - v[0]) : dot(n, -pc.direction.xyz);
    if (any(isnan(n)) || any(isinf(n)) || n == vec3(0.0) || s_light == 0.0 || isnan(s_light) || isinf(s_light)) {
        planes[i] = cp;
        atomicAdd(counters[COUNTER_DEGENERATE], 1u);
        return;
    }
    if (closed && s_light > 0.0) {
        planes[i] = cp;
        atomicAdd(counters[COUNTER_FRONT_FACING_CLOSED], 1u);
        return;
    }
    vec3 ns = n * sign(s_light);
    cp.support = vec4(ns, -dot(ns, v[0]));
    vec4 e[3];
    float side[3];
    for (int k = 0; k < 3; k++) {
        vec3 a = v[k], b = v[(k + 1) % 3], c = v[(k + 2) % 3];
        // Canonical endpoint order (lexicographic), shared by both triangles of an edge.
        bool swap_ab = a.x > b.x || (a.x == b.x && (a.y > b.y || (a.y == b.y && a.z > b.z)));
        vec3 lo = swap_ab ? b : a, hi = swap_ab ? a : b;
        vec3 m;
        float w, inside;
        if (point) {
            m = cross(lo - o, hi - lo);
            w = 0.0;
            inside = dot(m, c - o);
        } else {
            m = cross(hi - lo, pc.direction.xyz);
            w = -dot(m, lo);
            inside = dot(m, c) + w;
        }
        e[k] = vec4(m, w);
        side[k] = inside < 0.0 ? -1.0 : 1.0;
    }
    cp.side = vec4(side[0], side[1], side[2], 0.0);
    cp.edge0 = e[0];
    cp.edge1 = e[1];
    cp.edge2 = e[2];
    vec3 q[3] = vec3[3](v[0] - o, v[1] - o, v[2] - o);

    uint res = pc.sizes.z;
    float max_t = float(res) - 1.0;
    bool any_face = false;
    for (uint f = 0u; f < pc.sizes.w; f++) {
        LightFace lf = faces[f];
        if (lf.right.w == 0.0) {
            continue;
        }
        vec3 r = lf.right.xyz, u = lf.up.xyz, w = lf.forward.xyz;
        vec3 tri[3];
        for (int k = 0; k < 3; k++) {
            vec3 d = q[k];
            tri[k] = vec3(dot(d, r), dot(d, u), dot(d, w));
        }
        float x0 = lf.window.x, y0 = lf.window.y;
        float x1 = x0 + float(res) / lf.window.z;
        float y1 = y0 + float(res) / lf.window.w;
        // The window pyramid's planes, evaluated exactly as clip() does.
        vec4 wplanes[5] = vec4[5](vec4(1, 0, -x0, 0), vec4(-1, 0, x1, 0), vec4(0, 1, -y0, 0),
                                  vec4(0, -1, y1, 0), vec4(0, 0, 1, 0));
        int nplanes = point ? 5 : 4;
        // Quick accept / reject: a triangle wholly inside needs no clipping
        // (clip() would return it unchanged), one wholly outside a plane is
        // empty there. Most triangles take one of these paths; private
        // arrays with dynamic indices are slow on lavapipe.
        bool all_in = true;
        bool rejected = false;
        for (int j = 0; j < 5; j++) {
            if (j >= nplanes) {
                break;
            }
            vec4 pl = wplanes[j];
            float d0 = point ? dot(pl.xyz, tri[0]) : pl.x * tri[0].x + pl.y * tri[0].y + pl.z;
            float d1 = point ? dot(pl.xyz, tri[1]) : pl.x * tri[1].x + pl.y * tri[1].y + pl.z;
            float d2 = point ? dot(pl.xyz, tri[2]) : pl.x * tri[2].x + pl.y * tri[2].y + pl.z;
            rejected = rejected || (d0 < 0.0 && d1 < 0.0 && d2 < 0.0);
            all_in = all_in && d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0;
        }
        if (rejected) {
            continue;
        }
        float z_far = lf.far.x;
        float z_eps = z_far * 1e-6;
        float z_min = 1.0 / 0.0;
        vec2 lo = vec2(1.0 / 0.0), hi = vec2(-1.0 / 0.0);
        bool touches_light = false;
        if (all_in) {
            for (int k = 0; k < 3; k++) {
                accumulate(tri[k], point, z_eps, lf.window, z_min, lo, hi, touches_light);
            }
        } else {
            for (int k = 0; k < 3; k++) {
                poly[k] = tri[k];
            }
            poly_n = 3;
            if (point) {
                clip(vec4(0, 0, 1, 0), false);
                if (poly_n > 0) clip(vec4(1, 0, -x0, 0), false);
                if (poly_n > 0) clip(vec4(-1, 0, x1, 0), false);
                if (poly_n > 0) clip(vec4(0, 1, -y0, 0), false);
                if (poly_n > 0) clip(vec4(0, -1, y1, 0), false);
            } else {
                clip(vec4(1, 0, -x0, 0), true);
                if (poly_n > 0) clip(vec4(-1, 0, x1, 0), true);
                if (poly_n > 0) clip(vec4(0, 1, -y0, 0), true);
                if (poly_n > 0) clip(vec4(0, -1, y1, 0), true);
            }
            if (poly_n == 0) {
                continue;
            }
            for (int k = 0; k < poly_n; k++) {
                accumulate(poly[k], point, z_eps, lf.window, z_min, lo, hi, touches_light);
            }
        }
        if (z_min > z_far * (1.0 + 1e-5) + 1e-30) {
            continue;
        }
        uvec4 rect;
        if (touches_light || any(isinf(lo)) || any(isinf(hi)) || any(isnan(lo)) || any(isnan(hi))) {
            rect = uvec4(0u, 0u, res - 1u, res - 1u);
        } else {
            rect = uvec4(clamp(floor(lo.x - TEXEL_MARGIN), 0.0, max_t), clamp(floor(lo.y - TEXEL_MARGIN), 0.0, max_t),
                         clamp(floor(hi.x + TEXEL_MARGIN), 0.0, max_t), clamp(floor(hi.y + TEXEL_MARGIN), 0.0, max_t));
        }
        // Edge functions of the unclipped projection when all of it is in front of the light.
        vec4 pe[3] = vec4[3](vec4(0.0), vec4(0.0), vec4(0.0));
        bool front = !point || (tri[0].z > z_eps && tri[1].z > z_eps && tri[2].z > z_eps);
        if (front) {
            vec2 tt[3];
            for (int k = 0; k < 3; k++) {
                vec2 pr = point ? tri[k].xy / tri[k].z : tri[k].xy;
                tt[k] = vec2((pr.x - x0) * lf.window.z, (pr.y - y0) * lf.window.w);
            }
            vec2 ab = tt[1] - tt[0], ac = tt[2] - tt[0];
            float area = ab.x * ac.y - ab.y * ac.x;
            if (!isinf(area) && !isnan(area) && abs(area) >= 1e-6) {
                float s = sign(area);
                for (int k = 0; k < 3; k++) {
                    vec2 a = tt[k], b = tt[(k + 1) % 3];
                    float ea = -(b.y - a.y) * s;
                    float eb = (b.x - a.x) * s;
                    pe[k] = vec4(ea, eb, -(ea * a.x + eb * a.y), 1.0);
                }
            }
        }
        uint slot = atomicAdd(counters[COUNTER_PAIRS], 1u);
        if (slot < pc.more.x) {
            CasterFace cf;
            cf.ids = uvec4(i, f, rect.x | (rect.y << 16), rect.z | (rect.w << 16));
            cf.e0 = pe[0];
            cf.e1 = pe[1];
            cf.e2 = pe[2];
            pairs[slot] = cf;
        }
        any_face = true;
    }
    planes[i] = cp;
    atomicAdd(counters[any_face ? COUNTER_RASTERIZED : COUNTER_CULLED], 1u);
}
