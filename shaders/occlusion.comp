#version 450
// One workgroup per work unit (a tile, a chunk of OCC_PAIR_CHUNK
// of its pairs and a chunk of OCC_SAMPLE_CHUNK list entries; see tile_bin_units),
// one invocation per light texel of the tile. For every pair of the chunk
// whose projection may touch the texel, every view sample of the texel's
// list chunk is tested against the caster's planes; a hit sets the sample's
// shadow flag (the OR of paper §3.3). The chunks bound every invocation's
// loop iterations below lavapipe's per-invocation limit (shadow_common.glsl).
// Twin: cpu::occlusion::occlusion.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_shuffle : require
#include "shadow_common.glsl"
#include "alpha_common.glsl"
layout(local_size_x = 64) in;
// 1: the alpha-tested casters' round: a hit counts where the caster is
// opaque at the segment's crossing (alpha_common.glsl).
layout(constant_id = 5) const uint ALPHA = 0u;

// The hot gathers come from texel buffers (RGBA32UI / R32UI views): on
// lavapipe a texel fetch is ~10x faster than a storage-buffer load
// (shared/notes/lavapipe.md); floats travel as bits, so nothing is flushed.
layout(set = 0, binding = 0) uniform usamplerBuffer pairs_tb;   // CasterFace: 4 texels
layout(set = 0, binding = 1) uniform usamplerBuffer planes_tb;  // CasterPlanes: 5 texels
layout(set = 0, binding = 2) readonly buffer TileOffsets { uint tile_offsets[]; };
layout(set = 0, binding = 3) uniform usamplerBuffer tile_pairs_tb;
layout(set = 0, binding = 4) readonly buffer Counts { uint counts[]; };
layout(set = 0, binding = 5) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 6) uniform usamplerBuffer list_samples_tb; // xyz float bits, w triangle id
layout(set = 0, binding = 7) buffer Shadowed { uint shadowed[]; };
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };
layout(set = 0, binding = 9) readonly buffer UnitOffsets { uint unit_offsets[]; };
layout(set = 0, binding = 10) uniform usamplerBuffer triangles_tb;    // GpuTriangle: 3 texels
layout(set = 0, binding = 11) uniform usamplerBuffer alpha_records;
layout(set = 0, binding = 12) uniform usamplerBuffer alpha_textures;
layout(set = 0, binding = 13) uniform usamplerBuffer alpha_texels;

