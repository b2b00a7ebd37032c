// View-sample clusters (Sintorn et al. 2014, the plane cut of Lehtinen et
// al. 2006): per tile of light texels, the box of its listed samples, and
// the test that a caster cannot block any sample of a box. Both rules are
// the occlusion tests' own early outs, taken for a whole tile with a margin
// far above their rounding, so that a culled pair is one the per-sample
// test would have skipped for every sample: the masks stay bit-identical.
// Twin: cpu::clusters.
#ifndef AFS_CLUSTERS_COMMON_GLSL
#define AFS_CLUSTERS_COMMON_GLSL
#include "shadow_common.glsl"

// Box margins, relative to the magnitudes involved: f32 rounding of the
// per-sample plane tests is ~1e-6 of them.
#define CLUSTER_MARGIN 1e-4
// Tiles with more listed samples than this get no box (no culling): the
// bounds pass loops over a tile's samples in one invocation.
#define CLUSTER_MAX_SAMPLES 16384u

// Blocks of CLUSTER_BLOCK x CLUSTER_BLOCK tiles get a box too (the union
// of their tiles' boxes, after them in the same buffer): binning tests a
// pair against a block's box before its tiles' where the pair's rectangle
// holds at least CLUSTER_BLOCK_MIN_TILES occupied tiles of the block, and
// a block the rules drop drops each of those tiles. (A multiple of 32
// tiles per occupancy word: a block's columns lie in one word.)
#define CLUSTER_BLOCK 4u
#define CLUSTER_BLOCK_MIN_TILES 4u
// Pairs whose rectangle spans more than CLUSTER_BLOCK_PAIR_TILES tiles
// (shadow_common.glsl: large_pair) go by blocks.

// What the rules found (cull_rule).
#define CLUSTER_KEEP 0u
#define CLUSTER_LIGHT_SIDE 1u
#define CLUSTER_BEHIND_CLOSED 2u
#define CLUSTER_OUTSIDE_PENUMBRA 3u
#define CLUSTER_BEYOND_REACH 4u
#define CLUSTER_OUTSIDE_HULL 5u
// 64 f32 ulps: the rounding bound of a per-sample plane test, per unit of
// the magnitudes it involves (as ROUNDING_BOUND in soft_occlusion.comp).
#define CLUSTER_ROUNDING (64.0 * 1.1920929e-7)

// A caster's supporting plane as the rules see it.
struct ClusterPlane {
    vec3 n;      // unit normal of cross(b - a, c - a)
    vec3 a;      // its vertices, camera-relative
    vec3 b;
    vec3 c;
    float area2; // |cross(b - a, c - a)|
    float side;  // the light's side of the plane: +1, -1, or 0 (the light straddles it: no light-side rule)
    bool closed;
    // What the rules recompute for every box otherwise (binning tests a
    // caster against many): cluster_margin's terms that do not depend on
    // the box, and the caster's ball (caster_ball) and its caster_sphere.
    float margin_base;
    vec4 ball;
    vec2 sphere;
};

vec4 caster_ball(vec3 a, vec3 b, vec3 c);
vec2 caster_sphere(vec3 o, vec4 ball);

// The supporting plane of triangle (a, b, c) and the light's side of it
// (the whole light's bounding sphere beyond the margin, or a directional
// light's travel direction clearly not in the plane).
ClusterPlane cluster_plane(vec3 a, vec3 b, vec3 c, bool closed) {
    ClusterPlane cp;
    vec3 n = cross(b - a, c - a);
    float len = length(n);
    cp.n = n / len;
    cp.a = a;
    cp.b = b;
    cp.c = c;
    cp.area2 = len;
    cp.closed = closed;
    cp.side = 0.0;
    float r_light = is_soft() ? pc.soft_light.x : 0.0;
    cp.margin_base = length(a) + length(pc.origin.xyz) + r_light;
    cp.ball = caster_ball(a, b, c);
    cp.sphere = caster_sphere(pc.origin.xyz, cp.ball);
    if (!(len > 0.0) || isinf(len) || any(isnan(cp.n))) {
        cp.n = vec3(0.0);
        cp.closed = false;
        return cp;
    }
    vec3 o = pc.origin.xyz;
    if (is_soft() || is_point_light()) {
        float r = is_soft() ? pc.soft_light.x : 0.0;
        float s = dot(cp.n, o - a);
        float need = r + CLUSTER_MARGIN * (r + length(a) + length(o) + length(a - o));
        cp.side = s >= need ? 1.0 : s <= -need ? -1.0 : 0.0;
    } else {
        float s = -dot(cp.n, pc.direction.xyz) / length(pc.direction.xyz);
        cp.side = s >= CLUSTER_MARGIN ? 1.0 : s <= -CLUSTER_MARGIN ? -1.0 : 0.0;
    }
    return cp;
}

