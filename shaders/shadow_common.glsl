// Shared by every shadow pass of a light, hard and soft (light_view_*,
// texel_lists_*, casters_*, tile_bin*, occlusion, soft_occlusion, resolve_*). Structs are arrays of vec4 /
// uvec4 so std430 and the #[repr(C)] twins in src/gpu/shared.rs agree.
// Every function mirrors one in src/cpu/ (light_view.rs, casters.rs,
// occlusion.rs), in the same f32 arithmetic.
#ifndef AFS_SHADOW_COMMON_GLSL
#define AFS_SHADOW_COMMON_GLSL
#include "common.glsl"

#define NOT_LISTED 0xffffffffu
// Workgroup size of the 1D hard-shadow passes (WG in src/gpu/dispatch.rs).
#define WORKGROUP_1D 64
#define TILE 8u
// Occlusion work units: one workgroup per (tile, chunk of OCC_PAIR_CHUNK
// pairs, chunk of OCC_SAMPLE_CHUNK list entries). lavapipe (llvmpipe) ends
// every loop of a subgroup (one SIMD vector, whose loops run as long as
// their busiest lane) silently once all its loops together have run 65535
// iterations (LP_MAX_TGSI_LOOP_ITERATIONS), so each invocation's work is
// bounded per loop iteration, which bounds the busiest lane's too:
// occlusion.comp runs at most OCC_PAIR_CHUNK * (OCC_SAMPLE_CHUNK
// + 2) + OCC_PAIR_CHUNK / PAIR_WINDOW + OCC_SAMPLE_CHUNK iterations (a
// loop over each window's pairs, then the list for each pair that touches
// the texel, and in the alpha round the opacity of the entries it hides;
// last, the shadowed entries' writes), OCC_SAMPLE_CHUNK more per pair in
// the alpha round.
// Specialization constants: the soft exact mode loops over 128 light
// samples per test, so its chunks are smaller. Hard shadows take this
// default: 256 pairs (at most 256 * 66 + 40 = 16,936 iterations in the
// alpha round), against 64 before, cut hard occlusion by 4-7% (ToyCar on a
// ground 45.8 -> 42.5 ms, torus_knot:100000 26.1 -> 24.6, TransmissionTest
// 29.9 -> 28.6; 512 did no better): fewer units, and lavapipe runs a
// unit's code outside loops for every SIMD vector.
layout(constant_id = 2) const uint OCC_PAIR_CHUNK = 256u;
// The occlusion passes take their pairs in windows of PAIR_WINDOW, in two
// loops: the cheap rules for every pair of the window, which leave a
// bitmask of the pairs that pass, then the expensive work for those only
// (a findLSB loop over the mask; exact soft occlusion first narrows the
// mask by the wedge rule in a findLSB loop of its own). On
// lavapipe a lane's `continue` or `if` only masks it, so a loop body costs
// its whole length whenever any lane of the subgroup runs it; only a
// loop's trip count saves time. Most (sample, pair) combinations fail the
// cheap rules.
#define PAIR_WINDOW 32u
// 32: occlusion.comp keeps a chunk's shadowed entries in one uint.
layout(constant_id = 3) const uint OCC_SAMPLE_CHUNK = 32u;
#define TEXEL_MARGIN 0.01
// Rounding of projected coordinates that the texel margins absorb, in ulps
// of their magnitude (casters_common.glsl: face_scale, texel_margin).
#define ROUNDING_ULPS 32.0
// GpuTriangle flags bit: the triangle belongs to a closed mesh.
#define TRIANGLE_CLOSED 4u

