// Alpha-tested casters (glTF MASK, and BLEND cast as MASK at 0.5): whether
// a point of such a triangle is opaque. The arithmetic is documented in
// src/cpu/alpha.rs (its twin): texture coordinates from barycentrics,
// NEAREST or LINEAR over 8-bit alphas, REPEAT / CLAMP_TO_EDGE /
// MIRRORED_REPEAT, opaque where factor * alpha >= cutoff * 255.
//
// Tables (texel buffers, passed in by the caller):
// - records: per alpha-tested triangle two RGBA32UI texels: u0, v0, u1, v1
//   (float bits); u2, v2 (float bits), texture, 0;
// - textures: per texture two RGBA32UI texels: first alpha, width, height,
//   flags (ALPHA_LINEAR | wrap_s << 1 | wrap_t << 3); cutoff, factor (float
//   bits), 0, 0;
// - alphas: R8UI, every texture's rows one after another, row 0 on top.
// A triangle is alpha-tested when GpuTriangle's flags have TRIANGLE_ALPHA
// (common.glsl); its record index is the w of its third vertex.
#ifndef AFS_ALPHA_COMMON_GLSL
#define AFS_ALPHA_COMMON_GLSL

#define ALPHA_LINEAR 1u
#define WRAP_REPEAT 0u
#define WRAP_CLAMP 1u
#define WRAP_MIRRORED 2u

// i mod n, non-negative (GLSL's % is undefined for negative operands).
int alpha_mod(int i, int n) {
    return i >= 0 ? i % n : (n - 1) - ((-1 - i) % n);
}

int alpha_wrap(int i, int n, uint mode) {
    if (mode == WRAP_CLAMP) {
        return clamp(i, 0, n - 1);
    }
    if (mode == WRAP_MIRRORED) {
        int m = alpha_mod(i, 2 * n);
        return m < n ? m : 2 * n - 1 - m;
    }
    return alpha_mod(i, n);
}

float alpha_texel(usamplerBuffer alphas, uvec4 tex, int i, int j) {
    int w = int(tex.y), h = int(tex.z);
    int x = alpha_wrap(i, w, (tex.w >> 1) & 3u);
    int y = alpha_wrap(j, h, (tex.w >> 3) & 3u);
    return float(texelFetch(alphas, int(tex.x) + y * w + x).x);
}

// Whether texture `texture` is opaque at texture coordinates uv.
bool alpha_opaque_uv(usamplerBuffer textures, usamplerBuffer alphas, uint texture, vec2 uv) {
    uvec4 tex = texelFetch(textures, int(2u * texture));
    vec2 cf = uintBitsToFloat(texelFetch(textures, int(2u * texture + 1u)).xy);
    vec2 size = vec2(tex.yz);
    float alpha;
    if ((tex.w & ALPHA_LINEAR) != 0u) {
        vec2 p = clamp(uv * size - 0.5, vec2(-16777216.0), vec2(16777216.0));
        vec2 f0 = floor(p);
        vec2 f = p - f0;
        int i = int(f0.x), j = int(f0.y);
        float top = alpha_texel(alphas, tex, i, j) * (1.0 - f.x) + alpha_texel(alphas, tex, i + 1, j) * f.x;
        float bottom = alpha_texel(alphas, tex, i, j + 1) * (1.0 - f.x) + alpha_texel(alphas, tex, i + 1, j + 1) * f.x;
        alpha = top * (1.0 - f.y) + bottom * f.y;
    } else {
        vec2 p = floor(clamp(uv * size, vec2(-16777216.0), vec2(16777216.0)));
        alpha = alpha_texel(alphas, tex, int(p.x), int(p.y));
    }
    return cf.y * alpha >= cf.x * 255.0;
}

// Whether record `record`'s triangle is opaque at barycentrics b (b1, b2).
bool alpha_opaque_at(usamplerBuffer records, usamplerBuffer textures, usamplerBuffer alphas, uint record, vec2 b) {
    vec4 r0 = uintBitsToFloat(texelFetch(records, int(2u * record)));
    uvec4 r1 = texelFetch(records, int(2u * record + 1u));
    vec2 uv = r0.xy * (1.0 - b.x - b.y) + r0.zw * b.x + uintBitsToFloat(r1.xy) * b.y;
    return alpha_opaque_uv(textures, alphas, r1.z, uv);
}

// Barycentrics (b1, b2) where the line from x along d meets the plane of
// (a, b, c): Moller-Trumbore.
vec2 segment_barycentrics(vec3 x, vec3 d, vec3 a, vec3 b, vec3 c) {
    vec3 e1 = b - a, e2 = c - a;
    vec3 p = cross(d, e2);
    float det = dot(e1, p);
    vec3 t = x - a;
    vec3 q = cross(t, e1);
    return vec2(dot(t, p) / det, dot(d, q) / det);
}

// Barycentrics (b1, b2) of the point s of the plane of (a, b, c) (Ericson).
vec2 point_barycentrics(vec3 s, vec3 a, vec3 b, vec3 c) {
    vec3 v0 = b - a, v1 = c - a, v2 = s - a;
    float d00 = dot(v0, v0), d01 = dot(v0, v1), d11 = dot(v1, v1);
    float d20 = dot(v2, v0), d21 = dot(v2, v1);
    float den = d00 * d11 - d01 * d01;
    return vec2((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den);
}

#endif
