#version 450
// Soft pass: occlusion of one 128-sample block (paper §4.2). Work units as
// in the hard occlusion pass (tile, chunk of pairs, chunk of list entries),
// one invocation per light texel; for each listed view sample x of the
// texel's chunk, the block's bits that each caster T of the chunk blocks:
// the AND of "behind T's supporting plane, seen from x" and "inside the
// plane through x and each edge of T", each plane's bits looked up in the
// LUT (or, with EXACT, each light sample tested). The OR over casters goes
// into x's mask with one atomic OR per word. Closed meshes block only light
// samples behind their oriented plane (the back-face rule per light
// sample: no acne). Twin: cpu::soft::occlusion.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
#define LIGHT_SAMPLES_BINDING 10
#include "soft_common.glsl"
layout(local_size_x = 64) in;
layout(constant_id = 4) const uint EXACT = 0u;

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
layout(set = 0, binding = 11) uniform usamplerBuffer lut_tb;         // this block's LUT

// Light samples of the block with dot(n, y) < d (n unit).
uvec4 behind(vec3 n, float d) {
    if (d >= 1.0) {
        return uvec4(0xffffffffu);
    }
    if (!(d > -1.0)) {
        return uvec4(0u);
    }
    return texelFetch(lut_tb, int(lut_index(n, d, pc.soft.z)));
}

// The block's light samples that triangle (a, b, c) hides from x
// (camera-relative), with sigma the side of x (+1 in front of n).
uvec4 blocked_bits(vec3 x, vec3 a, vec3 b, vec3 c, vec3 n, float sigma) {
    vec3 o = pc.origin.xyz;
    float inv_r = 1.0 / pc.soft_light.x;
    vec3 m0 = cross(a - x, b - x), m1 = cross(b - x, c - x), m2 = cross(c - x, a - x);
    // Inside side of the edge planes: the side of the opposite vertex (one
    // determinant for all three, so that they agree).
    float se = dot(m0, c - x) < 0.0 ? -1.0 : 1.0;
    if (EXACT == 0u) {
        vec3 ns = normalize(sigma * n);
        uvec4 bits = behind(ns, dot(ns, a - o) * inv_r);
        if (bits == uvec4(0u)) return bits;
        vec3 u0 = normalize(-se * m0);
        bits &= behind(u0, dot(u0, x - o) * inv_r);
        if (bits == uvec4(0u)) return bits;
        vec3 u1 = normalize(-se * m1);
        bits &= behind(u1, dot(u1, x - o) * inv_r);
        if (bits == uvec4(0u)) return bits;
        vec3 u2 = normalize(-se * m2);
        bits &= behind(u2, dot(u2, x - o) * inv_r);
        return bits;
    }
    // Exact: every light sample of the block against the four planes.
    uint base = pc.soft.x * 128u;
    uint count = min(pc.soft.y - min(base, pc.soft.y), 128u);
    uvec4 bits = uvec4(0u);
    for (uint j = 0u; j < count; j++) {
        vec3 l = light_samples[base + j].xyz;
        if (sigma * dot(n, l - a) < 0.0 && se * dot(m0, l - x) > 0.0 && se * dot(m1, l - x) > 0.0
            && se * dot(m2, l - x) > 0.0) {
            uint w = j >> 5u, bit = 1u << (j & 31u);
            bits |= uvec4(w == 0u ? bit : 0u, w == 1u ? bit : 0u, w == 2u ? bit : 0u, w == 3u ? bit : 0u);
        }
    }
    return bits;
}

void main() {
    uint unit = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint tiles_per_face = pc.more.z;
    uint res = pc.sizes.z;
    if (unit >= pc.more.w) {
        return;
    }
    uint lo_t = 0u, hi_t = tiles_per_face * pc.sizes.w;
    while (hi_t - lo_t > 1u) {
        uint mid = (lo_t + hi_t) / 2u;
        if (unit_offsets[mid] <= unit) {
            lo_t = mid;
        } else {
            hi_t = mid;
        }
    }
    uint tile = lo_t;
    uint face = tile / tiles_per_face;
    uint in_face = tile % tiles_per_face;
    uvec2 tile_xy = uvec2(in_face % pc.more.y, in_face / pc.more.y);
    uvec2 texel = tile_xy * TILE + uvec2(gl_LocalInvocationID.x % TILE, gl_LocalInvocationID.x / TILE);
    uint begin = tile_offsets[tile], end = tile_offsets[tile + 1u];
    uint pair_chunks = (end - begin + OCC_PAIR_CHUNK - 1u) / OCC_PAIR_CHUNK;
    uint local_unit = unit - unit_offsets[tile];
    uint sample_chunk = local_unit / pair_chunks;
    begin += (local_unit % pair_chunks) * OCC_PAIR_CHUNK;
    end = min(end, begin + OCC_PAIR_CHUNK);
    uint tests = 0u, blocking = 0u;
    uint words = ((pc.soft.y + 127u) / 128u) * 4u;
    if (texel.x < res && texel.y < res && begin != end) {
        uint t = face * res * res + texel.y * res + texel.x;
        uint count = counts[t];
        uint list_begin = offsets[t] + min(count, sample_chunk * OCC_SAMPLE_CHUNK);
        uint list_end = offsets[t] + min(count, (sample_chunk + 1u) * OCC_SAMPLE_CHUNK);
        for (uint s = list_begin; s < list_end; s++) {
            uvec4 qb = texelFetch(list_samples_tb, int(s));
            vec3 x = uintBitsToFloat(qb.xyz);
            uvec4 acc = uvec4(0u);
            for (uint k = begin; k < end; k++) {
                uint pi = texelFetch(tile_pairs_tb, int(k)).x;
                uvec4 ids = texelFetch(pairs_tb, int(4u * pi));
                uvec2 rmin = uvec2(ids.z & 0xffffu, ids.z >> 16);
                uvec2 rmax = uvec2(ids.w & 0xffffu, ids.w >> 16);
                if (any(lessThan(texel, rmin)) || any(greaterThan(texel, rmax)) || qb.w == ids.x) {
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
                uvec4 bits = blocked_bits(x, a, b, c, n, sx > 0.0 ? 1.0 : -1.0);
                if (bits != uvec4(0u)) {
                    blocking++;
                    acc |= bits;
                }
            }
            if (acc != uvec4(0u)) {
                uint w = s * words + pc.soft.x * 4u;
                if (acc.x != 0u) atomicOr(masks[w], acc.x);
                if (acc.y != 0u) atomicOr(masks[w + 1u], acc.y);
                if (acc.z != 0u) atomicOr(masks[w + 2u], acc.z);
                if (acc.w != 0u) atomicOr(masks[w + 3u], acc.w);
            }
        }
    }
    uint sum_tests = subgroupAdd(tests);
    uint sum_blocking = subgroupAdd(blocking);
    if (subgroupElect() && (sum_tests | sum_blocking) != 0u) {
        atomicAdd(counters[COUNTER_TESTS], sum_tests);
        atomicAdd(counters[COUNTER_BLOCKING], sum_blocking);
    }
}
