#version 450
// Indirect: the (caster, face) pairs whose projection crosses the
// face's window pyramid: clipped to it (a triangle crossing the light's
// near plane is clipped, not dropped), then emitted like casters_setup's.
// Twin: cpu::casters::setup_casters.
#extension GL_GOOGLE_include_directive : require
#include "casters_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

#define MAX_POLY 9
vec3 poly[MAX_POLY];
vec3 tmp[MAX_POLY];
int poly_n;

// Sutherland-Hodgman: keep a*X + b*Y + c*w >= -slack (w = Z, or 1 for
// orthographic clipping).
void clip(vec4 plane, bool ortho, float slack) {
    int n = 0;
    for (int i = 0; i < poly_n; i++) {
        vec3 p = poly[i];
        vec3 q = poly[(i + 1) % poly_n];
        float dp = slack + (ortho ? plane.x * p.x + plane.y * p.y + plane.z : dot(plane.xyz, p));
        float dq = slack + (ortho ? plane.x * q.x + plane.y * q.y + plane.z : dot(plane.xyz, q));
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

void main() {
    uint k = linear_invocation();
    if (k >= min(counters[COUNTER_CLIP_ITEMS], pc.sizes.y)) {
        return;
    }
    uvec2 item = clip_items[k];
    uint i = item.x;
    vec3 o = pc.origin.xyz;
    vec3 q0 = triangle_vertex(i, 0u) - o, q1 = triangle_vertex(i, 1u) - o, q2 = triangle_vertex(i, 2u) - o;
    bool point = is_point_light();
    bool any_face = (item.y & CLIP_ITEM_RASTERIZED) != 0u;
    for (uint f = 0u; f < pc.sizes.w; f++) {
        if ((item.y & (1u << f)) == 0u) {
            continue;
        }
        LightFace lf = faces[f];
        vec3 t0 = to_face(lf, q0), t1 = to_face(lf, q1), t2 = to_face(lf, q2);
        float x0 = lf.window.x, y0 = lf.window.y;
        vec2 x1y1 = window_end(lf);
        poly[0] = t0;
        poly[1] = t1;
        poly[2] = t2;
        poly_n = 3;
        // The sides widened by clip_slack; a point light's near plane exact
        // (widened sides would reach behind the light).
        float t_max = face_extent(t0, t1, t2);
        vec4 sides[4] = vec4[4](vec4(1, 0, -x0, 0), vec4(-1, 0, x1y1.x, 0), vec4(0, 1, -y0, 0), vec4(0, -1, x1y1.y, 0));
        if (point) {
            clip(vec4(0, 0, 1, 0), false, 0.0);
        }
        for (int j = 0; j < 4 && poly_n > 0; j++) {
            clip(sides[j], !point, clip_slack(sides[j].xyz, !point, t_max));
        }
        if (poly_n == 0) {
            continue;
        }
        float z_eps = lf.far.x * 1e-6;
        float z_min = 1.0 / 0.0;
        vec2 lo = vec2(1.0 / 0.0), hi = vec2(-1.0 / 0.0);
        bool touches_light = false;
        for (int j = 0; j < poly_n; j++) {
            accumulate(poly[j], point, z_eps, lf.window, z_min, lo, hi, touches_light);
        }
        // A clipped vertex carries the rounding of the whole edge it cuts:
        // a few ulps of the vertices' magnitude, over its depth when projected.
        float clip_scale = point ? 2.0 * t_max * face_scale(lf, true) / max(z_min, 1e-30) : 2.0 * t_max;
        any_face = emit_pair(i, f, lf, t0, t1, t2, z_min, lo, hi, touches_light, clip_scale) || any_face;
    }
    atomicAdd(counters[any_face ? COUNTER_RASTERIZED : COUNTER_CULLED], 1u);
}
