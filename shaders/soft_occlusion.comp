#version 450
// Soft pass: occlusion (paper §4.2). Work units: (tile, chunk of
// OCC_PAIR_CHUNK pairs, chunk of 64 of the tile's listed samples), one
// invocation per listed view sample x; for x, the light samples that each
// caster T of the chunk whose influence region covers x's texel blocks: the AND of "behind T's
// supporting plane, seen from x" and "inside the plane through x and each
// edge of T". First the four planes are tested against the light's bounding
// sphere (no look-up: a plane that leaves the whole sphere outside means T
// blocks nothing); then each plane's bits are looked up in the LUT, every
// 128-sample block with the same index (LUT mode, all blocks in one pass),
// or every light sample of one block is tested (EXACT, one pass per block).
// The OR over casters goes into x's mask with one atomic OR per word; a
// sample whose every light sample is blocked stops early. Closed meshes
// block only light samples behind their oriented plane (the back-face rule
// per light sample: no acne). Twin: cpu::soft_occlusion::blocked_bits.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
#define LIGHT_SAMPLES_BINDING 10
#include "soft_common.glsl"
layout(local_size_x = 64) in;
// Compiled once per variant (build.rs): EXACT=1, or LUT_BLOCKS=1..8 (the
// light's 128-sample blocks). Code of the other mode and of unused blocks
// is compiled out, not branched over: lavapipe pays for guarded code it
// does not run (measured: 3.4 s against 1.7 s for one block).
#ifndef EXACT
#define EXACT 0
#endif
#ifndef LUT_BLOCKS
#define LUT_BLOCKS 1
#endif
#if EXACT
#define BLOCKS 1
#else
#define BLOCKS LUT_BLOCKS
#endif
// FOR_BLOCKS(M): M(0) M(1) ... M(BLOCKS - 1).
#if BLOCKS > 1
#define FOR_BLOCK_1(M) M(1)
#else
#define FOR_BLOCK_1(M)
#endif
#if BLOCKS > 2
#define FOR_BLOCK_2(M) M(2)
#else
#define FOR_BLOCK_2(M)
#endif
#if BLOCKS > 3
#define FOR_BLOCK_3(M) M(3)
#else
#define FOR_BLOCK_3(M)
#endif
#if BLOCKS > 4
#define FOR_BLOCK_4(M) M(4)
#else
#define FOR_BLOCK_4(M)
#endif
#if BLOCKS > 5
#define FOR_BLOCK_5(M) M(5)
#else
#define FOR_BLOCK_5(M)
#endif
#if BLOCKS > 6
#define FOR_BLOCK_6(M) M(6)
#else
#define FOR_BLOCK_6(M)
#endif
#if BLOCKS > 7
#define FOR_BLOCK_7(M) M(7)
#else
#define FOR_BLOCK_7(M)
#endif
#define FOR_BLOCKS(M) M(0) FOR_BLOCK_1(M) FOR_BLOCK_2(M) FOR_BLOCK_3(M) FOR_BLOCK_4(M) FOR_BLOCK_5(M) FOR_BLOCK_6(M) FOR_BLOCK_7(M)

layout(set = 0, binding = 0) uniform usamplerBuffer pairs_tb;     // CasterFace: 4 texels
layout(set = 0, binding = 1) uniform usamplerBuffer triangles_tb; // GpuTriangle: 3 texels
layout(set = 0, binding = 2) readonly buffer TileOffsets { uint tile_offsets[]; };
layout(set = 0, binding = 3) uniform usamplerBuffer tile_pairs_tb;
layout(set = 0, binding = 4) readonly buffer Counts { uint counts[]; };
layout(set = 0, binding = 5) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 6) uniform usamplerBuffer list_samples_tb; // xyz float bits, w triangle id
layout(set = 0, binding = 7) buffer Masks { uint masks[]; };         // per list slot: blocks * 4 words, blocked bits
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };
layout(set = 0, binding = 9) readonly buffer UnitOffsets { uint unit_offsets[]; };
layout(set = 0, binding = 11) uniform usamplerBuffer lut_tb;         // LUT, all blocks
#include "soft_occlusion_units.glsl"

#define LUT_ALL 0xffffffffu

