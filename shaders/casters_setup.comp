#version 450
// Per triangle, whether it casts and its four planes (paper §3.3);
// per light face, its projection as a conservative texel rectangle plus
// texel-space edge functions, appended to the (caster, face) pairs. A
// projection wholly inside the face's window pyramid is emitted here; one
// crossing it is left to casters_clip (see casters_common.glsl for why).
// Twin: cpu::casters::setup_casters.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "casters_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;
// 1: the soft-shadow pipeline (soft_caster), 0: the hard one. Chosen per
// run by the host, agreeing with is_soft(): lavapipe runs the code of an
// `if` that no lane takes, so each pipeline compiles the other's out
// (ToyCar on a ground, point light: caster setup 13.3-13.6 -> 11.9 ms).
layout(constant_id = 8) const uint SOFT_SETUP = 0u;

// The image (texel coordinates) of face point p seen from the light's centre.
void fold_image(LightFace lf, vec3 p, inout vec2 lo, inout vec2 hi) {
    vec2 tt = to_texel(lf.window, p.xy / p.z);
    lo = min(lo, tt);
    hi = max(hi, tt);
}

// Whether the influence region of a triangle (face coordinates t, from
// the light's centre) misses face lf's window: every vertex beyond one of
// the window's side planes (through the centre, moved out by two texels)
// by more than the light's radius R. Every point of the region lies on a
// ray from a light point l (|l| <= R) through a triangle point b, beyond
// b: p = l + (b - l) s with s >= 1, so m·p <= (s - 1) R |m| + s m·b < 0
// where m·b < -R |m|: no view sample of this face (each inside the
// window, a face's samples in front of it) is there. The margins: 1e-4 of
// R and 1e-5 of the coordinates' magnitude `scale` (f32 rounding is ~1e-7
// of it). Without it such faces computed the whole region to find it
// outside (ToyCar on a ground, sphere light, 512²: caster setup 20.5 ->
// 16.6-18.1 ms, binning 21.6 -> 17.7 ms, 1.5% fewer pairs).
bool outside_window(LightFace lf, vec3 t[3], float R, float scale) {
    vec2 x1y1 = window_end(lf);
    vec2 slack = 2.0 / lf.window.zw;
    vec3 sides[4] = vec3[4](vec3(1.0, 0.0, -(lf.window.x - slack.x)), vec3(-1.0, 0.0, x1y1.x + slack.x),
                            vec3(0.0, 1.0, -(lf.window.y - slack.y)), vec3(0.0, -1.0, x1y1.y + slack.y));
    bool outside = false;
    for (int j = 0; j < 4; j++) {
        vec3 m = sides[j];
        float need = length(m) * (R * (1.0 + 1e-4) + 1e-5 * scale);
        outside = outside || (dot(m, t[0]) < -need && dot(m, t[1]) < -need && dot(m, t[2]) < -need);
    }
    // Not finite (a degenerate window): no conclusion.
    return outside && !any(isnan(slack)) && !any(isinf(slack));
}