// Counter slots (HardCounters buffer).
#define COUNTER_PAIRS 0
#define COUNTER_DEGENERATE 1
#define COUNTER_FRONT_FACING_CLOSED 2
#define COUNTER_CULLED 3
#define COUNTER_RASTERIZED 4
#define COUNTER_TEXELS_VISITED 5
#define COUNTER_TESTS 6
#define COUNTER_CLIP_ITEMS 7
// Soft occlusion: (view sample, caster) tests that blocked >= 1 light sample.
#define COUNTER_BLOCKING 8
// Soft occlusion, look-up mode: light-sample bits the table left unsure,
// tested one by one (a 64-bit sum: low and high word).
#define COUNTER_UNSURE_LO 9
#define COUNTER_UNSURE_HI 10
// Soft occlusion: tests rejected by the caster's own plane (the whole
// light's bounding sphere on the sample's side of it).
#define COUNTER_PLANE_REJECTED 11
// Tile binning: (pair, tile) bins that a tile's view-sample box dropped,
// per rule (clusters_common.glsl).
#define COUNTER_CLUSTER_LIGHT_SIDE 12
#define COUNTER_CLUSTER_BEHIND_CLOSED 13
// Soft occlusion: (pair, chunk of 64 samples) visits that the chunk's own
// box or texels ruled out (soft_occlusion.comp, kept_pairs).
#define COUNTER_CLUSTER_CHUNK 14
// Soft occlusion: of those, the visits whose chunk's box lies outside the
// caster's penumbra volume (clusters_common.glsl: chunk_rule).
#define COUNTER_CLUSTER_OUTSIDE_PENUMBRA 15
// Soft occlusion: tests past the bounding-sphere tests of all four planes
// and the wedge rule, which went on to the look-ups or the per-light-sample
// tests (the rest of the tests were rejected by an edge's plane or by the
// wedge rule).
#define COUNTER_PAST_SPHERE 16
// Exact soft occlusion, 64-bit sums in two words each: light-sample groups
// (soft_common.glsl, LIGHT_GROUP_SIZE) whose samples were tested one by
// one, and groups wholly blocked without a per-sample test (the rest were
// wholly outside one of the pair's planes).
#define COUNTER_GROUPS_TESTED_LO 17
#define COUNTER_GROUPS_TESTED_HI 18
#define COUNTER_GROUPS_EVERY_LO 19
#define COUNTER_GROUPS_EVERY_HI 20
// Soft occlusion: tests that passed the four planes' sphere tests and
// that the wedge rule (soft_occlusion.comp: wedges_miss_light) rejected
// (exact mode only).
#define COUNTER_WEDGE_REJECTED 21
// Soft occlusion: (view sample, work unit) visits, once per block pass in
// exact mode. It does not depend on the order of the lists' atomics (the
// tests and the chunks' counts do), so a frame counts the same every run.
#define COUNTER_SAMPLE_VISITS 22
// Soft occlusion, the reach rule (clusters_common.glsl): (view sample,
// pair) visits culled before the test, and (pair, chunk) visits that a
// chunk's box dropped (of COUNTER_CLUSTER_CHUNK's).
#define COUNTER_BEYOND_REACH 23
#define COUNTER_CLUSTER_BEYOND_REACH 24
// Soft occlusion, the hull rule (clusters_common.glsl): (view sample,
// pair) visits culled before the test, or left out for a whole subgroup.
#define COUNTER_OUTSIDE_HULL 25
// Tile binning, soft shadows: (pair, tile) bins that the tile's box
// dropped by the reach rule and by the hull rule (clusters_common.glsl:
// bin_rule).
#define COUNTER_BIN_BEYOND_REACH 26
#define COUNTER_BIN_OUTSIDE_HULL 27
// Caster setup, soft shadows: the pairs listed as large (large_pair).
#define COUNTER_LARGE_PAIRS 28
// Soft occlusion: of COUNTER_CLUSTER_CHUNK's visits, those that the groups'
// boxes dropped (pair_groups.comp) before the chunk's own tests.
#define COUNTER_CLUSTER_GROUPS 29
#define COUNTER_COUNT 30

// Soft pairs whose rectangle spans more tiles than this are large: tile
// binning tests them against blocks of tiles first (tile_bin.comp,
// BY_BLOCKS), and caster setup lists them apart, so that binning's
// pipeline for them runs with every lane on one (they are a few in a
// hundred on a car, a quarter on a torus knot).
#define CLUSTER_BLOCK_PAIR_TILES 64u
bool large_pair(uvec2 rmin, uvec2 rmax) {
    uvec2 span = rmax / TILE - rmin / TILE + 1u;
    return span.x * span.y > CLUSTER_BLOCK_PAIR_TILES;
}