// A plane's LUT code: LUT_ALL when the whole light is behind it (d >= 1),
// else its texel.
uint plane_code(vec3 u, float d) {
    return d >= 1.0 ? LUT_ALL : lut_index(u, d, pc.soft.z);
}

uvec4 lut_bits(uint code, uint block) {
    return code == LUT_ALL ? uvec4(0xffffffffu) : texelFetch(lut_tb, int(code * uint(BLOCKS) + block));
}

// LUT mode, block K: the AND of the four planes' bits, ORed into acc_K.
#define LUT_BLOCK(K)                                                         \
    {                                                                        \
        uvec4 bits = lut_bits(c0, uint(K));                             \
        if (bits != uvec4(0u)) bits &= lut_bits(c1, uint(K));           \
        if (bits != uvec4(0u)) bits &= lut_bits(c2, uint(K));           \
        if (bits != uvec4(0u)) bits &= lut_bits(c3, uint(K));           \
        acc##K |= bits;                                                      \
        hit = hit || bits != uvec4(0u);                                      \
    }

// Bits past the light's samples in block `block` (set from the start: the
// resolve ignores them, and a sample whose masks are all ones is done).
uvec4 past_end(uint block) {
    uint first = block * 128u;
    uint count = pc.soft.y - min(first, pc.soft.y);
    uvec4 w = uvec4(0u, 32u, 64u, 96u);
    uvec4 valid = uvec4(min(uvec4(count) - min(uvec4(count), w), uvec4(32u)));
    return uvec4(
        valid.x >= 32u ? 0u : ~((1u << valid.x) - 1u),
        valid.y >= 32u ? 0u : ~((1u << valid.y) - 1u),
        valid.z >= 32u ? 0u : ~((1u << valid.z) - 1u),
        valid.w >= 32u ? 0u : ~((1u << valid.w) - 1u));
}

#define FLUSH_BLOCK(K)                                                       \
    if (acc##K != init##K) {                                                 \
        uint w = s * words + (first_block + uint(K)) * 4u;                      \
        uvec4 a = acc##K & ~init##K;                                         \
        if (a.x != 0u) atomicOr(masks[w], a.x);                              \
        if (a.y != 0u) atomicOr(masks[w + 1u], a.y);                         \
        if (a.z != 0u) atomicOr(masks[w + 2u], a.z);                         \
        if (a.w != 0u) atomicOr(masks[w + 3u], a.w);                         \
    }

#define INIT_BLOCK(K) uvec4 init##K = past_end(first_block + uint(K));
#define ACC_BLOCK(K) uvec4 acc##K = init##K;
#define AND_BLOCK(K) all_blocks &= acc##K;

