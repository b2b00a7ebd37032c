// Soft shadows (paper §4): the plane look-up texture and the light samples.
// A plane is (n, d) in the light's normalized frame y = (l - origin) / R
// (every light sample has |y| <= 1); a LUT texel holds, for the plane at its
// centre, the bits of the light samples with dot(n, y) < d ("behind"), one
// uvec4 per 128-sample block, the blocks of a texel side by side (one
// index serves every block). Texel (i, j, k): n in octahedral coordinates
// (i, j over [-1, 1]^2: no trigonometry, cells within a factor ~2 of equal
// area) and d over [-1, 1]. That is approximate mode's table; look-up
// mode's (soft_occlusion.comp, sure_texels) has, per normal cell, the
// planes at d = -1 + k * 2 / res side by side (index (cell * res + k) *
// blocks + block).
// Twin: cpu::plane_lut (lut_texel_plane, lut_index, build_lut,
// build_sure_lut).
#ifndef AFS_SOFT_COMMON_GLSL
#define AFS_SOFT_COMMON_GLSL
#include "shadow_common.glsl"

#define MAX_LIGHT_SAMPLES 1024
#define MAX_LIGHT_BLOCKS 8
// Look-up mode's unsure list comes in segments, each with its own count a
// cache line apart (work unit u lists into segment u % UNSURE_SEGMENTS):
// one count that every unit's atomics hit cost 0.36 s of 1.3 s on two
// lavapipe threads (torus_knot:20000). Twin: gpu::soft_occlusion.
#define UNSURE_SEGMENTS 4u
#define UNSURE_COUNT_STRIDE 16u

// Light samples (xyz), read alike by every invocation: camera-relative, or
// normalized (plane_lut_build); a shader that reads them so defines
// LIGHT_SAMPLES_BINDING before including this file (one that reads them at
// a per-lane index binds a texel buffer of its own instead).
// Exact mode's occlusion also reads, after the samples, a sphere around
// each group of LIGHT_GROUP_SIZE consecutive samples (xyz centre, w
// radius; a group never spans two blocks), built by
// gpu::soft_light::light_groups.
#define LIGHT_GROUP_SIZE 16u
#define LIGHT_GROUPS_PER_BLOCK (128u / LIGHT_GROUP_SIZE)
#ifdef LIGHT_SAMPLES_BINDING
#ifdef LIGHT_GROUPS
layout(set = 0, binding = LIGHT_SAMPLES_BINDING, std140) uniform LightSamples {
    vec4 light_samples[MAX_LIGHT_SAMPLES];
    vec4 light_groups[MAX_LIGHT_SAMPLES / LIGHT_GROUP_SIZE];
};
#else
layout(set = 0, binding = LIGHT_SAMPLES_BINDING, std140) uniform LightSamples { vec4 light_samples[MAX_LIGHT_SAMPLES]; };
#endif
#endif

uint light_blocks() { return (pc.soft.y + 127u) / 128u; }

// The bits of the light samples first..first+31 that exist (of pc.soft.y).
uint existing_samples(uint first) {
    uint left = pc.soft.y - min(pc.soft.y, first);
    return left >= 32u ? 0xffffffffu : (1u << left) - 1u;
}

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

// The normal cell of lut_index (its index with k = 0) and that cell's
// centre normal (the plane of its texel (i, j, 0)). Twin:
// plane_lut::cell_normal. The centre comes from the cell's float
// coordinates, the same values as float(i), float(j), not from the index
// by integer division: lavapipe has no vector integer division and runs
// one per lane (look-up mode calls this four times per pair).
uint lut_normal_cell(vec3 n, uint res, out vec3 centre) {
    float r = float(res);
    vec2 c = clamp(floor((oct_encode(n) + 1.0) * (0.5 * r)), vec2(0.0), vec2(r - 1.0));
    centre = oct_decode(-1.0 + (c + 0.5) * (2.0 / r));
    return uint(c.y) * res + uint(c.x);
}

// Takes the lowest set bit out of a 128-bit mask (words x..w, not all
// zero): its word, and its bit in that word. Selects (mix with a boolean),
// not nested `?:`, which the compilers turned into branches: on lavapipe
// each branch is a masked block with its own mask bookkeeping.
uint take_lowest_bit(inout uvec4 left, out uint w) {
    bvec4 nonzero = notEqual(left, uvec4(0u));
    w = mix(mix(mix(3u, 2u, nonzero.z), 1u, nonzero.y), 0u, nonzero.x);
    bvec4 is_w = equal(uvec4(w), uvec4(0u, 1u, 2u, 3u));
    uvec4 picked = mix(uvec4(0u), left, is_w);
    uint word = picked.x | picked.y | picked.z | picked.w;
    uint bit = uint(findLSB(word));
    left = mix(left, uvec4(word & (word - 1u)), is_w);
    return bit;
}

// The exact per-sample test (exact mode, and the look-up mode's unsure
// bits): whether caster (a, b, c) hides light sample l from x, with the
// caster's normal n = cross(b - a, c - a), sigma the side of x
// (sign of dot(n, x - a)), the planes through x and each edge m0..m2 and
// their orientation se (soft_occlusion.comp computes them). One function,
// so that both modes evaluate the same f32 expressions.
bool exact_blocks(vec3 l, vec3 n, float sigma, vec3 a, vec3 x, vec3 m0, vec3 m1, vec3 m2, float se) {
    // all(), not &&: the same four comparisons without short-circuit
    // branches (see take_lowest_bit).
    return all(bvec4(sigma * dot(n, l - a) < 0.0, se * dot(m0, l - x) > 0.0,
                     se * dot(m1, l - x) > 0.0, se * dot(m2, l - x) > 0.0));
}

// `bits` as word `wd` of a block's four (a select, not an indexed write:
// lavapipe keeps locals in registers).
uvec4 in_word(uint wd, uint bits) {
    return mix(uvec4(0u), uvec4(bits), equal(uvec4(wd), uvec4(0u, 1u, 2u, 3u)));
}

// The bits of `unsure` (light samples `first` + 0..127 of `samples`) whose
// sample the caster blocks from x by exact_blocks: one loop over the set
// bits of all four words, not one per word, so that a subgroup runs as
// often as its busiest lane has bits, not the sum over words of each
// word's busiest (the unsure pass and look-up occlusion's in-place test).
uvec4 exact_blocked_bits(samplerBuffer samples, uint first, uvec4 unsure, vec3 n, float sigma, vec3 a, vec3 x,
                         vec3 m0, vec3 m1, vec3 m2, float se) {
    uvec4 left = unsure;
    uvec4 got = uvec4(0u);
    while (any(notEqual(left, uvec4(0u)))) {
        uint w;
        uint bit = take_lowest_bit(left, w);
        vec3 l = texelFetch(samples, int(first + w * 32u + bit)).xyz;
        got |= in_word(w, mix(0u, 1u << bit, exact_blocks(l, n, sigma, a, x, m0, m1, m2, se)));
    }
    return got;
}

#endif