// Frame-wide parameters (push constants).
struct LightPush {
    vec4 origin;       // xyz: light position (point) or 0 (directional); w: LIGHT_KIND_* bits
    vec4 direction;    // xyz: directional light's travel direction
    uvec4 sizes;       // x: view samples, y: triangles, z: resolution, w: face count
    uvec4 more;        // x: pair capacity, y: tiles per row, z: tiles per face, w: occlusion units
    vec4 dir_right;    // directional light's face basis: right
    vec4 dir_up;       // and up (forward = direction); w: the casters of this run (caster_in_class)
    uvec4 soft;        // x: 128-sample block (exact mode) or the unsure list's capacity (look-up mode),
                       // y: light samples (0: hard shadows), z: LUT resolution,
                       // w: soft occlusion, look-up mode: the dispatch's first work unit
    vec4 soft_light;   // x: light bounding radius R (light samples within R of origin), y: influence polygon degree,
                       // z: global id of this run's triangle 0 (uint bits; triangle batches),
                       // w: look-up mode's largest rounding allowance LUT_ALLOWANCE_CAP, in light radii (soft_occlusion.comp)
};

// One light face: basis and fitted window (written by light_view_finalize).
struct LightFace {
    vec4 right;   // xyz; w: 1 when the face has samples
    vec4 up;
    vec4 forward;
    vec4 window;  // x0, y0, sx (texels per unit), sy
    vec4 far;     // x: depth of the farthest sample
    vec4 pad0;
    vec4 pad1;
    vec4 pad2;
};

// A caster's planes: blocked <=> dot(support, p) + w < 0 on the camera-relative p
// and every dot(edge_k, q) + w > 0 on q = p - origin.
// Edge planes are computed from the edge's endpoints in a canonical order,
// so the two triangles sharing an edge get exactly negated planes; `side`
// (+1/-1) orients each, and a point exactly on the plane (value 0) is inside
// for the +1 side only: a ray through a shared edge is claimed by exactly one
// of the two triangles (watertight, like the oracle's test).
struct CasterPlanes {
    vec4 support;
    vec4 edge0;
    vec4 edge1;
    vec4 edge2;
    vec4 side;    // xyz: +1 or -1 per edge
};