void main() {
    OcclusionUnit un = occlusion_unit();
    uint begin = un.pair_begin, end = un.pair_end, s = un.slot;
    uvec2 texel = un.texel;
    uint tests = 0u, blocking = 0u;
    uint words = light_blocks() * 4u;
    // LUT mode: every block in this pass; exact: block pc.soft.x only.
    uint first_block = EXACT != 0 ? pc.soft.x : 0u;
    vec3 o = pc.origin.xyz;
    float inv_r = 1.0 / pc.soft_light.x;
    if (un.has_sample) {
        FOR_BLOCKS(INIT_BLOCK)
        uvec4 qb = texelFetch(list_samples_tb, int(s));
        vec3 x = uintBitsToFloat(qb.xyz);
        vec3 ox = x - o;
        // Exact mode rejects a plane only beyond its rounding (1e-5 of
        // the distance in light radii), so that it never drops a light
        // sample that the per-sample test would block.
        float lo_x = EXACT != 0 ? -1.0 - 1e-5 * (1.0 + length(ox) * inv_r) : -1.0;
        FOR_BLOCKS(ACC_BLOCK)
        for (uint k = begin; k < end; k++) {
            uint pi = texelFetch(tile_pairs_tb, int(k)).x;
            uvec4 ids = texelFetch(pairs_tb, int(4u * pi));
            uvec2 rmin = uvec2(ids.z & 0xffffu, ids.z >> 16);
            uvec2 rmax = uvec2(ids.w & 0xffffu, ids.w >> 16);
            if (any(lessThan(texel, rmin)) || any(greaterThan(texel, rmax)) || qb.w == global_triangle(ids.x)) {
                continue; // outside the influence region, or the sample's own triangle
            }
            uvec4 t0 = texelFetch(triangles_tb, int(3u * ids.x));
            vec3 a = uintBitsToFloat(t0.xyz);
            vec3 b = uintBitsToFloat(texelFetch(triangles_tb, int(3u * ids.x + 1u)).xyz);
            vec3 c = uintBitsToFloat(texelFetch(triangles_tb, int(3u * ids.x + 2u)).xyz);
            vec3 n = cross(b - a, c - a);
            float sx = dot(n, x - a);
            bool closed = (t0.w & TRIANGLE_CLOSED) != 0u;
            // x on the plane: the segment does not cross it; x behind a
            // closed caster: only its front faces could block, and they do not cast.
            if (sx == 0.0 || isnan(sx) || (closed && sx < 0.0)) {
                continue;
            }
            tests++;
            float sigma = sx > 0.0 ? 1.0 : -1.0;
            // The supporting plane, facing x: light samples behind it.
            vec3 ns = (sigma * inversesqrt(dot(n, n))) * n;
            vec3 ao = a - o;
            float d0 = dot(ns, ao) * inv_r;
            float lo_a = EXACT != 0 ? -1.0 - 1e-5 * (1.0 + length(ao) * inv_r) : -1.0;
            if (!(d0 > lo_a)) {
                continue; // the whole light is on x's side of T
            }
            // The planes through x and each edge, facing out of T's
            // cone from x (one determinant orients all three alike).
            vec3 m0 = cross(a - x, b - x), m1 = cross(b - x, c - x), m2 = cross(c - x, a - x);
            float se = dot(m0, c - x) < 0.0 ? -1.0 : 1.0;
            vec3 u0 = (-se * inversesqrt(dot(m0, m0))) * m0;
            float d1 = dot(u0, ox) * inv_r;
            if (!(d1 > lo_x)) continue;
            vec3 u1 = (-se * inversesqrt(dot(m1, m1))) * m1;
            float d2 = dot(u1, ox) * inv_r;
            if (!(d2 > lo_x)) continue;
            vec3 u2 = (-se * inversesqrt(dot(m2, m2))) * m2;
            float d3 = dot(u2, ox) * inv_r;
            if (!(d3 > lo_x)) continue;
            bool hit = false;
#if !EXACT
            uint c0 = plane_code(ns, d0), c1 = plane_code(u0, d1);
            uint c2 = plane_code(u1, d2), c3 = plane_code(u2, d3);
            FOR_BLOCKS(LUT_BLOCK)
#else
            // Every light sample of the block against the four planes.
            uint base = first_block * 128u;
            uint n_block = min(pc.soft.y - min(base, pc.soft.y), 128u);
            uvec4 bits = uvec4(0u);
            for (uint j = 0u; j < n_block; j++) {
                vec3 l = light_samples[base + j].xyz;
                if (sigma * dot(n, l - a) < 0.0 && se * dot(m0, l - x) > 0.0
                    && se * dot(m1, l - x) > 0.0 && se * dot(m2, l - x) > 0.0) {
                    uint w = j >> 5u, bit = 1u << (j & 31u);
                    bits |= uvec4(w == 0u ? bit : 0u, w == 1u ? bit : 0u, w == 2u ? bit : 0u, w == 3u ? bit : 0u);
                }
            }
            acc0 |= bits;
            hit = bits != uvec4(0u);
#endif
            if (hit) {
                blocking++;
                uvec4 all_blocks = uvec4(0xffffffffu);
                FOR_BLOCKS(AND_BLOCK)
                if (all(equal(all_blocks, uvec4(0xffffffffu)))) {
                    break; // every light sample is blocked: nothing left to find
                }
            }
        }
        FOR_BLOCKS(FLUSH_BLOCK)
    }
    uint sum_tests = subgroupAdd(tests);
    uint sum_blocking = subgroupAdd(blocking);
    if (subgroupElect() && (sum_tests | sum_blocking) != 0u) {
        atomicAdd(counters[COUNTER_TESTS], sum_tests);
        atomicAdd(counters[COUNTER_BLOCKING], sum_blocking);
    }
}
