#version 450
// Soft pass: occlusion (paper §4.2). Work units: (tile, chunk of
// OCC_PAIR_CHUNK pairs, chunk of 64 of the tile's listed samples), one
// invocation per listed view sample x; for x, the light samples that each
// caster T of the chunk whose influence region covers x's texel blocks: the AND of "behind T's
// supporting plane, seen from x" and "inside the plane through x and each
// edge of T". First the four planes are tested against the light's bounding
// sphere (no look-up: a plane that leaves the whole sphere outside means T
// blocks nothing), and with exact masks two edge planes together (the
// wedge rule); then each plane's bits are looked up in the LUT, every
// 128-sample block with the same index (LUT mode, all blocks in one pass),
// or the light samples of one block are tested (EXACT, one pass per block;
// by groups of 16, each group first as a sphere against the four planes),
// or (SURE, the default mode: the masks of EXACT, all blocks in one pass)
// the table bounds each plane's bits from both sides and only the bits it
// leaves unsure are tested as EXACT tests them (see SURE_BLOCK): here, in
// the opaque round (within IN_PLACE_BUDGET), else by
// soft_occlusion_unsure.comp.
// The OR over casters goes into x's mask with one atomic OR per word; a
// sample whose every light sample is blocked stops early. Closed meshes
// block only light samples behind their oriented plane (the back-face rule
// per light sample: no acne). Twin: cpu::soft_occlusion::blocked_bits.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_shuffle : require
#define LIGHT_SAMPLES_BINDING 10
#define LIGHT_GROUPS
#include "soft_common.glsl"
#include "clusters_common.glsl"
#include "alpha_common.glsl"
#define PIXEL_ROTATION_BINDING 18
#include "pixel_rotation.glsl"
layout(local_size_x = 64) in;
// 1: the alpha-tested casters' round (exact and look-up modes): a light
// sample counts as blocked only where the caster is opaque at its
// segment's crossing, tested per light sample (exact mode, here; look-up
// mode, every bit the table does not rule out goes to the unsure list).
layout(constant_id = 5) const uint ALPHA = 0u;
// The wedge rule (wedges_miss_light; where WEDGE_COMPILED) in a loop of
// its own between the first loop and the second: 0 turns it off
// (ShadowSettings::wedge_rule).
layout(constant_id = 7) const uint WEDGE_RULE = 1u;
// Compiled once per variant (build.rs): EXACT=1, or LUT_BLOCKS=1..8 (the
// light's 128-sample blocks) with SURE=0 or 1. Code of the other mode and of unused blocks
// is compiled out, not branched over: lavapipe pays for guarded code it
// does not run (measured: 3.4 s against 1.7 s for one block).
#ifndef EXACT
#define EXACT 0
#endif
#ifndef LUT_BLOCKS
#define LUT_BLOCKS 1
#endif
#ifndef SURE
#define SURE 0
#endif
// The masks of exact mode (per-sample tests, with their rounding margins).
#define EXACT_MASKS (EXACT != 0 || SURE != 0)
// The wedge rule is compiled into exact mode only. In look-up mode it cost
// more than it saved even when run only while it paid (stop 47's
// bookkeeping): a warm 256² frame's shader instructions fall without it at
// one block, torus_knot:20000 4442 -> 4293 M, ToyCar on a ground 8584 ->
// 8226 M; at two blocks torus_knot:20000 5368 -> 5034 M; at eight blocks
// torus_knot:20000 9527 -> 9437 M, ToyCar 12073 -> 11878 M
// (scripts/frame-instructions.sh; docs/status.md, stops 55 and 56).
#define WEDGE_COMPILED (EXACT != 0)
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
// The light samples again (binding 10's buffer), for reads at a per-lane
// index (exact mode's groups, the unsure bits): a gather from a texel
// buffer. (No triangles: a pair carries its own, soft_pair_triangle.)
layout(set = 0, binding = 1) uniform samplerBuffer light_samples_tb;
layout(set = 0, binding = 2) readonly buffer TileOffsets { uint tile_offsets[]; };
layout(set = 0, binding = 3) uniform usamplerBuffer tile_pairs_tb;
layout(set = 0, binding = 4) readonly buffer Counts { uint counts[]; };
layout(set = 0, binding = 5) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 6) uniform usamplerBuffer list_samples_tb; // xyz float bits, w triangle id
layout(set = 0, binding = 7) buffer Masks { uint masks[]; };         // per list slot: blocks * 4 words, blocked bits
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };
layout(set = 0, binding = 9) readonly buffer UnitOffsets { uint unit_offsets[]; };
layout(set = 0, binding = 11) uniform usamplerBuffer lut_tb;         // LUT, all blocks
// SURE mode: the (slot, triangle, block) and unsure bits of each pair whose
// bits the table leaves unsure, for soft_occlusion_unsure.comp: segment k
// (UNSURE_SEGMENTS) holds pc.soft.x entries from entry k * pc.soft.x, and
// its count is unsure_counts[k * UNSURE_COUNT_STRIDE]; after the counts,
// each unit's number of entries (the host plans its ranges by them).
layout(set = 0, binding = 12) writeonly buffer UnsureList { uvec4 unsure_list[]; };
layout(set = 0, binding = 19) buffer UnsureCounts { uint unsure_counts[]; };
// Per tile: its view-sample box (clusters_bounds.comp; lo.w = 0: no box,
// and then no chunk culling either: the clusters are off or the tile too big).
layout(set = 0, binding = 13) uniform usamplerBuffer boxes_tb;
layout(set = 0, binding = 14) uniform usamplerBuffer alpha_records;
layout(set = 0, binding = 15) uniform usamplerBuffer alpha_textures;
layout(set = 0, binding = 16) uniform usamplerBuffer alpha_texels;
layout(set = 0, binding = 17) uniform usamplerBuffer list_sample_index_tb; // per slot: its view sample
// Per binned pair (slot of tile_pairs): the groups of the tile's samples
// it may shadow (pair_groups.comp).
layout(set = 0, binding = 20) uniform usamplerBuffer pair_groups_tb;
#if SURE
// Look-up mode runs the units in ranges, each flushing its unsure list
// (soft_occlusion.rs): soft.w is the range's first unit.
#define OCC_UNIT_BASE pc.soft.w
#endif
#include "soft_occlusion_units.glsl"

// The iterations of the in-place loops (unsure bits, and one per block
// with bits) that one subgroup may run in the opaque round: what its other
// loops leave of lavapipe's 65535 per subgroup (one SIMD vector runs a
// subgroup's invocations together and counts its loops' iterations once,
// all loops together), at most IN_PLACE_BUDGET. The other loops run at
// most 6 + 2 BLOCKS iterations per kept pair (the first loop's pair and
// the second's, one per block whose in-place loop no lane enters, one per
// block the pair lists and that loop's exit, and the windows' and groups'
// exits, 11 per window of 32 pairs) and fewer than 1024 more (keep_pairs'
// loops over a chunk of at most 2048 pairs, and the searches):
// with MAX_KEPT pairs and eight blocks that is 46,080, which leaves the
// in-place loops 19,455 iterations.
#define IN_PLACE_BUDGET 49152u
uint in_place_budget(uint kept) {
    uint others = (6u + 2u * uint(BLOCKS)) * kept + 1024u;
    return min(IN_PLACE_BUDGET, 65535u - others);
}