// Soft shadows (paper §4.3): a triangle casts unless it is degenerate or,
// on a closed mesh, every point of the light lies in front of it. Its
// influence region on a face: the images, seen from the light's centre, of
// its vertices and of the rays from the corners of a polygon bounding the
// light's silhouette (seen from each vertex) through the vertex, to the
// farthest view sample's depth; plus its edges' crossings of that depth.
// A vertex as near as the light's extent makes the region the whole face.
// Each pair carries its triangle (CasterFace, soft pairs), so that binning
// and occlusion read a pair and its vertices from one 64-byte record.
// A face whose window the region misses by a side plane is left out
// before the region is computed (outside_window).
// No twin of its own: tests/soft_shadows.rs checks that the regions drop
// no blocking caster (the GPU masks against a brute force without regions).
void soft_caster(uint i, vec3 v[3], vec3 n, bool closed, uint flags) {
    uint alpha_record = texelFetch(triangles_tb, int(3u * i + 2u)).w;
    vec3 o = pc.origin.xyz;
    float R = pc.soft_light.x;
    uint degree = uint(pc.soft_light.y);
    CasterPlanes cp = no_planes();
    planes[i] = cp;
    float nl = length(n);
    if (any(isnan(n)) || any(isinf(n)) || nl == 0.0 || isinf(nl)) {
        atomicAdd(counters[COUNTER_DEGENERATE], 1u);
        return;
    }
    if (closed && dot(n, o - v[0]) > R * nl) {
        atomicAdd(counters[COUNTER_FRONT_FACING_CLOSED], 1u);
        return;
    }
    float half_angle = 3.14159265 / float(degree);
    // How far from the centre a corner of the bounding polygon can be.
    float reach = R / cos(half_angle) * (1.0 + 1e-4);
    vec2 step_cs = vec2(cos(2.0 * half_angle), sin(2.0 * half_angle));
    uint res = pc.sizes.z;
    float max_t = float(res) - 1.0;
    bool any_face = false;
    // The faces this caster may cast on, by the cheap tests, then the
    // region for those only, a face at a time over the subgroup's union:
    // lavapipe runs a loop's body for every lane as long as any lane has a
    // face left, so six turns cost six regions where most casters need
    // one or two.
    float scale = length(o) + max(length(v[0]), max(length(v[1]), length(v[2])));
    uint todo = 0u;
    for (uint f = 0u; f < pc.sizes.w; f++) {
        LightFace lf = faces[f];
        vec3 t[3] = vec3[3](to_face(lf, v[0] - o), to_face(lf, v[1] - o), to_face(lf, v[2] - o));
        float z_min = min(t[0].z, min(t[1].z, t[2].z));
        float z_max = max(t[0].z, max(t[1].z, t[2].z));
        // A blocker lies on a segment from a sample (depth <= z_far) to a
        // light sample (depth <= reach): beyond both, it hides nothing;
        // wholly behind the light, nothing either.
        bool misses = lf.right.w == 0.0 || z_min > max(lf.far.x, reach) * (1.0 + 1e-5) + 1e-30 || z_max < -reach
            || outside_window(lf, t, R, scale);
        todo |= misses ? 0u : 1u << f;
    }
    uint faces_left = subgroupOr(todo);
    while (faces_left != 0u) {
        uint f = uint(findLSB(faces_left));
        faces_left &= faces_left - 1u;
        if ((todo & (1u << f)) == 0u) {
            continue;
        }
        LightFace lf = faces[f];
        vec3 t[3] = vec3[3](to_face(lf, v[0] - o), to_face(lf, v[1] - o), to_face(lf, v[2] - o));
        float z_far = lf.far.x;
        float z_min = min(t[0].z, min(t[1].z, t[2].z));
        uvec4 rect = uvec4(0u, 0u, res - 1u, res - 1u);
        if (z_min > reach) {
            vec2 lo = vec2(1.0 / 0.0), hi = vec2(-1.0 / 0.0);
            for (int k = 0; k < 3; k++) {
                vec3 a = t[k], b = t[(k + 1) % 3];
                if ((a.z - z_far) * (b.z - z_far) < 0.0) {
                    fold_image(lf, a + (b - a) * ((z_far - a.z) / (b.z - a.z)), lo, hi);
                }
                if (a.z > z_far) {
                    continue;
                }
                fold_image(lf, a, lo, hi);
                // The silhouette circle of the light's bounding sphere seen from a.
                float dist2 = dot(a, a);
                vec3 centre = a * (R * R / dist2);
                float rho = R * sqrt(max(dist2 - R * R, 0.0) / dist2) / cos(half_angle) * (1.0 + 1e-4);
                vec3 ax = normalize(a);
                vec3 e1 = normalize(abs(ax.x) < 0.9 ? cross(ax, vec3(1, 0, 0)) : cross(ax, vec3(0, 1, 0)));
                vec3 e2 = cross(ax, e1);
                // The corners at angles 2 half_angle j, by rotating (cos,
                // sin) one step at a time (lavapipe's sin and cos cost more
                // than the setup's other work); their f32 drift over
                // `degree` steps is far inside rho's 1e-4 of margin.
                vec2 cs = vec2(1.0, 0.0);
                for (uint j = 0u; j < degree; j++) {
                    vec3 l = centre + rho * (cs.x * e1 + cs.y * e2);
                    fold_image(lf, l + (a - l) * ((z_far - l.z) / (a.z - l.z)), lo, hi);
                    cs = vec2(cs.x * step_cs.x - cs.y * step_cs.y, cs.x * step_cs.y + cs.y * step_cs.x);
                }
            }
            // One texel of margin: the region is conservative by construction,
            // the margin absorbs f32 rounding against the samples' texels.
            if (any(isnan(lo)) || any(isnan(hi))) {
                rect = uvec4(0u, 0u, res - 1u, res - 1u);
            } else if (hi.x < -1.0 || hi.y < -1.0 || lo.x > float(res) + 1.0 || lo.y > float(res) + 1.0) {
                continue;
            } else {
                // Plus the rounding of coordinates this far out (face_scale).
                float reach = max(max(abs(lo.x), abs(hi.x)) / lf.window.z, max(abs(lo.y), abs(hi.y)) / lf.window.w);
                vec2 m = vec2(1.0 - TEXEL_MARGIN) + texel_margin(lf.window, face_scale(lf, true) + reach);
                if (any(isinf(m)) || any(isnan(m))) {
                    rect = uvec4(0u, 0u, res - 1u, res - 1u);
                } else {
                    rect = uvec4(clamp(floor(lo.x - m.x), 0.0, max_t), clamp(floor(lo.y - m.y), 0.0, max_t),
                                 clamp(floor(hi.x + m.x), 0.0, max_t), clamp(floor(hi.y + m.y), 0.0, max_t));
                }
            }
        }
        uint slot = append_pair(i, f, rect, vec4(v[0], 0.0), vec4(v[1], uintBitsToFloat(flags)),
                                vec4(v[2], uintBitsToFloat(alpha_record)));
        // The large pairs listed apart, for binning's by-blocks pipeline
        // (here, not in append_pair: hard pipelines then carry none of it;
        // hard ToyCar's caster setup 12.2-13.4 -> 11.5 ms).
        if (slot < pc.more.x && large_pair(rect.xy, rect.zw)) {
            large_pairs[atomicAdd(counters[COUNTER_LARGE_PAIRS], 1u)] = slot;
        }
        any_face = true;
    }
    atomicAdd(counters[any_face ? COUNTER_RASTERIZED : COUNTER_CULLED], 1u);
}