// The ClusterPlane of a triangle given as GpuTriangle's three texels (a
// soft pair's: shadow_common.glsl, soft_pair_triangle).
ClusterPlane triangle_cluster_plane(uvec4 t0, uvec4 t1, uvec4 t2) {
    return cluster_plane(uintBitsToFloat(t0.xyz), uintBitsToFloat(t1.xyz), uintBitsToFloat(t2.xyz),
                         (t0.w & TRIANGLE_CLOSED) != 0u);
}

// 16 f32 ulps: the rounding bound of a cross product or determinant of
// differences that are each rounded once relative to themselves (a - x,
// b - x), per unit of the product of their lengths.
#define CLUSTER_CROSS_ROUNDING (16.0 * 1.1920929e-7)

// The lower and upper bounds of dot(g, x - p) over the box (bc, bh).
vec2 box_range(vec3 g, vec3 p, vec3 bc, vec3 bh) {
    float c = dot(g, bc - p), r = dot(abs(g), bh);
    return vec2(c - r, c + r);
}

// Soft occlusion's early out for edge (p, q) of a caster whose third
// vertex is r, for every point x of the box (bc, bh): whether the plane
// through x and the edge leaves the sphere (o, rr) wholly outside the
// caster's cone from x (bit 0, the planes oriented as they truly are) or
// wholly inside it (bit 1, the three planes' orientation flipped). Seen
// along the edge, that plane is the line through the edge and x: it
// misses the sphere's disk where x is in one of the two wedges between
// the disk's tangents through the edge (planes A and B), and the disk is
// on r's side or not by x's side of the caster's plane (P).
uint edge_rule(vec3 p, vec3 q, vec3 r, vec3 o, float rr, vec3 bc, vec3 bh, float m) {
    vec3 d = q - p;
    float dd = dot(d, d);
    vec3 w = o - p;
    vec3 wp = w - d * (dot(w, d) / dd);
    float h = length(wp);
    // The sphere reaches the edge's line: every plane through it cuts the
    // sphere (decided at the end: see cull_rule).
    bool reaches = !(h > rr) || !(dd > 0.0);
    vec3 e1 = wp / h;
    vec3 e2 = normalize(cross(d, e1));
    float sa = rr / h, ca = sqrt(max(0.0, 1.0 - sa * sa));
    vec3 rp = r - p;
    float ru = dot(rp, e1), rw = dot(rp, e2);
    vec3 g_p = rw * e1 - ru * e2;
    vec2 ra = box_range(ca * e2 - sa * e1, p, bc, bh);
    vec2 rb = box_range(ca * e2 + sa * e1, p, bc, bh);
    vec2 rpl = box_range(g_p, p, bc, bh);
    float mp = m * length(g_p);
    bool upper = ra.x >= m && rb.x >= m, lower = ra.y <= -m && rb.y <= -m;
    bool pos = rpl.x >= mp, neg = rpl.y <= -mp;
    uint outside = (upper && pos) || (lower && neg) ? 1u : 0u;
    uint inside = (upper && neg) || (lower && pos) ? 2u : 0u;
    return reaches ? 0u : outside | inside;
}