// The planes of a triangle that casts nothing (all zero).
CasterPlanes no_planes() {
    return CasterPlanes(vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
}

bool inside_edge(vec4 e, float side, vec3 q) {
    float v = dot(e.xyz, q) + e.w;
    return side > 0.0 ? v >= 0.0 : v < 0.0;
}

// One (caster, face) pair to rasterize.
// Hard pairs: e0..e2 hold the texel-space edges (or none: e0.w = 0).
// Soft pairs carry no edges but their triangle's vertices (GpuTriangle's
// xyz, bit for bit), e0.w = 0, e1.w the TRIANGLE_* flags' bits, e2.w the
// alpha record's (soft_pair_triangle): binning and occlusion then read a
// pair and its caster from one 64-byte record instead of two places at
// random (ToyCar's chunk rules alone: 336 -> 312 ms, a variant).
struct CasterFace {
    uvec4 ids;    // x: triangle, y: face, z: rect min (x | y << 16), w: rect max
    vec4 e0;      // texel-space edge a, b, c; w: the x margin (> 0) when edges are valid
    vec4 e1;      // w: the y margin
    vec4 e2;
};

// A soft pair's caster as GpuTriangle's three texels (its mesh id left
// 0), from the pair's CasterFace texels e0..e2.
void soft_pair_triangle(uvec4 e0, uvec4 e1, uvec4 e2, out uvec4 t0, out uvec4 t1, out uvec4 t2) {
    t0 = uvec4(e0.xyz, e1.w);
    t1 = uvec4(e1.xyz, 0u);
    t2 = e2;
}

// A pair's texel rectangle (CasterFace.ids z and w): its min and max corners.
uvec2 pair_rect_min(uvec4 ids) { return uvec2(ids.z & 0xffffu, ids.z >> 16); }
uvec2 pair_rect_max(uvec4 ids) { return uvec2(ids.w & 0xffffu, ids.w >> 16); }

// Whether a pair's texel rectangle shares a texel with [tmin, tmax].
bool pair_meets(uvec4 ids, uvec2 tmin, uvec2 tmax) {
    return !(any(lessThan(tmax, pair_rect_min(ids))) || any(greaterThan(tmin, pair_rect_max(ids))));
}

// Bits 0 .. n - 1 (n <= 32): the lanes of a ballot's first n.
uint first_bits(uint n) { return n >= 32u ? 0xffffffffu : (1u << n) - 1u; }

layout(push_constant) uniform Push { LightPush pc; };
// The global id of this run's triangle i: view samples name their own triangle globally.
uint global_triangle(uint i) { return i + floatBitsToUint(pc.soft_light.z); }

// Which casters a run's passes take (LightPush.dir_up.w, a float): 0 every
// triangle, 1 the opaque ones, 2 the alpha-tested ones (the second round of
// a light's passes, with the alpha tests: light_passes.rs).
bool caster_in_class(uint flags) {
    float c = pc.dir_up.w;
    bool casts = (flags & TRIANGLE_INVISIBLE) == 0u;
    return casts && (c == 0.0 || (c == 2.0) == ((flags & TRIANGLE_ALPHA) != 0u));
}

// Soft shadows: the light is the bounding sphere (origin, R) of its samples.
bool is_soft() { return pc.soft.y != 0u; }

// This workgroup's index in a dispatch of x by y workgroups (x fastest,
// as groups_2d lays them out and lavapipe numbers them).
uint workgroup_index() {
    return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
}

uint linear_invocation() {
    return workgroup_index() * WORKGROUP_1D + gl_LocalInvocationID.x;
}

// Lavapipe hands each of its T threads one contiguous run of a
// dispatch's n workgroups (Mesa's lp_cs_tpool: n / T each, the remainder
// one by one), so where the work is uneven along the index (a scene's busy
// tiles, caster pairs of large regions next to each other) one thread gets
// most of it and the others wait. The dispatches whose work is uneven
// number their workgroups through spread_index instead: thread t's run
// takes indices t, t + T, t + 2T, ..., so every thread walks the whole
// range (and they walk it together, which keeps neighbouring work in the
// shared cache; 64 interleaved runs per thread were measured slower).
// SPREAD_THREADS is T (vulkan::DeviceInfo::dispatch_runs; 1, the identity,
// on a GPU), set for every pipeline (vulkan::pipeline). A bijection on
// [0, n). Twin: gpu::dispatch::spread_index.
layout(constant_id = 9) const uint SPREAD_THREADS = 1u;
uint spread_index(uint w, uint n) {
    uint run = max(n / SPREAD_THREADS, 1u);
    uint b = (w % run) * SPREAD_THREADS + w / run;
    return w < run * SPREAD_THREADS ? b : w;
}

// This workgroup's index (workgroup_index), spread (spread_index).
uint spread_workgroup() {
    return spread_index(workgroup_index(), gl_NumWorkGroups.x * gl_NumWorkGroups.y);
}

bool is_point_light() { return floatBitsToUint(pc.origin.w) == LIGHT_KIND_POINT; }

// Point-light cube faces: forward, right, up (src/cpu/light_view.rs).
void point_face_basis(uint f, out vec3 r, out vec3 u, out vec3 w) {
    w = f == 0u ? vec3(1, 0, 0) : f == 1u ? vec3(-1, 0, 0) : f == 2u ? vec3(0, 1, 0)
      : f == 3u ? vec3(0, -1, 0) : f == 4u ? vec3(0, 0, 1) : vec3(0, 0, -1);
    r = f <= 1u ? vec3(0, 0, 1) : vec3(1, 0, 0);
    u = (f == 2u || f == 3u) ? vec3(0, 0, 1) : vec3(0, 1, 0);
}

bool faces_light(vec3 p, vec3 n) {
    if (is_soft()) {
        // Some light sample may be in front of the surface.
        return dot(n, pc.origin.xyz - p) > -pc.soft_light.x * length(n);
    }
    return is_point_light() ? dot(n, pc.origin.xyz - p) > 0.0 : dot(n, -pc.direction.xyz) > 0.0;
}

// Soft shadows: every light sample l passes dot(n, l - p) > 0 as f32
// computes it: the light's bounding sphere (origin, R) is in front of the
// surface by more than that test's rounding (~1e-6 of |n| (|origin - p| + R)).
bool faces_whole_light(vec3 p, vec3 n) {
    vec3 to_centre = pc.origin.xyz - p;
    float r = pc.soft_light.x;
    return dot(n, to_centre) > length(n) * (r + 1e-5 * (length(to_centre) + r));
}

// The basis of face f (right, up, forward).
void face_basis(uint f, out vec3 r, out vec3 u, out vec3 w) {
    if (is_point_light()) {
        point_face_basis(f, r, u, w);
    } else {
        r = pc.dir_right.xyz;
        u = pc.dir_up.xyz;
        w = pc.direction.xyz;
    }
}

// Face and projected (x, y, depth) of camera-relative p; false at the light.
bool project_to_face(vec3 p, out uint f, out vec3 xyz) {
    if (!is_point_light()) {
        f = 0u;
        xyz = vec3(dot(p, pc.dir_right.xyz), dot(p, pc.dir_up.xyz), dot(p, pc.direction.xyz));
        return true;
    }
    vec3 d = p - pc.origin.xyz;
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) {
        f = d.x >= 0.0 ? 0u : 1u;
    } else if (a.y >= a.z) {
        f = d.y >= 0.0 ? 2u : 3u;
    } else {
        f = d.z >= 0.0 ? 4u : 5u;
    }
    vec3 r, u, w;
    point_face_basis(f, r, u, w);
    float z = dot(d, w);
    if (!(z > 0.0) || isinf(z)) {
        return false;
    }
    xyz = vec3(dot(d, r) / z, dot(d, u) / z, z);
    return true;
}