#define LUT_ALL 0xffffffffu
#define LUT_NONE 0xfffffffeu

// A plane's LUT code: LUT_ALL when the whole light is behind it (d >= 1),
// else its texel.
uint plane_code(vec3 u, float d) {
    return d >= 1.0 ? LUT_ALL : lut_index(u, d, pc.soft.z);
}

// SURE mode: where no plane of the table bounds a caster's plane (see
// sure_texels): every sample certainly behind (SURE_ALL), none certainly
// behind (SURE_NONE), every sample possibly behind (MAYBE_ALL).
#define BOUND_MAYBE_ALL 1u
#define BOUND_SURE_ALL 2u
#define BOUND_SURE_NONE 4u
// 64 f32 ulps: the rounding bound of a per-sample test, per unit of the
// magnitudes it involves.
#define ROUNDING_BOUND (64.0 * 1.1920929e-7)
// That bound for the per-sample test against planes through point q (the
// view sample, or a caster's vertex), in light radii (o the light's
// centre).
float rounding_bound(vec3 q, vec3 o, float inv_r) {
    return ROUNDING_BOUND * (length(o) + pc.soft_light.x + length(q) + length(q - o)) * inv_r;
}
// Exact mode's allowance past the bounding sphere for a plane through a
// point at `v` from the light's centre (1e-5 of the distance, in light
// radii): beyond it a plane rejects no light sample that the per-sample
// test would block.
float sphere_allowance(vec3 v, float inv_r) {
    return 1e-5 * (1.0 + length(v) * inv_r);
}
// plane_lut::SURE_SLACK: the build's and this choice's f32 rounding, and
// this device's decode of a cell's centre normal against the host's.
#define SURE_SLACK 3e-5
// SURE mode: the table's planes that bound caster plane (u, d) in u's
// normal cell (centre n_t): `te` at or below d - delta, `ts` at or above
// d + delta (texel indices, without the block), delta bounding
// |(u - n_t).y| over |y| <= 1 plus the pair's rounding allowance `allow`
// (the per-sample test's rounding bound) and SURE_SLACK, and the flags
// where no plane does. Twin: plane_lut::sure_texels.
void sure_texels(vec3 u, float d, uint res, float allow, out uint te, out uint ts, out uint flags) {
    vec3 centre;
    uint cell = lut_normal_cell(u, res, centre);
    float delta = length(u - centre) * (1.0 + 1e-5) + allow + SURE_SLACK;
    float lo = d - delta, hi = d + delta;
    float half_res = 0.5 * float(res);
    float ke = floor((lo + 1.0) * half_res);
    float ks = ceil((hi + 1.0) * half_res);
    float last = float(res) - 1.0;
    te = (cell * res + uint(clamp(ke, 0.0, last))) * uint(BLOCKS);
    ts = (cell * res + uint(clamp(ks, 0.0, last))) * uint(BLOCKS);
    flags = (ks >= float(res) ? BOUND_MAYBE_ALL : 0u)
        | (lo >= 1.0 + 1e-6 ? BOUND_SURE_ALL : 0u)
        | (ke < 0.0 ? BOUND_SURE_NONE : 0u);
}

uvec4 lut_bits(uint code, uint block) {
    return code == LUT_ALL ? uvec4(0xffffffffu)
        : (code == LUT_NONE ? uvec4(0u) : texelFetch(lut_tb, int(code * uint(BLOCKS) + block)));
}

// Adds `value` to the 64-bit counter whose low word is slot `lo` and high
// word slot `lo + 1` (the carry of the low word).
void count_wide(uint lo, uint value) {
    uint before = atomicAdd(counters[lo], value);
    if (before + value < before) {
        atomicAdd(counters[lo + 1u], 1u);
    }
}

// Exact mode's alpha round: sample K of a light-sample group (`first`
// its first, n_block the block's samples), tested without a loop; groups
// of 16 (LIGHT_GROUP_SIZE, held to 16 by gpu::soft_light).
#define GROUP_SAMPLE(K)                                                      \
    {                                                                        \
        uint jl = first + uint(K);                                           \
        vec3 l = texelFetch(light_samples_tb, int(base + min(jl, n_block - 1u))).xyz; \
        bool blocked = jl < n_block && exact_blocks(l, p.n, p.sigma, p.a, x, p.m0, p.m1, p.m2, p.se); \
        group_bits |= blocked ? 1u << (jl & 31u) : 0u;                      \
    }
#define FOR_GROUP_SAMPLES(M) M(0) M(1) M(2) M(3) M(4) M(5) M(6) M(7) M(8) M(9) M(10) M(11) M(12) M(13) M(14) M(15)

uint bit_count(uvec4 v) {
    return uint(bitCount(v.x) + bitCount(v.y) + bitCount(v.z) + bitCount(v.w));
}

// SURE mode: a plane's bounds in block `block`: the bits certainly behind
// it (from its lower texel te) and possibly behind it (its upper texel ts,
// a few texels on: a second fetch, where the old layout's two adjacent
// masks cost about one), and its flags.
uvec4 bounds_sure(uint te, uint flags, uint block) {
    uvec4 every = texelFetch(lut_tb, int(te + block));
    return (flags & BOUND_SURE_ALL) != 0u ? uvec4(0xffffffffu) : ((flags & BOUND_SURE_NONE) != 0u ? uvec4(0u) : every);
}
uvec4 bounds_maybe(uint ts, uint flags, uint block) {
    uvec4 some = texelFetch(lut_tb, int(ts + block));
    return (flags & BOUND_MAYBE_ALL) != 0u ? uvec4(0xffffffffu) : some;
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
    return ~uvec4(existing_samples(first), existing_samples(first + 32u),
                  existing_samples(first + 64u), existing_samples(first + 96u));
}