// Whether the caster of `cp` blocks no light sample of any point of the
// box (centre bc, half extent bh) by soft occlusion's own early out: one
// edge's plane through x leaves the whole light outside the caster's
// cone from x (edge_rule), for a sphere grown by what that test lets
// through (1e-5 of the radius and of the distance: lo_x) and by its
// rounding. Its plane through x and an edge comes from cross(a - x, b - x)
// and errs in direction by about CLUSTER_CROSS_ROUNDING |a - x| |b - x| /
// (|b - a| times x's distance to the edge's line). The three planes'
// orientation is the sign of det(a - x, b - x, c - x), sure only where
// area2 times x's distance to the caster's plane passes that
// determinant's rounding; elsewhere the box is dropped only when either
// orientation rejects it.
bool outside_penumbra(ClusterPlane cp, vec3 bc, vec3 bh, float m) {
    vec3 o = pc.origin.xyz;
    float r_light = pc.soft_light.x;
    float ext = length(bh);
    float da = length(cp.a - bc) + ext, db = length(cp.b - bc) + ext, dc = length(cp.c - bc) + ext;
    float lab = length(cp.b - cp.a), lbc = length(cp.c - cp.b), lca = length(cp.a - cp.c);
    // The box's distance to the plane, less the rounded unit normal's error.
    float plane_dist = abs(dot(cp.n, bc - cp.a)) - dot(abs(cp.n), bh)
        - CLUSTER_ROUNDING * (1.0 + lab * lca / cp.area2) * da;
    bool sure = plane_dist > 0.0 && cp.area2 * plane_dist > CLUSTER_CROSS_ROUNDING * da * db * dc;
    float reach = length(bc - o) + ext;
    float grow = r_light * (1.0 + 1e-5) + 1e-5 * reach + CLUSTER_ROUNDING * (reach + r_light);
    float k = CLUSTER_CROSS_ROUNDING * reach;
    uint rules = 0u;
    // Each edge: (p, q, third vertex), the box's distance to its line.
    for (int i = 0; i < 3; i++) {
        vec3 p = i == 0 ? cp.a : (i == 1 ? cp.b : cp.c);
        vec3 q = i == 0 ? cp.b : (i == 1 ? cp.c : cp.a);
        vec3 r = i == 0 ? cp.c : (i == 1 ? cp.a : cp.b);
        float dp = i == 0 ? da : (i == 1 ? db : dc);
        float dq = i == 0 ? db : (i == 1 ? dc : da);
        float len = i == 0 ? lab : (i == 1 ? lbc : lca);
        vec3 v = bc - p, e = q - p;
        float line_dist = length(v - e * (dot(v, e) / dot(e, e))) - ext;
        uint edge = edge_rule(p, q, r, o, grow + k * dp * dq / (len * line_dist), bc, bh, m);
        rules |= line_dist > 0.0 ? edge : 0u;
    }
    return (rules & 1u) != 0u && (sure || (rules & 2u) != 0u);
}

// The rules' margin for the box [lo, hi]: CLUSTER_MARGIN of the
// magnitudes involved.
float cluster_margin(ClusterPlane cp, vec3 lo, vec3 hi) {
    float scale = cp.margin_base + length(max(abs(lo), abs(hi)));
    return CLUSTER_MARGIN * scale;
}

// Which rule (if any) drops the caster for every sample of the box
// [lo, hi]: every sample on the light's side of its plane (its segments to
// the light never cross it), or, soft shadows, behind a closed caster
// (occlusion's back-face rule).
uint cull_rule(ClusterPlane cp, vec3 lo, vec3 hi) {
    // Straight-line code and one select at the end, not early returns:
    // lavapipe runs every lane through all of it anyway, and each return
    // adds a mask to what follows.
    vec3 c = 0.5 * (lo + hi), h = 0.5 * (hi - lo);
    float dc = dot(cp.n, c - cp.a);
    float r = dot(abs(cp.n), h);
    float m = cluster_margin(cp, lo, hi);
    bool light_side = (cp.side > 0.0 && dc - r >= m) || (cp.side < 0.0 && dc + r <= -m);
    bool behind_closed = is_soft() && cp.closed && dc + r <= -m;
    uint rule = light_side ? CLUSTER_LIGHT_SIDE : (behind_closed ? CLUSTER_BEHIND_CLOSED : CLUSTER_KEEP);
    return cp.n == vec3(0.0) ? CLUSTER_KEEP : rule;
}

// The reach rule (soft shadows): a caster whose every point is farther
// from the light's centre o than both the view sample x and the light's
// bounding radius blocks nothing from x, since every segment from x to a
// light sample stays within max(|x - o|, radius) of o (a ball is convex).
// The caster's distance is bounded below through its vertices' mean g:
// |o - g| - max |v - g| (true for any point g); each of the two lengths
// comes out of f32 within a few ulps of itself, and so does |x - o|, so a
// relative margin of the three holds the bound. Soft occlusion culls
// (sample, pair) by it with REACH_MARGIN, a chunk's (pair, box) with
// REACH_MARGIN_BOX (far above the sample's margin and its rounding: a pair
// dropped for a box is one every sample in it culls). Twin:
// cpu::clusters::caster_sphere and beyond_reach.
#define REACH_MARGIN 1e-5
#define REACH_MARGIN_BOX 1e-4