void main() {
    uint i = linear_invocation();
    if (i >= pc.sizes.y) {
        return;
    }
    uint flags = texelFetch(triangles_tb, int(3u * i)).w;
    bool closed = (flags & TRIANGLE_CLOSED) != 0u;
    if (!caster_in_class(flags)) {
        // The other round's caster: no planes, no pairs.
        planes[i] = no_planes();
        return;
    }
    vec3 o = pc.origin.xyz;
    // Camera-relative vertices; every normal is a cross product with one
    // short edge vector so small triangles far from the light keep
    // f32-accurate planes (cpu::casters::caster_planes).
    vec3 v[3] = vec3[3](triangle_vertex(i, 0u), triangle_vertex(i, 1u), triangle_vertex(i, 2u));
    vec3 n = cross(v[1] - v[0], v[2] - v[0]);
    if (SOFT_SETUP != 0u) {
        soft_caster(i, v, n, closed, flags);
        return;
    }
    CasterPlanes cp = no_planes();
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
    // Every edge plane's inside is the triangle's side of it, which one
    // determinant gives for all three: (a - o)·n = -s_light for a point
    // light, (c - a)·((b - a) x d) = s_light for a directional one. Taken
    // per edge from its opposite vertex instead, a sliver's short side
    // rounds the wrong way and its region becomes an unbounded wedge.
    float inside_side = point ? -sign(s_light) : sign(s_light);
    for (int k = 0; k < 3; k++) {
        vec3 a = v[k], b = v[(k + 1) % 3], c = v[(k + 2) % 3];
        // Canonical endpoint order (lexicographic), shared by both triangles of an edge.
        bool swap_ab = a.x > b.x || (a.x == b.x && (a.y > b.y || (a.y == b.y && a.z > b.z)));
        vec3 lo = swap_ab ? b : a, hi = swap_ab ? a : b;
        vec3 m;
        float w;
        if (point) {
            m = cross(lo - o, hi - lo);
            w = 0.0;
        } else {
            m = cross(hi - lo, pc.direction.xyz);
            w = -dot(m, lo);
        }
        e[k] = vec4(m, w);
        side[k] = swap_ab ? -inside_side : inside_side;
    }
    cp.side = vec4(side[0], side[1], side[2], 0.0);
    cp.edge0 = e[0];
    cp.edge1 = e[1];
    cp.edge2 = e[2];
    planes[i] = cp;

    bool any_face = false;
    uint clip_mask = 0u;
    // As soft_caster: which faces need a pair, then the pairs over the
    // subgroup's union of those faces.
    uint todo = 0u;
    for (uint f = 0u; f < pc.sizes.w; f++) {
        LightFace lf = faces[f];
        vec3 t0 = to_face(lf, v[0] - o), t1 = to_face(lf, v[1] - o), t2 = to_face(lf, v[2] - o);
        vec2 x1y1 = window_end(lf);
        // The window pyramid's planes, evaluated exactly as casters_clip's clip() does.
        vec4 wplanes[5] = vec4[5](vec4(1, 0, -lf.window.x, 0), vec4(-1, 0, x1y1.x, 0), vec4(0, 1, -lf.window.y, 0),
                                  vec4(0, -1, x1y1.y, 0), vec4(0, 0, 1, 0));
        // Quick accept / reject: a triangle wholly inside needs no clipping
        // (clipping would return it unchanged), one wholly outside a plane
        // is empty there.
        // Rejection allows casters_clip's slack, so that what it would keep
        // is never rejected here.
        bool all_in = true;
        bool rejected = lf.right.w == 0.0;
        float t_max = face_extent(t0, t1, t2);
        for (int j = 0; j < 5; j++) {
            vec4 pl = wplanes[j];
            bool used = point || j < 4;
            float d0 = point ? dot(pl.xyz, t0) : pl.x * t0.x + pl.y * t0.y + pl.z;
            float d1 = point ? dot(pl.xyz, t1) : pl.x * t1.x + pl.y * t1.y + pl.z;
            float d2 = point ? dot(pl.xyz, t2) : pl.x * t2.x + pl.y * t2.y + pl.z;
            float slack = j < 4 ? clip_slack(pl.xyz, !point, t_max) : 0.0;
            rejected = rejected || (used && d0 < -slack && d1 < -slack && d2 < -slack);
            all_in = all_in && (!used || (d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0));
        }
        clip_mask |= !rejected && !all_in ? 1u << f : 0u;
        todo |= !rejected && all_in ? 1u << f : 0u;
    }
    uint faces_left = subgroupOr(todo);
    while (faces_left != 0u) {
        uint f = uint(findLSB(faces_left));
        faces_left &= faces_left - 1u;
        if ((todo & (1u << f)) == 0u) {
            continue;
        }
        LightFace lf = faces[f];
        vec3 t0 = to_face(lf, v[0] - o), t1 = to_face(lf, v[1] - o), t2 = to_face(lf, v[2] - o);
        float z_eps = lf.far.x * 1e-6;
        float z_min = 1.0 / 0.0;
        vec2 lo = vec2(1.0 / 0.0), hi = vec2(-1.0 / 0.0);
        bool touches_light = false;
        accumulate(t0, point, z_eps, lf.window, z_min, lo, hi, touches_light);
        accumulate(t1, point, z_eps, lf.window, z_min, lo, hi, touches_light);
        accumulate(t2, point, z_eps, lf.window, z_min, lo, hi, touches_light);
        any_face = emit_pair(i, f, lf, t0, t1, t2, z_min, lo, hi, touches_light, 0.0) || any_face;
    }
    if (clip_mask != 0u) {
        uint slot = atomicAdd(counters[COUNTER_CLIP_ITEMS], 1u);
        clip_items[slot] = uvec2(i, clip_mask | (any_face ? CLIP_ITEM_RASTERIZED : 0u));
    } else {
        atomicAdd(counters[any_face ? COUNTER_RASTERIZED : COUNTER_CULLED], 1u);
    }
}