// Order-preserving float <-> uint keys for atomic min/max.
uint float_key(float f) {
    uint b = floatBitsToUint(f);
    return (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
}
float key_float(uint k) {
    return uintBitsToFloat((k & 0x80000000u) != 0u ? (k & 0x7fffffffu) : ~k);
}

// A texel's place in its tile's lists: Z order (x's bits at the even
// places, y's at the odd), so that consecutive texels form compact
// blocks (occlusion's chunks of samples cover a small texel rectangle).
// (TILE is 8: three bits of each; gpu::light_frame checks it.)
uint in_tile_index(uvec2 t) {
    return (t.x & 1u) | ((t.y & 1u) << 1) | ((t.x & 2u) << 1) | ((t.y & 2u) << 2) | ((t.x & 4u) << 2) | ((t.y & 4u) << 3);
}
// Its inverse: the texel (in its tile) at place i.
uvec2 in_tile_texel(uint i) {
    return uvec2((i & 1u) | ((i >> 1) & 2u) | ((i >> 2) & 4u), ((i >> 1) & 1u) | ((i >> 2) & 2u) | ((i >> 3) & 4u));
}

// A texel's list index: tile-major (64 texels per tile, Z order inside, in_tile_index),
// so that one tile's samples are contiguous in the lists and the soft
// occlusion can give each lane one sample. pc.more: y tiles per row, z
// tiles per face.
uint texel_index(uint face, uvec2 t) {
    uvec2 tile = t / TILE;
    return (face * pc.more.z + tile.y * pc.more.y + tile.x) * TILE * TILE + in_tile_index(t % TILE);
}

// Which tiles hold view samples, after the per-tile longest list lengths
// in the same buffer (texel_lists_count.comp writes both): per face and
// row of tiles, one bit per tile in words of 32, so that binning visits
// only occupied tiles (a loop's length is what lavapipe saves; 39-45% of
// the tiles under ToyCar's, the hairball's and torus_knot:100000's
// influence regions held none). LightFrame::tile_words sizes the buffer.
uint occupancy_words_per_row() {
    return (pc.more.y + 31u) / 32u;
}
uint occupancy_word(uint face, uint row, uint word) {
    return pc.more.z * pc.sizes.w + (face * pc.more.y + row) * occupancy_words_per_row() + word;
}

// The texel of a projected point, clamped to the map (cpu::light_view::texel_of).
uvec2 texel_of(vec4 window, float x, float y, uint resolution) {
    float m = float(resolution) - 1.0;
    float tx = clamp(floor((x - window.x) * window.z), 0.0, m);
    float ty = clamp(floor((y - window.y) * window.w), 0.0, m);
    return uvec2(tx, ty);
}

// Conservative overlap of a texel-space square with a triangle's edges
// (cpu::casters::square_overlaps); `margin`: the pair's texel margin.
bool square_overlaps(vec3 e0, vec3 e1, vec3 e2, vec2 margin, vec2 lo, vec2 hi) {
    vec2 c = 0.5 * (lo + hi);
    vec2 h = 0.5 * (hi - lo) + margin;
    return e0.x * c.x + e0.y * c.y + e0.z + abs(e0.x) * h.x + abs(e0.y) * h.y >= 0.0
        && e1.x * c.x + e1.y * c.y + e1.z + abs(e1.x) * h.x + abs(e1.y) * h.y >= 0.0
        && e2.x * c.x + e2.y * c.y + e2.z + abs(e2.x) * h.x + abs(e2.y) * h.y >= 0.0;
}

#endif