// A ball holding the caster: its vertices' mean g (xyz) and max |v - g| (w).
vec4 caster_ball(vec3 a, vec3 b, vec3 c) {
    vec3 g = (a + b + c) * (1.0 / 3.0);
    vec3 da = a - g, db = b - g, dc = c - g;
    float rho2 = max(max(dot(da, da), dot(db, db)), dot(dc, dc));
    return vec4(g, sqrt(rho2));
}

// The bound's two lengths for a caster's ball (caster_ball): |o - g| and
// max |v - g|.
vec2 caster_sphere(vec3 o, vec4 ball) {
    return vec2(length(o - ball.xyz), ball.w);
}

// The hull rule (soft shadows): every segment from a view sample in ball
// (c, rc) to a light sample lies in the convex hull of that ball and the
// light's (o, r), a round cone; a caster whose ball (caster_ball) lies
// outside it hides nothing from those samples. The distance to the round
// cone (after Quilez) is computed in coordinates scaled by the cone's
// length, from differences of the f32 points (each rounded relative to
// itself), so its rounding is a few ulps of the lengths involved; the
// rule asks for a relative margin of them (HULL_MARGIN per sample, with
// rc = 0; HULL_MARGIN_BOX for a subgroup's or a chunk's ball, far above
// the per-sample margin and both roundings, so a pair dropped for the ball
// is one that each of its samples culls: the hull of a sample's point
// lies in the hull of the ball holding it). No rule where one ball nearly holds
// the other (the cone's side is then ill-conditioned) or where anything
// is not finite. Twin: cpu::clusters::outside_hull.
#define HULL_MARGIN 1e-5
#define HULL_MARGIN_BOX 1e-4

// Signed distance from p to the hull of balls (a, r1) and (b, r2), in
// units of L = len + r1 + r2 (len = |b - a|); NaN where the rule does not
// apply.
float hull_distance(vec3 p, vec3 a, float r1, vec3 b, float r2, float len) {
    float s = 1.0 / (len + r1 + r2);
    vec3 ba = (b - a) * s, pa = (p - a) * s;
    r1 *= s;
    r2 *= s;
    float l2 = dot(ba, ba), rr = r1 - r2, a2 = l2 - rr * rr, il2 = 1.0 / l2;
    float y = dot(pa, ba), z = y - l2;
    vec3 xv = pa * l2 - ba * y;
    float x2 = dot(xv, xv), y2 = y * y * l2, z2 = z * z * l2;
    float k = sign(rr) * rr * rr * x2;
    // The three candidates computed, then selected (see cull_rule).
    float d_b = sqrt(x2 + z2) * il2 - r2, d_a = sqrt(x2 + y2) * il2 - r1;
    float d_side = (sqrt(x2 * a2 * il2) + y * rr) * il2 - r1;
    float d = sign(z) * a2 * z2 > k ? d_b : (sign(y) * a2 * y2 < k ? d_a : d_side);
    // A cone's side steeper than about 87 degrees: no rule.
    return a2 > 1e-2 * l2 ? d : uintBitsToFloat(0x7fc00000u);
}

// Whether the caster's ball `ball` lies outside the hull of ball (c, rc)
// and the light's by `margin` of the lengths (false for NaN).
bool outside_hull(vec4 ball, vec3 c, float rc, float margin) {
    vec3 o = pc.origin.xyz;
    float r = pc.soft_light.x;
    float len = length(o - c);
    float scale = len + r + rc;
    float d = hull_distance(ball.xyz, c, rc, o, r, len) * scale;
    // Samples near the light's sphere: no rule (the cone's side is then
    // steep); a ball's guard is wider than a point's, so that where a
    // ball's rule applies, the rule of every point in it does.
    bool clear = len - rc > (rc > 0.0 ? 1.02 : 1.01) * r;
    return clear && d > ball.w + margin * (scale + length(ball.xyz - c) + ball.w);
}

// Whether the caster of caster_sphere `s` lies beyond `reach` (the largest
// of the light's radius and the distances to o of the points it stands
// for) by `margin` of the magnitudes (NaN or infinite: no).
bool beyond_reach(vec2 s, float reach, float margin) {
    return s.x - s.y > reach + margin * (s.x + s.y + reach);
}

