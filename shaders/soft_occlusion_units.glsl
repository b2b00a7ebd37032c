// Occlusion work units (tile_bin_units.comp with SAMPLE_LANES): one workgroup
// per (tile, chunk of OCC_PAIR_CHUNK of its binned pairs, chunk of 64 of its
// listed samples), one invocation per listed sample. The tile's lists are
// contiguous (tile-major texel order, texel_index), so every lane of a
// workgroup has a sample, not only the lanes of occupied texels.
// Include after declaring tile_offsets, offsets and unit_offsets.
#ifndef AFS_OCCLUSION_UNITS_GLSL
#define AFS_OCCLUSION_UNITS_GLSL

// The first unit of this dispatch (a dispatch may run a range of units).
#ifndef OCC_UNIT_BASE
#define OCC_UNIT_BASE 0u
#endif

struct OcclusionUnit {
    uint index;        // this unit's index (OCC_UNIT_BASE and on)
    bool exists;       // index is one of the units (a dispatch may have more groups)
    uint pair_begin;   // this unit's pairs: tile_pairs[pair_begin..pair_end)
    uint pair_end;
    uint slot;         // this invocation's list slot (valid when has_sample)
    bool has_sample;
    bool first_of_texel; // the slot is the first of its texel's list
    uint face;
    uint tile;         // face-major tile index (valid when the unit exists)
    uvec2 texel;
};

OcclusionUnit occlusion_unit() {
    OcclusionUnit u;
    uint unit = spread_workgroup() + OCC_UNIT_BASE;
    uint tiles_per_face = pc.more.z;
    u.index = unit;
    u.exists = false;
    u.has_sample = false;
    u.first_of_texel = false;
    u.pair_begin = 0u;
    u.pair_end = 0u;
    u.slot = 0u;
    u.face = 0u;
    u.tile = 0u;
    u.texel = uvec2(0u);
    // more.w: the units the host read back, or ~0 when a caller's command
    // buffer dispatches them indirectly (record_args.comp).
    if (unit >= min(pc.more.w, unit_offsets[tiles_per_face * pc.sizes.w])) {
        return u;
    }
    u.exists = true;
    // The tile: the last one whose first unit is at most `unit`.
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
    u.tile = tile;
    u.face = tile / tiles_per_face;
    uint in_face = tile % tiles_per_face;
    uvec2 tile_xy = uvec2(in_face % pc.more.y, in_face / pc.more.y);
    uint begin = tile_offsets[tile], end = tile_offsets[tile + 1u];
    uint pair_chunks = (end - begin + OCC_PAIR_CHUNK - 1u) / OCC_PAIR_CHUNK;
    uint local_unit = unit - unit_offsets[tile];
    uint sample_chunk = local_unit / pair_chunks;
    u.pair_begin = begin + (local_unit % pair_chunks) * OCC_PAIR_CHUNK;
    u.pair_end = min(end, u.pair_begin + OCC_PAIR_CHUNK);
    uint first_texel = tile * TILE * TILE;
    uint tile_end = offsets[first_texel + TILE * TILE];
    u.slot = offsets[first_texel] + sample_chunk * 64u + gl_LocalInvocationID.x;
    u.has_sample = u.slot < tile_end && u.pair_begin != u.pair_end;
    if (u.has_sample) {
        // The slot's texel: the last of the tile's 64 whose list starts at or before it.
        uint lo = 0u, hi = TILE * TILE;
        while (hi - lo > 1u) {
            uint mid = (lo + hi) / 2u;
            if (offsets[first_texel + mid] <= u.slot) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        u.texel = tile_xy * TILE + in_tile_texel(lo);
        u.first_of_texel = offsets[first_texel + lo] == u.slot;
    }
    return u;
}

#endif
