#version 450
// Turns each face's min/max keys into its window (one workgroup).
// Twin: cpu::light_view::fit_finalize.
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
#include "exact_div.glsl"
layout(local_size_x = 8) in;

layout(set = 0, binding = 0) readonly buffer Fit { uint fit_keys[]; };
layout(set = 0, binding = 1) writeonly buffer Faces { LightFace faces[]; };

void axis(float lo, float hi, out float x0, out float s) {
    float scale = max(max(abs(lo), abs(hi)), 1e-30);
    float width = max(hi - lo, scale * 1e-5);
    float pad = width * 1e-3;
    x0 = lo - pad;
    s = div_rn(float(pc.sizes.z), width + 2.0 * pad);
}

void main() {
    uint f = gl_LocalInvocationID.x;
    if (f >= pc.sizes.w) {
        return;
    }
    vec3 r, u, w;
    face_basis(f, r, u, w);
    LightFace lf;
    lf.up = vec4(u, 0.0);
    lf.forward = vec4(w, 0.0);
    lf.pad0 = vec4(0.0);
    lf.pad1 = vec4(0.0);
    lf.pad2 = vec4(0.0);
    if (fit_keys[f * 8u + 2u] == 0u) {
        lf.right = vec4(r, 0.0);
        lf.window = vec4(0.0);
        lf.far = vec4(0.0);
    } else {
        float x0, sx, y0, sy;
        axis(key_float(fit_keys[f * 8u + 0u]), key_float(fit_keys[f * 8u + 2u]), x0, sx);
        axis(key_float(fit_keys[f * 8u + 1u]), key_float(fit_keys[f * 8u + 3u]), y0, sy);
        lf.right = vec4(r, 1.0);
        lf.window = vec4(x0, y0, sx, sy);
        lf.far = vec4(key_float(fit_keys[f * 8u + 4u]), 0.0, 0.0, 0.0);
    }
    faces[f] = lf;
}