// SURE mode, block K. For each of the caster's four planes (u, d) the
// table's plane below it (n_t, d_e) has only samples with n_t.y < d_e <=
// d - delta, so u.y < d - (rounding allowance), and outside its plane
// above (n_t, d_s) only samples with u.y >= d + (allowance) (sure_texels);
// the exact per-sample test differs from "u.y < d" by at most the pair's
// rounding bound (through a and through x), which is the allowance: so
// "every" is blocked by that plane as the exact test sees it, and outside
// "some" it is not. Over the four planes: `sure` is blocked, `maybe`
// possibly; bits earlier casters blocked are left out (the OR does not need them
// again), and the pair's unsure bits are left to the exact test (main()'s
// loop over them, or the list that soft_occlusion_unsure.comp tests).
// Nothing is tested here: on lavapipe every branch's code runs for every
// lane, tested or not.
#define SURE_BLOCK(K)                                                        \
    uvec4 unsure##K;                                                         \
    {                                                                        \
        uvec4 sure = bounds_sure(le0, lf0, uint(K)) & bounds_sure(le1, lf1, uint(K)) \
            & bounds_sure(le2, lf2, uint(K)) & bounds_sure(le3, lf3, uint(K));   \
        uvec4 maybe = bounds_maybe(ls0, lf0, uint(K)) & bounds_maybe(ls1, lf1, uint(K)) \
            & bounds_maybe(ls2, lf2, uint(K)) & bounds_maybe(ls3, lf3, uint(K)); \
        if (rounding_too_large) {                                            \
            sure = uvec4(0u);                                                \
            maybe = uvec4(0xffffffffu);                                      \
        }                                                                    \
        if (ALPHA != 0u) {                                                   \
            sure = uvec4(0u); /* opaque or not: the unsure pass decides */   \
        }                                                                    \
        maybe &= ~acc##K;                                                    \
        sure &= maybe;                                                       \
        unsure##K = maybe & ~sure;                                           \
        acc##K |= sure;                                                      \
        hit = hit || sure != uvec4(0u);                                      \
        unsure_bits += bit_count(unsure##K);                                 \
        unsure_blocks |= unsure##K != uvec4(0u) ? 1u << uint(K) : 0u;        \
    }

// SURE mode: block K's unsure bits if K is `k` (a select, not an array:
// lavapipe keeps locals in registers).
#define PICK_UNSURE(K) if (k == uint(K)) picked = unsure##K;
// SURE mode, block K's unsure bits tested in place (when `in_place`), the
// bits blocked ORed into its accumulator.
#define PLACE_BLOCK(K)                                                       \
    {                                                                        \
        uvec4 got = exact_blocked_bits(light_samples_tb, (first_block + uint(K)) * 128u, \
                                       in_place ? unsure##K : uvec4(0u),     \
                                       p.n, p.sigma, p.a, x, p.m0, p.m1, p.m2, p.se); \
        acc##K |= got;                                                       \
        hit = hit || got != uvec4(0u);                                       \
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

// The alpha round starts from what the opaque round blocked (its masks,
// complete before this dispatch): those samples need no opacity look-up,
// and a sample they block wholly is done from the start.
uvec4 earlier_bits(bool has_sample, uint s, uint words, uint block) {
    uint w = (has_sample ? s : 0u) * words + block * 4u;
    return ALPHA != 0u && has_sample ? uvec4(masks[w], masks[w + 1u], masks[w + 2u], masks[w + 3u]) : uvec4(0u);
}
#define INIT_BLOCK(K) uvec4 init##K = past_end(first_block + uint(K)) | earlier_bits(un.has_sample, s, words, first_block + uint(K));
#define AND_INIT(K) all_init &= init##K;
#define ACC_BLOCK(K) uvec4 acc##K = init##K;
#define AND_BLOCK(K) all_blocks &= acc##K;

// View-sample clusters per chunk: the unit's pairs that this workgroup's
// own 64 samples can need (by the tile rules of clusters_common.glsl on
// the chunk's box, and the chunk's texels against each pair's rectangle),
// compacted before the loop: on lavapipe every lane runs every iteration,
// so only a shorter loop saves time. The pairs dropped are ones every lane
// would skip by occlusion's own early outs: the masks do not change.
// (main() counts a lane's tests in 16 bits: MAX_KEPT stays below 65536.)
// As long as look-up mode's chunks (gpu::tile_bin::LOOKUP_PAIR_CHUNK);
// gpu::soft_occlusion::SHARED_BYTES counts this kernel's shared arrays.
#define MAX_KEPT 2048u
shared uint kept_pairs[MAX_KEPT];
shared uint kept_count;
// The chunk's pairs whose texel rectangle meets its samples' (keep_pairs'
// first step).
shared uint meeting_pairs[MAX_KEPT];
shared uint meeting_count;
// Per subgroup: its samples' box (xyz) and texel rectangle (w: x | y << 16).
shared vec4 chunk_lo[64], chunk_hi[64];

// A pair's texels: its CasterFace's first (ids) and its triangle's three.
struct PairTexels {
    uvec4 ids, t0, t1, t2;
};

// A pair's texels, all from its own record (soft pairs carry their
// triangle: soft_pair_triangle).
PairTexels fetch_pair(uint pi) {
    PairTexels f;
    f.ids = texelFetch(pairs_tb, int(4u * pi));
    soft_pair_triangle(texelFetch(pairs_tb, int(4u * pi + 1u)), texelFetch(pairs_tb, int(4u * pi + 2u)),
                       texelFetch(pairs_tb, int(4u * pi + 3u)), f.t0, f.t1, f.t2);
    return f;
}

// This workgroup's pairs that its samples may need, into kept_pairs; the
// count of those kept, and the texel rectangle of the subgroup's samples
// (sg_tmin, sg_tmax: the first loop's per-subgroup test). All invocations
// call it (barriers).
uint keep_pairs(OcclusionUnit un, vec3 x, out uint dropped, out uint by_groups, out uint penumbra,
                out uint beyond_chunk, out uvec2 sg_tmin, out uvec2 sg_tmax) {
    uint lid = gl_LocalInvocationID.x;
    // The chunk's box and texel rectangle: per subgroup, then over the
    // subgroups through shared memory; lanes without a sample add nothing.
    vec3 inf = vec3(1.0 / 0.0);
    vec3 sg_lo = subgroupMin(un.has_sample ? x : inf);
    vec3 sg_hi = subgroupMax(un.has_sample ? x : -inf);
    sg_tmin = subgroupMin(un.has_sample ? un.texel : uvec2(0xffffu));
    sg_tmax = subgroupMax(un.has_sample ? un.texel : uvec2(0u));
    if (subgroupElect()) {
        chunk_lo[gl_SubgroupID] = vec4(sg_lo, uintBitsToFloat(sg_tmin.x | (sg_tmin.y << 16)));
        chunk_hi[gl_SubgroupID] = vec4(sg_hi, uintBitsToFloat(sg_tmax.x | (sg_tmax.y << 16)));
    }
    if (lid == 0u) {
        kept_count = 0u;
        meeting_count = 0u;
    }
    barrier();
    vec3 lo = inf, hi = -inf;
    uvec2 tmin = uvec2(0xffffu), tmax = uvec2(0u);
    for (uint j = 0u; j < gl_NumSubgroups; j++) {
        vec4 l = chunk_lo[j], h = chunk_hi[j];
        lo = min(lo, l.xyz);
        hi = max(hi, h.xyz);
        uint a = floatBitsToUint(l.w), b = floatBitsToUint(h.w);
        tmin = min(tmin, uvec2(a & 0xffffu, a >> 16));
        tmax = max(tmax, uvec2(b & 0xffffu, b >> 16));
    }
    bool any_sample = lo.x <= hi.x;
    bool box = any_sample && uintBitsToFloat(texelFetch(boxes_tb, int(2u * un.tile)).w) != 0.0;
    uint local_dropped = 0u, local_groups = 0u, local_penumbra = 0u, local_beyond = 0u;
    // The groups of the tile's samples (pair_groups.comp) that this chunk
    // overlaps: bits ga and gb of each pair's group bits (none in a tile
    // of fewer than CLUSTER_GROUP_MIN groups, which has no bits, or past
    // the bits: every pair kept).
    uint tile_first = offsets[un.tile * TILE * TILE], tile_end = offsets[(un.tile + 1u) * TILE * TILE];
    uint chunk_first = un.slot - lid;
    uint chunk_last = min(chunk_first + 63u, max(tile_end, 1u) - 1u);
    uint g0 = tile_first / CLUSTER_GROUP_SAMPLES;
    uint ga = chunk_first / CLUSTER_GROUP_SAMPLES - g0, gb = chunk_last / CLUSTER_GROUP_SAMPLES - g0;
    bool grouped_tile = cluster_groups_spanned(tile_first, tile_end) >= CLUSTER_GROUP_MIN && gb < CLUSTER_GROUP_BITS;
    uint group_bits = grouped_tile ? (1u << ga) | (1u << gb) : 0u;
    // First the pairs that some group of the chunk keeps and whose texel
    // rectangle meets the chunk's (one fetch each; most of the chunk's
    // drops), then the chunk rules (the pair's triangle and plane) for
    // those only: on lavapipe a loop's lanes pay for every pair's rules,
    // needed or not.
    for (uint k = un.pair_begin + lid; k < un.pair_end; k += 64u) {
        uint pi = texelFetch(tile_pairs_tb, int(k)).x;
        bool grouped = group_bits == 0u || (texelFetch(pair_groups_tb, int(k)).x & group_bits) != 0u;
        local_groups += box && !grouped ? 1u : 0u;
        bool meets = !box || (grouped && pair_meets(texelFetch(pairs_tb, int(4u * pi)), tmin, tmax));
        uvec4 ballot = subgroupBallot(meets);
        uint first = 0u;
        if (subgroupElect()) {
            first = atomicAdd(meeting_count, subgroupBallotBitCount(ballot));
        }
        first = subgroupBroadcastFirst(first);
        if (meets) {
            meeting_pairs[first + subgroupBallotExclusiveBitCount(ballot)] = pi;
        } else {
            local_dropped++;
        }
    }
    barrier();
    uint meeting = meeting_count;
    for (uint k = lid; k < meeting; k += 64u) {
        uint pi = meeting_pairs[k];
        bool keep = true;
        if (box) {
            PairTexels f = fetch_pair(pi);
            uint rule = chunk_rule(triangle_cluster_plane(f.t0, f.t1, f.t2), lo, hi);
            keep = rule == CLUSTER_KEEP;
            local_penumbra += rule == CLUSTER_OUTSIDE_PENUMBRA ? 1u : 0u;
            local_beyond += rule == CLUSTER_BEYOND_REACH ? 1u : 0u;
        }
        // One shared atomic per subgroup (lavapipe serializes per-lane atomics).
        uvec4 ballot = subgroupBallot(keep);
        uint count = subgroupBallotBitCount(ballot);
        uint first = 0u;
        if (subgroupElect()) {
            first = atomicAdd(kept_count, count);
        }
        first = subgroupBroadcastFirst(first);
        if (keep) {
            kept_pairs[first + subgroupBallotExclusiveBitCount(ballot)] = pi;
        } else {
            local_dropped++;
        }
    }
    barrier();
    dropped = local_dropped;
    by_groups = local_groups;
    penumbra = local_penumbra;
    beyond_chunk = local_beyond;
    return kept_count;
}

// What pair_planes decided for a (sample, pair): culled before the
// test counter (outside the pair's region, the sample's own triangle, on
// its plane or behind a closed caster), culled by the caster's plane or by
// an edge's plane leaving the light's bounding sphere on x's side (each
// counted as a test, and counted apart), or passed.
#define PAIR_CULLED 0u
#define PAIR_PLANE_REJECTED 1u
#define PAIR_EDGE_REJECTED 2u
#define PAIR_PASSED 3u
struct PairPlanes {
    uvec4 ids;
    vec3 a, b, c, n, ns, m0, m1, m2, u0, u1, u2;
    float sigma, se, d0, d1, d2, d3;
    uint alpha_record;
};

// Lane `lane`'s PairTexels, for every lane.
PairTexels shuffle_pair(PairTexels f, uint lane) {
    return PairTexels(subgroupShuffle(f.ids, lane), subgroupShuffle(f.t0, lane),
                      subgroupShuffle(f.t1, lane), subgroupShuffle(f.t2, lane));
}

// The caster of a pair (its texels `f`; pair_planes: of pair `pi`)
// against sample x (in texel `texel`, on global triangle `own`): its
// supporting plane facing x (ns, d0) and the planes
// through x and each edge (u0..u2, d1..d3), in light radii from the
// light's centre o; x and the caster are turned back by `turn_back`.
// In two parts: pair_culled, the per-lane culls that need only the
// caster's plane (true: PAIR_CULLED), then pair_tail for the rest, so
// that the first loop can skip the tail where every lane culls the pair.
bool pair_culled(PairTexels f, uvec2 texel, uint own, vec3 x, mat3 turn_back, out PairPlanes p) {
    p.ids = f.ids;
    uvec4 ids = p.ids;
    uvec4 t0 = f.t0;
    vec3 a = uintBitsToFloat(t0.xyz);
    vec3 b = uintBitsToFloat(f.t1.xyz);
    uvec4 c_record = f.t2;
    vec3 c = uintBitsToFloat(c_record.xyz);
    p.alpha_record = c_record.w;
    if (ROTATION != 0u) {
        a = unrotate_point(a, turn_back);
        b = unrotate_point(b, turn_back);
        c = unrotate_point(c, turn_back);
    }
    p.a = a;
    p.b = b;
    p.c = c;
    vec3 n = cross(b - a, c - a);
    p.n = n;
    float sx = dot(n, x - a);
    p.sigma = sx > 0.0 ? 1.0 : -1.0;
    bool closed = (t0.w & TRIANGLE_CLOSED) != 0u;
    // Outside the influence region, or the sample's own triangle; x on
    // the plane: the segment does not cross it; x behind a closed
    // caster: only its front faces could block, and they do not cast.
    // (Each test in a local first: `||` over calls became branches, and
    // lavapipe runs a branch's body for every lane, masked.)
    bool outside = !pair_meets(ids, texel, texel);
    bool own_triangle = own == global_triangle(ids.x);
    return outside || own_triangle || sx == 0.0 || isnan(sx) || (closed && sx < 0.0);
}

// The rest of a pair that pair_culled kept: PAIR_PLANE_REJECTED,
// PAIR_EDGE_REJECTED or PAIR_PASSED.
uint pair_tail(vec3 x, vec3 o, float inv_r, vec3 ox, float lo_x, inout PairPlanes p) {
    vec3 a = p.a, b = p.b, c = p.c, n = p.n;
    // The supporting plane, facing x: light samples behind it.
    vec3 ns = (p.sigma * inversesqrt(dot(n, n))) * n;
    p.ns = ns;
    vec3 ao = a - o;
    p.d0 = dot(ns, ao) * inv_r;
    float lo_a = EXACT_MASKS ? -1.0 - sphere_allowance(ao, inv_r) : -1.0;
    // The whole light on x's side of T: rejected by T's plane (decided at
    // the end, not by an early return: lavapipe runs the rest for every
    // lane anyway, and a return adds a mask to all of it).
    bool plane_rejected = !(p.d0 > lo_a);
    // The planes through x and each edge, facing out of T's
    // cone from x (one determinant orients all three alike).
    vec3 m0 = cross(a - x, b - x), m1 = cross(b - x, c - x), m2 = cross(c - x, a - x);
    p.m0 = m0;
    p.m1 = m1;
    p.m2 = m2;
    float se = dot(m0, c - x) < 0.0 ? -1.0 : 1.0;
    p.se = se;
    p.u0 = (-se * inversesqrt(dot(m0, m0))) * m0;
    p.d1 = dot(p.u0, ox) * inv_r;
    p.u1 = (-se * inversesqrt(dot(m1, m1))) * m1;
    p.d2 = dot(p.u1, ox) * inv_r;
    p.u2 = (-se * inversesqrt(dot(m2, m2))) * m2;
    p.d3 = dot(p.u2, ox) * inv_r;
    bool edges_pass = all(greaterThan(vec3(p.d1, p.d2, p.d3), vec3(lo_x)));
    return plane_rejected ? PAIR_PLANE_REJECTED : (edges_pass ? PAIR_PASSED : PAIR_EDGE_REJECTED);
}

uint pair_planes_of(PairTexels f, uvec2 texel, uint own, vec3 x, vec3 o, float inv_r, vec3 ox,
                    float lo_x, mat3 turn_back, out PairPlanes p) {
    // Both parts, then a select (see pair_culled).
    bool culled = pair_culled(f, texel, own, x, turn_back, p);
    uint tail = pair_tail(x, o, inv_r, ox, lo_x, p);
    return culled ? PAIR_CULLED : tail;
}

// The ball of the subgroup's samples whose lanes are `member`: centre
// (xyz; any point, the radius is measured from it) and radius (w), or
// w < 0 where no lane is a member.
vec4 subgroup_ball(bool member, vec3 x) {
    vec3 c = 0.5 * (subgroupMin(member ? x : vec3(1.0 / 0.0)) + subgroupMax(member ? x : vec3(-1.0 / 0.0)));
    return vec4(c, subgroupMax(member ? length(x - c) : -1.0));
}

// Whether the caster's ball lies outside the hull of the subgroup's ball
// `sb` (subgroup_ball) and the light's; true for no ball (no sample
// needs the caster).
bool outside_ball_hull(vec4 ball, vec4 sb) {
    return sb.w < 0.0 || outside_hull(ball, sb.xyz, sb.w, HULL_MARGIN_BOX);
}

// The wedge rule (a separating plane from two of the edges' planes): the
// light samples y (light radii from its centre, |y| <= 1) that the exact
// test can find behind planes (u_i, d_i) and (u_j, d_j) satisfy
// u.y < d + m, m above the test's rounding bound; for weights l_i, l_j >= 0
// every such y has (l_i u_i + l_j u_j).y < l_i (d_i + m) + l_j (d_j + m), and
// no y with |y| <= 1 does when that sum is below -|l_i u_i + l_j u_j| (the
// 1 + 1e-5 and m also hold this sum's own rounding). Any weights keep
// that true; those of the point of the planes' common edge nearest the
// light's centre (s = -d: the centre's distance outside each plane) make it
// reject whenever that edge passes outside the sphere, which a plane alone
// does not (a thin cone passing the light up to two radii off). Twin:
// cpu::soft_occlusion::edge_misses_light.
bool edge_misses_light(vec3 ui, float di, vec3 uj, float dj, float m) {
    float g = dot(ui, uj);
    float li = max(g * dj - di, 0.0), lj = max(g * di - dj, 0.0);
    return li * (di + m) + lj * (dj + m) + (1.0 + 1e-5) * length(li * ui + lj * uj) < 0.0;
}

// The wedge rule over the three edges' planes through x (their cone holds
// every light sample the caster can block from x). Twin:
// cpu::soft_occlusion::wedges_miss_light.
bool wedges_miss_light(PairPlanes p, float m) {
    return edge_misses_light(p.u0, p.d1, p.u1, p.d2, m) || edge_misses_light(p.u1, p.d2, p.u2, p.d3, m)
        || edge_misses_light(p.u2, p.d3, p.u0, p.d1, m);
}

uint pair_planes(uint pi, uvec2 texel, uint own, vec3 x, vec3 o, float inv_r, vec3 ox,
                 float lo_x, mat3 turn_back, out PairPlanes p) {
    return pair_planes_of(fetch_pair(pi), texel, own, x, o, inv_r, ox, lo_x, turn_back, p);
}

void main() {
    OcclusionUnit un = occlusion_unit();
    uint s = un.slot;
    uvec2 texel = un.texel;
    uint tests = 0u, blocking = 0u, unsure_bits = 0u, listed = 0u, past_sphere = 0u, wedge_rejected = 0u;
    // Exact mode: light-sample groups tested sample by sample, and groups
    // wholly blocked without a per-sample test.
    uint groups_tested = 0u, groups_every = 0u;
    uint words = light_blocks() * 4u;
    // LUT mode: every block in this pass; exact: block pc.soft.x only.
    uint first_block = EXACT != 0 ? pc.soft.x : 0u;
    vec3 o = pc.origin.xyz;
    float inv_r = 1.0 / pc.soft_light.x;
    uvec4 qb = un.has_sample ? texelFetch(list_samples_tb, int(s)) : uvec4(0u);
    vec3 x = uintBitsToFloat(qb.xyz);
    uint chunk_dropped, chunk_groups, chunk_penumbra, chunk_beyond;
    uvec2 sg_tmin, sg_tmax;
    uint kept = keep_pairs(un, x, chunk_dropped, chunk_groups, chunk_penumbra, chunk_beyond, sg_tmin, sg_tmax);
#if SURE
    uint in_place_left = in_place_budget(kept);
#endif
    // The reach rule's bound for x: x's distance to the light's centre, or
    // the light's radius.
    float reach_x = max(length(x - pc.origin.xyz), pc.soft_light.x);
    uint beyond_tests = 0u;
    // The subgroup's largest: a pair beyond it is one every lane culls
    // (beyond_reach grows with the reach), left out of the loop.
    float sg_reach = subgroupMax(un.has_sample ? reach_x : 0.0);
    // The hull rule's balls of the subgroup's samples, two of them: its
    // samples nearer the light than the middle of their distances (a) and
    // the others (b). A subgroup can hold samples far apart in depth (a
    // car's roof and the ground under it, in one texel), whose one ball
    // culls little; a pair outside the hull of both balls is one that
    // every lane culls. (Each ball's centre is any point: its radius is
    // measured from it.)
    float depth = length(x - pc.origin.xyz);
    float split = 0.5 * (subgroupMin(un.has_sample ? depth : 1.0 / 0.0) + subgroupMax(un.has_sample ? depth : -1.0 / 0.0));
    bool in_a = un.has_sample && depth <= split;
    vec4 sg_ball_a = subgroup_ball(in_a, x), sg_ball_b = subgroup_ball(un.has_sample && !in_a, x);
    // x as seen (the pairs' frame, before any turn below).
    vec3 x_seen = x;
    uint hull_tests = 0u;
    uint begin = 0u, end = kept;
    // Per-pixel rotation: x and each caster turned back by x's angle about
    // the light's axis through its centre, which keeps the light's bounding
    // sphere: every rule above and every influence region (tested on the
    // unturned geometry against that sphere) hold for the turned pair too.
    mat3 turn_back = mat3(1.0);
    if (ROTATION != 0u && un.has_sample) {
        turn_back = unrotation(pixel_angle(texelFetch(list_sample_index_tb, int(s)).x));
        x = unrotate_point(x, turn_back);
    }
    {
        FOR_BLOCKS(INIT_BLOCK)
        vec3 ox = x - o;
        // Exact mode rejects a plane only beyond its rounding (1e-5 of
        // the distance in light radii), so that it never drops a light
        // sample that the per-sample test would block.
        float lo_x = EXACT_MASKS ? -1.0 - sphere_allowance(ox, inv_r) : -1.0;
#if EXACT_MASKS
        // The rounding bound of the per-sample test against the planes
        // through x.
        float delta_x = rounding_bound(x, o, inv_r);
#endif
#if SURE
        // This unit's segment of the unsure list (by its index in the dispatch).
        uint segment = workgroup_index() % UNSURE_SEGMENTS;
#endif
#if EXACT_MASKS
        // Exact mode's group rules hold beyond twice the per-sample test's
        // rounding bound and the whole-light rejection's allowance.
        float margin_x = 2.0 * (delta_x + sphere_allowance(ox, inv_r));
#endif
        FOR_BLOCKS(ACC_BLOCK)
        // Per window (PAIR_WINDOW, shadow_common.glsl): the cheap rules of
        // pair_planes for each pair, with exact masks the wedge rule for
        // the pairs that passed, then the look-ups (or exact tests) for
        // those left. The later loops compute a pair's planes again rather
        // than keep a window of them per lane.
        // Lanes without a sample take part in the first loop's fetches
        // (below) and count nothing.
        uvec4 all_init = uvec4(0xffffffffu);
        FOR_BLOCKS(AND_INIT)
        bool full = !un.has_sample || all(equal(all_init, uvec4(0xffffffffu)));
        for (uint w0 = begin; w0 < end; w0 += PAIR_WINDOW) {
            // The subgroup leaves together: its lanes stay converged for
            // the first loop's shuffles.
            if (subgroupBallotBitCount(subgroupBallot(!full)) == 0u) {
                break;
            }
            uint window = min(PAIR_WINDOW, end - w0);
            uint passed = 0u;
            // The first loop's pairs are the same for every lane: lane k of
            // the subgroup fetches pair j0 + k of each `group`, and each
            // lane takes them from it by a shuffle (on lavapipe a gather
            // costs a load per lane: 8 pairs for 4 fetches, not 32).
            uint group = min(gl_SubgroupSize, PAIR_WINDOW);
            for (uint j0 = 0u; j0 < window; j0 += group) {
                uint k = min(j0 + gl_SubgroupInvocationID % group, window - 1u);
                PairTexels fetched = fetch_pair(kept_pairs[w0 + k]);
                // Per pair, the reach rule's caster bound (each lane takes
                // pair jj's by a shuffle).
                vec4 ball = caster_ball(uintBitsToFloat(fetched.t0.xyz), uintBitsToFloat(fetched.t1.xyz),
                                        uintBitsToFloat(fetched.t2.xyz));
                vec2 sphere = caster_sphere(o, ball);
                // The pairs whose rectangle meets some texel of the
                // subgroup's samples and that are within its reach: the
                // others every lane culls (those beyond reach counted as
                // each lane's culls).
                uint meeting = subgroupBallot(pair_meets(fetched.ids, sg_tmin, sg_tmax)).x
                    & first_bits(min(group, window - j0));
                uint far = subgroupBallot(beyond_reach(sphere, sg_reach, REACH_MARGIN)).x & meeting;
                meeting &= ~far;
                beyond_tests += full ? 0u : uint(bitCount(far));
                // The hull rule for the subgroup's two balls (counted as
                // each lane's culls).
                uint outside = subgroupBallot(outside_ball_hull(ball, sg_ball_a) && outside_ball_hull(ball, sg_ball_b)).x & meeting;
                meeting &= ~outside;
                hull_tests += full ? 0u : uint(bitCount(outside));
                while (meeting != 0u) {
                    uint jj = uint(findLSB(meeting));
                    meeting &= meeting - 1u;
                    uint j = j0 + jj;
                    PairPlanes p;
                    bool culled = pair_culled(shuffle_pair(fetched, jj), texel, qb.w, x, turn_back, p);
                    // The reach rule: culled, not a test.
                    bool beyond = !culled && beyond_reach(subgroupShuffle(sphere, jj), reach_x, REACH_MARGIN);
                    // The hull rule for x itself.
                    bool outside_x = !culled && !beyond
                        && outside_hull(subgroupShuffle(ball, jj), x_seen, 0.0, HULL_MARGIN);
                    // The planes' tail for every lane, then a select: in a
                    // loop that lanes which culled the pair skip (lavapipe
                    // skips a loop no lane enters) it cost more than it
                    // saved (a warm 256² frame, look-up mode:
                    // torus_knot:20000 4070 -> 3949 M shader instructions,
                    // ToyCar on a ground 7948 -> 7815 M; status.md, stop 57).
                    uint tail_rule = pair_tail(x, o, inv_r, ox, lo_x, p);
                    uint rule = culled || beyond || outside_x ? PAIR_CULLED : tail_rule;
                    if (!full) {
                        beyond_tests += beyond ? 1u : 0u;
                        hull_tests += outside_x ? 1u : 0u;
                        // Tests in the low half, plane rejections in the high
                        // half (at most MAX_KEPT of each per invocation): one add.
                        tests += rule == PAIR_CULLED ? 0u : (rule == PAIR_PLANE_REJECTED ? 0x10001u : 1u);
                        passed |= rule == PAIR_PASSED ? 1u << j : 0u;
                    }
                }
            }
#if WEDGE_COMPILED
            // The wedge rule, over the pairs that passed, in a loop of its
            // own: each iteration recomputes a pair's planes, and the second
            // loop then runs as often as its busiest lane's pairs left. In
            // the first loop it cost every (sample, pair) there (ToyCar on a
            // ground, 128 samples: 171.5 M tests for 12.1 M past the sphere
            // tests); here it costs those past them, and the second loop's
            // iterations fall where it rejects most (ToyCar: 2.16 -> 0.43 M
            // for the subgroups).
            if (WEDGE_RULE != 0u) {
                uint candidates = full ? 0u : passed;
                passed = 0u;
                while (candidates != 0u) {
                    uint j = uint(findLSB(candidates));
                    candidates &= candidates - 1u;
                    PairPlanes p;
                    pair_planes(kept_pairs[w0 + j], texel, qb.w, x, o, inv_r, ox, lo_x, turn_back, p);
                    bool wedge_miss = wedges_miss_light(p, margin_x);
                    passed |= wedge_miss ? 0u : 1u << j;
                    wedge_rejected += wedge_miss ? 1u : 0u;
                }
            }
#endif
            past_sphere += uint(bitCount(passed));
            while (passed != 0u && !full) {
                uint j = uint(findLSB(passed));
                passed &= passed - 1u;
                PairPlanes p;
                pair_planes(kept_pairs[w0 + j], texel, qb.w, x, o, inv_r, ox, lo_x, turn_back, p);
                bool hit = false;
#if SURE
                // The pair's own rounding bound is its allowance: a small
                // light (far from the camera for its size) widens each
                // plane's unsure band by that much instead of leaving every
                // bit unsure under one fixed allowance. Past the largest
                // allowance (soft_light.w; or not a number) every bit is.
                float allow = max(rounding_bound(p.a, o, inv_r), delta_x);
                bool rounding_too_large = !(allow <= pc.soft_light.w);
                uint res = pc.soft.z;
                uint le0, ls0, lf0, le1, ls1, lf1, le2, ls2, lf2, le3, ls3, lf3;
                sure_texels(p.ns, p.d0, res, allow, le0, ls0, lf0);
                sure_texels(p.u0, p.d1, res, allow, le1, ls1, lf1);
                sure_texels(p.u1, p.d2, res, allow, le2, ls2, lf2);
                sure_texels(p.u2, p.d3, res, allow, le3, ls3, lf3);
                uint unsure_blocks = 0u;
                uint unsure_before = unsure_bits;
                FOR_BLOCKS(SURE_BLOCK)
                // The opaque round tests the unsure bits here, as the unsure
                // pass tests them (the same planes and exact_blocked_bits), in
                // a loop that runs as often as the most bits any lane has, so
                // that a sample they block wholly stops at once (measured in
                // status.md, stop 51); with more blocks, one such loop per
                // block, unrolled: no selects to pick a lane's block, and
                // lanes' unsure bits mostly fall in the same blocks
                // (torus_knot:20000 at 1024 samples: 8.7 M iterations where
                // a loop over each lane's own blocks ran 16.3 M; the frame
                // time did not measurably change, stop 54). The alpha round
                // lists them (opacity look-ups per bit). So does a pair past
                // in_place_budget's iterations of
                // those loops in this subgroup: lavapipe silently ends the
                // loops of a subgroup (one SIMD vector) after 65535
                // iterations in all, and a unit's pairs with 128 unsure
                // bits each would pass that (a light small for its distance
                // leaves every bit unsure; stop 53). The budget is counted
                // per subgroup, as the loops count: a pair's cost is the sum
                // of its lanes' bits (each block's loop runs as long as its
                // busiest lane's bits, at most that sum) and one per block,
                // one decision for every lane. A per-lane budget let 46 mask
                // words differ (lut_exact.rs,
                // lanes_with_unsure_bits_of_their_own_stay_exact; stop 54).
                uint pair_bits = unsure_bits - unsure_before;
                uint sg_bits = subgroupAdd(pair_bits);
                uint sg_cost = sg_bits + (sg_bits != 0u ? uint(BLOCKS) : 0u);
                bool in_place = ALPHA == 0u && sg_cost <= in_place_left;
                in_place_left -= in_place ? sg_cost : 0u;
                unsure_blocks = in_place ? 0u : unsure_blocks;
                FOR_BLOCKS(PLACE_BLOCK)
                // The pair's entries, one per block with unsure bits, after
                // the subgroup's lanes before it: one atomic per subgroup
                // and pair (lavapipe serializes per-lane atomics), and the
                // writes in a loop that runs as often as the most blocks
                // any lane has (a masked write costs as much as a real one).
                uint entries = uint(bitCount(unsure_blocks));
                listed += entries;
                uint total = subgroupAdd(entries);
                uint first = 0u;
                if (subgroupElect() && total != 0u) {
                    first = atomicAdd(unsure_counts[segment * UNSURE_COUNT_STRIDE], total);
                }
                uint e = subgroupBroadcastFirst(first) + subgroupExclusiveAdd(entries);
                while (unsure_blocks != 0u) {
                    uint k = uint(findLSB(unsure_blocks));
                    unsure_blocks &= unsure_blocks - 1u;
                    uvec4 picked = unsure0;
                    FOR_BLOCKS(PICK_UNSURE)
                    if (e < pc.soft.x) {
                        uint at = segment * pc.soft.x + e;
                        unsure_list[2u * at] = uvec4(s, p.ids.x, k, 0u);
                        unsure_list[2u * at + 1u] = picked;
                    }
                    e++;
                }
#elif !EXACT
                uint c0 = plane_code(p.ns, p.d0), c1 = plane_code(p.u0, p.d1);
                uint c2 = plane_code(p.u1, p.d2), c3 = plane_code(p.u2, p.d3);
                FOR_BLOCKS(LUT_BLOCK)
#else
                // The block's light samples by groups (LIGHT_GROUP_SIZE
                // consecutive samples; light.rs orders them in Z-order, so a
                // group is compact): a group whose sphere lies outside one of
                // the four planes by more than the margin has no sample
                // blocked, one inside all four has every sample blocked (not
                // with alpha tests: the crossings' opacity decides), and only
                // the samples of the others are tested, each lane looping over
                // its own groups. The margins hold the per-sample test's
                // rounding and that of the group's own distances, so the
                // masks are those of testing every sample (the twin does).
                // Loop iterations per pair: at most 3 + 8 + 8 + 128 (the
                // first loop, the wedge rule's and the second; groups,
                // candidate groups, their samples or, in the alpha round,
                // the opacity of those the caster hides), so a unit of
                // SOFT_PAIR_CHUNK = 256 pairs stays within lavapipe's 65535
                // per invocation (shadow_common.glsl) at about 38 K.
                uint base = first_block * 128u;
                uint n_block = min(pc.soft.y - min(base, pc.soft.y), 128u);
                uint n_groups = (n_block + LIGHT_GROUP_SIZE - 1u) / LIGHT_GROUP_SIZE;
                float delta_a = rounding_bound(p.a, o, inv_r);
                float margin_a = 2.0 * (delta_a + sphere_allowance(p.a - o, inv_r));
                uvec4 bits = uvec4(0u);
                uint candidates = 0u;
                for (uint g = 0u; g < n_groups; g++) {
                    vec4 sphere = light_groups[first_block * LIGHT_GROUPS_PER_BLOCK + g];
                    vec3 gy = (sphere.xyz - o) * inv_r;
                    float rho = sphere.w * inv_r;
                    // Each plane's distance of the group's centre past it
                    // (behind: below zero), in light radii.
                    float t0 = dot(p.ns, gy) - p.d0, t1 = dot(p.u0, gy) - p.d1;
                    float t2 = dot(p.u1, gy) - p.d2, t3 = dot(p.u2, gy) - p.d3;
                    float ra = rho + margin_a, rx = rho + margin_x;
                    bool none = t0 >= ra || t1 >= rx || t2 >= rx || t3 >= rx;
                    bool every = ALPHA == 0u && t0 < -ra && t1 < -rx && t2 < -rx && t3 < -rx;
                    uint first = g * LIGHT_GROUP_SIZE;
                    uint group_bits = every ? (existing_samples(base + first) & (0xffffffffu >> (32u - LIGHT_GROUP_SIZE))) << (first & 31u) : 0u;
                    bits |= in_word(first >> 5u, group_bits);
                    candidates |= none || every ? 0u : 1u << g;
                    groups_every += every ? 1u : 0u;
                }
                groups_tested += uint(bitCount(candidates));
                while (candidates != 0u) {
                    uint g = uint(findLSB(candidates));
                    candidates &= candidates - 1u;
                    uint first = g * LIGHT_GROUP_SIZE;
                    uint group_bits = 0u;
                    if (ALPHA != 0u) {
                        // The group's samples unrolled (no loop iterations),
                        // then the opacity at the crossing only for those
                        // the triangle blocks, in a loop over them: lavapipe
                        // runs an `if` for every lane, and the opacity's
                        // texture look-ups for every sample cost TransmissionTest's
                        // exact frames 29 s. The loops stay within the bound
                        // of SOFT_PAIR_CHUNK's (16 iterations per group).
                        FOR_GROUP_SAMPLES(GROUP_SAMPLE)
                        // Samples blocked already (an earlier caster, or the
                        // opaque round) need no look-up.
                        uint wd = first >> 5u;
                        uint done = wd == 0u ? acc0.x : (wd == 1u ? acc0.y : (wd == 2u ? acc0.z : acc0.w));
                        uint left = group_bits & ~done;
                        group_bits = 0u;
                        uint word_first = base + (first & ~31u);
                        while (left != 0u) {
                            uint bit = uint(findLSB(left));
                            left &= left - 1u;
                            vec3 l = texelFetch(light_samples_tb, int(word_first + bit)).xyz;
                            vec2 bc = segment_barycentrics(x, l - x, p.a, p.b, p.c);
                            bool opaque = alpha_opaque_at(alpha_records, alpha_textures, alpha_texels, p.alpha_record, bc);
                            group_bits |= opaque ? 1u << bit : 0u;
                        }
                    } else {
                        for (uint jl = first; jl < min(first + LIGHT_GROUP_SIZE, n_block); jl++) {
                            vec3 l = texelFetch(light_samples_tb, int(base + jl)).xyz;
                            bool blocked = exact_blocks(l, p.n, p.sigma, p.a, x, p.m0, p.m1, p.m2, p.se);
                            group_bits |= blocked ? 1u << (jl & 31u) : 0u;
                        }
                    }
                    bits |= in_word(first >> 5u, group_bits);
                }
                acc0 |= bits;
                hit = bits != uvec4(0u);
#endif
                if (hit) {
                    blocking++;
                    uvec4 all_blocks = uvec4(0xffffffffu);
                    FOR_BLOCKS(AND_BLOCK)
                    // Every light sample is blocked: nothing left to find.
                    full = all(equal(all_blocks, uvec4(0xffffffffu)));
                }
            }
#if SURE
            // The lanes that left the loop early did not count the
            // iterations after they left; the last lane to leave counted
            // them all (lanes converge here).
            in_place_left = subgroupMin(in_place_left);
#endif
        }
        if (un.has_sample) {
            FOR_BLOCKS(FLUSH_BLOCK)
        }
    }
#if SURE
    uint sum_listed = subgroupAdd(listed);
    if (subgroupElect() && sum_listed != 0u && un.exists) {
        atomicAdd(unsure_counts[UNSURE_SEGMENTS * UNSURE_COUNT_STRIDE + un.index], sum_listed);
    }
#endif
    uint plane_rejected = tests >> 16;
    tests &= 0xffffu;
    uint sum_tests = subgroupAdd(tests);
    uint sum_blocking = subgroupAdd(blocking);
    uint sum_unsure = subgroupAdd(unsure_bits);
    uint sum_dropped = subgroupAdd(chunk_dropped);
    uint sum_penumbra = subgroupAdd(chunk_penumbra);
    uint sum_plane = subgroupAdd(plane_rejected);
    uint sum_past = subgroupAdd(past_sphere);
    uint sum_visits = subgroupBallotBitCount(subgroupBallot(un.has_sample));
    if (subgroupElect() && sum_visits != 0u) {
        atomicAdd(counters[COUNTER_SAMPLE_VISITS], sum_visits);
    }
    uint sum_beyond_chunk = subgroupAdd(chunk_beyond);
    uint sum_groups = subgroupAdd(chunk_groups);
    uint sum_beyond = subgroupAdd(beyond_tests);
    if (subgroupElect() && sum_dropped != 0u) {
        atomicAdd(counters[COUNTER_CLUSTER_CHUNK], sum_dropped);
        atomicAdd(counters[COUNTER_CLUSTER_OUTSIDE_PENUMBRA], sum_penumbra);
        atomicAdd(counters[COUNTER_CLUSTER_BEYOND_REACH], sum_beyond_chunk);
        atomicAdd(counters[COUNTER_CLUSTER_GROUPS], sum_groups);
    }
    if (subgroupElect() && sum_beyond != 0u) {
        atomicAdd(counters[COUNTER_BEYOND_REACH], sum_beyond);
    }
    uint sum_hull = subgroupAdd(hull_tests);
    if (subgroupElect() && sum_hull != 0u) {
        atomicAdd(counters[COUNTER_OUTSIDE_HULL], sum_hull);
    }
#if WEDGE_COMPILED
    uint sum_wedge = subgroupAdd(wedge_rejected);
    if (subgroupElect() && sum_wedge != 0u) {
        atomicAdd(counters[COUNTER_WEDGE_REJECTED], sum_wedge);
    }
#endif
    if (subgroupElect() && (sum_tests | sum_blocking | sum_unsure) != 0u) {
        atomicAdd(counters[COUNTER_TESTS], sum_tests);
        atomicAdd(counters[COUNTER_BLOCKING], sum_blocking);
        atomicAdd(counters[COUNTER_PLANE_REJECTED], sum_plane);
        atomicAdd(counters[COUNTER_PAST_SPHERE], sum_past);
        count_wide(COUNTER_UNSURE_LO, sum_unsure);
    }
#if EXACT
    uint sum_groups_tested = subgroupAdd(groups_tested);
    uint sum_groups_every = subgroupAdd(groups_every);
    if (subgroupElect() && (sum_groups_tested | sum_groups_every) != 0u) {
        count_wide(COUNTER_GROUPS_TESTED_LO, sum_groups_tested);
        count_wide(COUNTER_GROUPS_EVERY_LO, sum_groups_every);
    }
#endif
}