// The rules that need no plane, for the box [lo, hi] (soft shadows): the
// caster beyond the box's reach (beyond_reach), or outside the hull of a
// ball holding the box and the light (outside_hull). Twin:
// cpu::clusters::far_rule.
uint far_rule(ClusterPlane cp, vec3 lo, vec3 hi) {
    vec3 c = 0.5 * (lo + hi);
    // The reach rule: the box's farthest corner from the light's centre.
    vec3 o = pc.origin.xyz;
    float reach = max(length(max(abs(lo - o), abs(hi - o))), pc.soft_light.x);
    vec4 ball = cp.ball;
    bool beyond = beyond_reach(cp.sphere, reach, REACH_MARGIN_BOX);
    // The hull rule for a ball holding the box (its radius measured from
    // the rounded centre, and rounded up).
    float rb = length(max(abs(hi - c), abs(lo - c))) * (1.0 + 1e-6);
    bool outside = outside_hull(ball, c, rb, HULL_MARGIN_BOX);
    return beyond ? CLUSTER_BEYOND_REACH : (outside ? CLUSTER_OUTSIDE_HULL : CLUSTER_KEEP);
}

// Tile binning's rule for a tile's box: cull_rule, and for soft shadows
// far_rule. Tile binning leaves the penumbra rule out: per tile it cost
// more than it saved (torus_knot:100000: binning 0.6 -> 1.6 s, occlusion
// unchanged), the chunks' own boxes drop the same pairs. Twin:
// cpu::clusters::bin_rule.
uint bin_rule(ClusterPlane cp, vec3 lo, vec3 hi) {
    uint rule = cull_rule(cp, lo, hi);
    return rule != CLUSTER_KEEP || !is_soft() ? rule : far_rule(cp, lo, hi);
}

// Blocks per row of tiles, and a block's box's first texel (after the
// tiles' boxes).
uint cluster_blocks_per_row() {
    return (pc.more.y + CLUSTER_BLOCK - 1u) / CLUSTER_BLOCK;
}
uint cluster_block_box(uint face, uvec2 block) {
    uint per_row = cluster_blocks_per_row();
    return 2u * (pc.more.z * pc.sizes.w + (face * per_row + block.y) * per_row + block.x);
}

// Groups of CLUSTER_GROUP_SAMPLES consecutive listed samples (of all
// tiles' lists, tile-major: a group lies in one tile or spans the end of
// one and the start of the next), each with a box after the blocks' boxes
// (clusters_bounds.comp, BLOCKS = 2): pair_groups.comp tests a tile's pairs
// against the boxes of the groups its samples fall in, so that a work unit
// (a chunk of 64 of the tile's samples, soft_occlusion.comp) skips the
// pairs that the rules drop for every group it overlaps, before its own
// chunk's rules. Eight chunks a group: a tile of thousands of samples (a
// car over a ground, seen from the light) had each of its pairs judged by
// the chunk rules once per chunk.
#define CLUSTER_GROUP_SAMPLES 512u
// A pair's group bits (pair_groups.comp) cover a tile's first 32 groups;
// past them, every group keeps the pair.
#define CLUSTER_GROUP_BITS 32u
// Only tiles whose samples span at least this many groups get bits (the
// others' chunks go by their own rules): in fewer, the groups dropped too
// little for what they cost (ToyCar, pass and occlusion ms: 21.5 + 424
// from two groups, 18.2 + 427 from five, 13.4 + 446 from nine;
// torus_knot:100000's pass 18.3 -> 2.1 ms from five).
#define CLUSTER_GROUP_MIN 5u
uint cluster_group_box(uint g) {
    return cluster_block_box(pc.sizes.w, uvec2(0u)) + 2u * g;
}
// The groups that listed samples first..end (a tile's) fall in (0 for none).
uint cluster_groups_spanned(uint first, uint end) {
    return end > first ? (end - 1u) / CLUSTER_GROUP_SAMPLES - first / CLUSTER_GROUP_SAMPLES + 1u : 0u;
}

// Soft occlusion's rule for a chunk of samples (kept_pairs): cull_rule,
// the box outside the caster's penumbra volume (outside_penumbra), then
// far_rule. Twin: cpu::clusters::chunk_rule.
uint chunk_rule(ClusterPlane cp, vec3 lo, vec3 hi) {
    uint rule = cull_rule(cp, lo, hi);
    // Every rule computed, then chosen in their order (see cull_rule).
    vec3 c = 0.5 * (lo + hi), h = 0.5 * (hi - lo);
    bool penumbra = outside_penumbra(cp, c, h, cluster_margin(cp, lo, hi));
    uint far = far_rule(cp, lo, hi);
    uint soft_rule = cp.n != vec3(0.0) && penumbra ? CLUSTER_OUTSIDE_PENUMBRA : far;
    return rule != CLUSTER_KEEP || !is_soft() ? rule : soft_rule;
}


#endif