void main() {
    uint unit = spread_workgroup();
    uint tiles_per_face = pc.more.z;
    uint res = pc.sizes.z;
    // more.w: the units the host read back, or ~0 when a caller's command
    // buffer dispatches them indirectly (record_args.comp): then the count
    // is the scan's total.
    if (unit >= min(pc.more.w, unit_offsets[tiles_per_face * pc.sizes.w])) {
        return;
    }
    // The tile: the last one whose first unit is at most `unit` (the
    // offsets hold tiles + 1 non-decreasing values).
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
    uint tests = 0u, visited = 0u;
    // The lane's shadowed list entries (bit s - list_begin; OCC_SAMPLE_CHUNK
    // is 32), written once at the end: on lavapipe a storage write costs a
    // loop over the lanes whether or not they write, so one inside the
    // sample loop cost every (pair, sample) test.
    uint hits = 0u;
    // Every lane of the unit runs the window loop (its first loop's
    // shuffles need the whole subgroup); lanes without samples find no
    // pair touching.
    bool in_tile = texel.x < res && texel.y < res && begin != end;
    uint t = in_tile ? texel_index(face, texel) : 0u;
    uint count = in_tile ? counts[t] : 0u;
    uint list_first = in_tile ? offsets[t] : 0u;
    uint list_begin = list_first + min(count, sample_chunk * OCC_SAMPLE_CHUNK);
    uint list_end = list_first + min(count, (sample_chunk + 1u) * OCC_SAMPLE_CHUNK);
    {
        // Per window (PAIR_WINDOW, shadow_common.glsl): which pairs'
        // projections may touch the texel, then the list against those
        // only. A subgroup whose lanes have no samples stops at once.
        bool has_list = list_begin != list_end;
        vec2 lo = vec2(texel), hi = lo + 1.0;
        // The rectangle of the subgroup's texels with lists.
        uvec2 sg_tmin = subgroupMin(has_list ? texel : uvec2(0xffffu));
        uvec2 sg_tmax = subgroupMax(has_list ? texel : uvec2(0u));
        for (uint w0 = begin; w0 < end; w0 += PAIR_WINDOW) {
            if (subgroupBallotBitCount(subgroupBallot(has_list)) == 0u) {
                break;
            }
            uint window = min(PAIR_WINDOW, end - w0);
            uint touching = 0u;
            // The first loop's pairs are the same for every lane: lane k
            // fetches pair j0 + k of each `group` and the others take it
            // by a shuffle (on lavapipe a gather costs a load per lane).
            uint group = min(gl_SubgroupSize, PAIR_WINDOW);
            for (uint j0 = 0u; j0 < window; j0 += group) {
                uint pk = texelFetch(tile_pairs_tb, int(w0 + min(j0 + gl_SubgroupInvocationID % group, window - 1u))).x;
                uvec4 ids_k = texelFetch(pairs_tb, int(4u * pk));
                uvec4 e0_k = texelFetch(pairs_tb, int(4u * pk + 1u));
                uvec4 e1_k = texelFetch(pairs_tb, int(4u * pk + 2u));
                uvec4 e2_k = texelFetch(pairs_tb, int(4u * pk + 3u));
                // The pairs whose rectangle meets the subgroup's texels
                // with lists (one ballot); the others no lane touches.
                uint meeting = subgroupBallot(pair_meets(ids_k, sg_tmin, sg_tmax)).x
                    & first_bits(min(group, window - j0));
                while (meeting != 0u) {
                    uint lane = uint(findLSB(meeting));
                    meeting &= meeting - 1u;
                    uint j = j0 + lane;
                    CasterFace cf;
                    cf.ids = subgroupShuffle(ids_k, lane);
                    cf.e0 = uintBitsToFloat(subgroupShuffle(e0_k, lane));
                    cf.e1 = uintBitsToFloat(subgroupShuffle(e1_k, lane));
                    cf.e2 = uintBitsToFloat(subgroupShuffle(e2_k, lane));
                    bool touches = has_list && pair_meets(cf.ids, texel, texel)
                        && (cf.e0.w == 0.0 || square_overlaps(cf.e0.xyz, cf.e1.xyz, cf.e2.xyz, vec2(cf.e0.w, cf.e1.w), lo, hi));
                    touching |= touches ? 1u << j : 0u;
                }
            }
            while (touching != 0u) {
                uint j = uint(findLSB(touching));
                touching &= touching - 1u;
                uint pi = texelFetch(tile_pairs_tb, int(w0 + j)).x;
                uint caster = texelFetch(pairs_tb, int(4u * pi)).x;
                if (sample_chunk == 0u) {
                    visited++; // once per (pair, texel), not per list chunk
                }
                uint pl = 5u * caster;
                CasterPlanes cp;
                cp.support = uintBitsToFloat(texelFetch(planes_tb, int(pl)));
                cp.edge0 = uintBitsToFloat(texelFetch(planes_tb, int(pl + 1u)));
                cp.edge1 = uintBitsToFloat(texelFetch(planes_tb, int(pl + 2u)));
                cp.edge2 = uintBitsToFloat(texelFetch(planes_tb, int(pl + 3u)));
                cp.side = uintBitsToFloat(texelFetch(planes_tb, int(pl + 4u)));
                uint caster_hits = 0u;
                for (uint s = list_begin; s < list_end; s++) {
                    uvec4 qb = texelFetch(list_samples_tb, int(s));
                    vec4 qs = vec4(uintBitsToFloat(qb.xyz), 0.0);
                    if (qb.w == global_triangle(caster)) {
                        continue; // never onto a sample of the same triangle
                    }
                    tests++;
                    // Support plane on the camera-relative position, edge
                    // planes on the light-relative one (cpu::casters::CasterPlanes::blocks).
                    vec3 q = qs.xyz - pc.origin.xyz;
                    bool hit = dot(cp.support.xyz, qs.xyz) + cp.support.w < 0.0
                        && inside_edge(cp.edge0, cp.side.x, q)
                        && inside_edge(cp.edge1, cp.side.y, q)
                        && inside_edge(cp.edge2, cp.side.z, q);
                    caster_hits |= hit ? 1u << (s - list_begin) : 0u;
                }
                if (ALPHA != 0u) {
                    // The opacity where the segment to the light crosses the
                    // caster, only for the samples it hides that no earlier
                    // caster did, in a loop of their own (lavapipe runs an
                    // `if` for every lane: its texture look-ups cost more
                    // than the tests). At most OCC_SAMPLE_CHUNK iterations
                    // per pair.
                    uint ti = 3u * caster;
                    vec3 a = uintBitsToFloat(texelFetch(triangles_tb, int(ti)).xyz);
                    vec3 b = uintBitsToFloat(texelFetch(triangles_tb, int(ti + 1u)).xyz);
                    uvec4 c = texelFetch(triangles_tb, int(ti + 2u));
                    uint left = caster_hits & ~hits;
                    caster_hits = 0u;
                    while (left != 0u) {
                        uint bit = uint(findLSB(left));
                        left &= left - 1u;
                        vec3 qs = uintBitsToFloat(texelFetch(list_samples_tb, int(list_begin + bit)).xyz);
                        vec3 d = is_point_light() ? pc.origin.xyz - qs : -pc.direction.xyz;
                        vec2 bc = segment_barycentrics(qs, d, a, b, uintBitsToFloat(c.xyz));
                        caster_hits |= alpha_opaque_at(alpha_records, alpha_textures, alpha_texels, c.w, bc) ? 1u << bit : 0u;
                    }
                }
                hits |= caster_hits;
            }
        }
    }
    while (hits != 0u) {
        uint bit = uint(findLSB(hits));
        hits &= hits - 1u;
        shadowed[list_begin + bit] = 1u;
    }
    uint sum_tests = subgroupAdd(tests);
    uint sum_visited = subgroupAdd(visited);
    if (subgroupElect() && (sum_tests | sum_visited) != 0u) {
        atomicAdd(counters[COUNTER_TESTS], sum_tests);
        atomicAdd(counters[COUNTER_TEXELS_VISITED], sum_visited);
    }
}
