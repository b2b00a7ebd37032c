//! CPU twin of the view-sample clusters (`clusters_bounds.comp`,
//! `clusters_common.glsl`): per tile, the box of its listed samples, and
//! the rules by which tile binning drops a caster for a whole box. Same f32
//! arithmetic as the shaders. The GPU builds boxes for soft shadows only
//! (for hard shadows they did not pay, `gpu::clusters`); the rules hold for
//! point and directional lights as well.

use glam::Vec3;

/// Box margins, relative to the magnitudes involved (`CLUSTER_MARGIN`).
pub const CLUSTER_MARGIN: f32 = 1e-4;
/// The rounding bound of a per-sample plane test, per unit of the
/// magnitudes it involves (`CLUSTER_ROUNDING`: 64 f32 ulps).
pub const CLUSTER_ROUNDING: f32 = 64.0 * f32::EPSILON;
/// The rounding bound of a cross product or determinant of differences
/// each rounded once relative to itself, per unit of the product of their
/// lengths (`CLUSTER_CROSS_ROUNDING`: 16 f32 ulps).
pub const CLUSTER_CROSS_ROUNDING: f32 = 16.0 * f32::EPSILON;
/// Tiles with more listed samples get no box (`CLUSTER_MAX_SAMPLES`).
pub const CLUSTER_MAX_SAMPLES: usize = 16384;

/// Tiles per side of a block (`CLUSTER_BLOCK`): binning tests a pair
/// whose rectangle spans more than [`CLUSTER_BLOCK_PAIR_TILES`] tiles
/// against a block's box (the union of its tiles' boxes) before the tiles'
/// boxes.
pub const CLUSTER_BLOCK: u32 = 4;
/// The occupied tiles of a block inside a pair's rectangle for which the
/// block's box is tested (`CLUSTER_BLOCK_MIN_TILES`).
pub const CLUSTER_BLOCK_MIN_TILES: u32 = 4;
/// Pairs whose rectangle spans more tiles go by blocks
/// (`CLUSTER_BLOCK_PAIR_TILES`).
pub const CLUSTER_BLOCK_PAIR_TILES: u32 = 64;

/// Listed samples per group (`CLUSTER_GROUP_SAMPLES`): the groups of the
/// lists' order (tile-major) whose boxes [`crate::cpu::pair_groups`] tests
/// a tile's pairs against, once per group instead of once per chunk of 64.
pub const CLUSTER_GROUP_SAMPLES: u32 = 512;
/// A pair's group bits cover its tile's first this many groups
/// (`CLUSTER_GROUP_BITS`); past them every group keeps it.
pub const CLUSTER_GROUP_BITS: u32 = 32;
/// Only tiles whose samples span at least this many groups get group bits
/// (`CLUSTER_GROUP_MIN`): in fewer, the groups dropped too little for what
/// they cost.
pub const CLUSTER_GROUP_MIN: u32 = 5;

/// The box of a tile's listed samples (camera-relative).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileBox {
    /// Per-axis minimum of the tile's sample positions.
    pub lo: Vec3,
    /// Per-axis maximum of the tile's sample positions.
    pub hi: Vec3,
}

/// Per tile, the box of the samples `positions[offsets[t]..offsets[t + 1]]`
/// (`None`: no samples, more than [`CLUSTER_MAX_SAMPLES`], or a non-finite
/// one); `offsets` has one entry per tile and the total at the end.
pub fn tile_boxes(offsets: &[u32], positions: &[Vec3]) -> Vec<Option<TileBox>> {
    offsets
        .windows(2)
        .map(|w| {
            let s = &positions[w[0] as usize..w[1] as usize];
            match s.is_empty() || s.len() > CLUSTER_MAX_SAMPLES {
                true => None,
                false => samples_box(s),
            }
        })
        .collect()
}

/// The box of samples `s`, `None` where one is not finite.
fn samples_box(s: &[Vec3]) -> Option<TileBox> {
    if !s.iter().all(|x| x.is_finite()) {
        return None;
    }
    let lo = s.iter().fold(Vec3::INFINITY, |a, &x| a.min(x));
    let hi = s.iter().fold(Vec3::NEG_INFINITY, |a, &x| a.max(x));
    Some(TileBox { lo, hi })
}

/// The groups of [`CLUSTER_GROUP_SAMPLES`] that listed samples
/// `first..end` (a tile's) fall in, 0 for none (`cluster_groups_spanned`).
pub fn groups_spanned(first: u32, end: u32) -> u32 {
    match end > first {
        true => (end - 1) / CLUSTER_GROUP_SAMPLES - first / CLUSTER_GROUP_SAMPLES + 1,
        false => 0,
    }
}

/// Per group of [`CLUSTER_GROUP_SAMPLES`] consecutive listed samples
/// (`positions`, the lists' order), their box, `None` where one is not
/// finite (`clusters_bounds.comp` with `BLOCKS = 2`).
pub fn group_boxes(positions: &[Vec3]) -> Vec<Option<TileBox>> {
    positions
        .chunks(CLUSTER_GROUP_SAMPLES as usize)
        .map(samples_box)
        .collect()
}

/// Per block of [`CLUSTER_BLOCK`]² tiles (face by face, row by row), the
/// union of the `boxes` of its tiles that hold samples (`occupied`), or
/// `None` when one of those has no box or none holds samples
/// (`clusters_bounds.comp` with `BLOCKS = 1`). Tiles are indexed
/// `face · tiles_per_row² + y · tiles_per_row + x`.
pub fn block_boxes(
    boxes: &[Option<TileBox>],
    occupied: &[bool],
    tiles_per_row: u32,
) -> Vec<Option<TileBox>> {
    let per_face = (tiles_per_row * tiles_per_row) as usize;
    let faces = boxes.len().checked_div(per_face).unwrap_or(0);
    let per_row = tiles_per_row.div_ceil(CLUSTER_BLOCK);
    let mut out = Vec::with_capacity(faces * (per_row * per_row) as usize);
    for face in 0..faces {
        for by in 0..per_row {
            for bx in 0..per_row {
                let mut union: Option<TileBox> = None;
                let mut valid = true;
                for ty in by * CLUSTER_BLOCK..((by + 1) * CLUSTER_BLOCK).min(tiles_per_row) {
                    for tx in bx * CLUSTER_BLOCK..((bx + 1) * CLUSTER_BLOCK).min(tiles_per_row) {
                        let t = face * per_face + (ty * tiles_per_row + tx) as usize;
                        if !occupied[t] {
                            continue;
                        }
                        match (boxes[t], &mut union) {
                            (None, _) => valid = false,
                            (Some(b), None) => union = Some(b),
                            (Some(b), Some(u)) => {
                                u.lo = u.lo.min(b.lo);
                                u.hi = u.hi.max(b.hi);
                            }
                        }
                    }
                }
                out.push(union.filter(|_| valid));
            }
        }
    }
    out
}

/// The light as the rules see it (camera-relative).
#[derive(Clone, Copy, Debug)]
pub enum ClusterLight {
    /// A point light at this camera-relative position.
    Point(Vec3),
    /// A directional light travelling along this direction (need not be
    /// unit).
    Directional(Vec3),
    /// A light with extent: its samples' bounding sphere.
    Sphere(Vec3, f32),
}

impl ClusterLight {
    fn origin(&self) -> Vec3 {
        match *self {
            ClusterLight::Point(o) | ClusterLight::Sphere(o, _) => o,
            ClusterLight::Directional(_) => Vec3::ZERO,
        }
    }

    fn radius(&self) -> f32 {
        match *self {
            ClusterLight::Sphere(_, r) => r,
            _ => 0.0,
        }
    }
}

/// What dropped a caster for a box (`CLUSTER_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClusterRule {
    /// Every sample on the light's side of the caster's plane.
    LightSide,
    /// Every sample behind a closed caster (soft shadows).
    BehindClosed,
    /// Every sample outside the caster's penumbra volume: one edge's plane
    /// through the sample leaves the whole light outside the caster's cone
    /// (soft shadows; [`chunk_rule`] only).
    OutsidePenumbra,
    /// Every point of the caster farther from the light's centre than
    /// every sample of the box and the light's radius ([`beyond_reach`];
    /// soft shadows, [`far_rule`]).
    BeyondReach,
    /// The caster's ball outside the hull of a ball holding the box and the
    /// light's sphere ([`outside_hull`]; soft shadows, [`far_rule`]).
    OutsideHull,
}

/// A caster's supporting plane as the rules see it (`ClusterPlane`).
#[derive(Clone, Copy, Debug)]
pub struct ClusterPlane {
    n: Vec3,
    a: Vec3,
    b: Vec3,
    c: Vec3,
    /// `|cross(b - a, c - a)|`.
    area2: f32,
    /// The light's side: +1, -1, or 0 when it straddles the plane.
    side: f32,
    closed: bool,
}

/// The supporting plane of triangle (a, b, c) and the light's side of it.
pub fn cluster_plane(v: [Vec3; 3], closed: bool, light: &ClusterLight) -> ClusterPlane {
    let [a, b, c] = v;
    let n = (b - a).cross(c - a);
    let len = n.length();
    let unit = n / len;
    if len.is_nan() || len <= 0.0 || len.is_infinite() || unit.is_nan() {
        return ClusterPlane {
            n: Vec3::ZERO,
            a,
            b,
            c,
            area2: 0.0,
            side: 0.0,
            closed: false,
        };
    }
    let side = match *light {
        ClusterLight::Directional(d) => {
            let s = -unit.dot(d) / d.length();
            side_of(s, CLUSTER_MARGIN)
        }
        _ => {
            let (o, r) = (light.origin(), light.radius());
            let s = unit.dot(o - a);
            let need = r + CLUSTER_MARGIN * (r + a.length() + o.length() + (a - o).length());
            side_of(s, need)
        }
    };
    ClusterPlane {
        n: unit,
        a,
        b,
        c,
        area2: len,
        side,
        closed,
    }
}

fn side_of(s: f32, need: f32) -> f32 {
    if s >= need {
        1.0
    } else if s <= -need {
        -1.0
    } else {
        0.0
    }
}

/// The reach rule's margin per (view sample, caster) (`REACH_MARGIN`).
pub const REACH_MARGIN: f32 = 1e-5;
/// The reach rule's margin per (box, caster) (`REACH_MARGIN_BOX`): far
/// above [`REACH_MARGIN`] and the rounding of both, so that a caster
/// dropped for a box is one that every sample in it culls.
pub const REACH_MARGIN_BOX: f32 = 1e-4;

/// A ball holding triangle `v` (`caster_ball`): its vertices' mean and
/// the largest distance of a vertex from it.
pub fn caster_ball([a, b, c]: [Vec3; 3]) -> (Vec3, f32) {
    let g = (a + b + c) * (1.0 / 3.0);
    let (da, db, dc) = (a - g, b - g, c - g);
    let rho2 = da.dot(da).max(db.dot(db)).max(dc.dot(dc));
    (g, rho2.sqrt())
}

/// The reach rule's lower bound on the distance from `o` to a triangle
/// whose [`caster_ball`] is `(g, rho)` (`caster_sphere`): `(|o - g|, rho)`;
/// the distance is at least the first less the second, for any `g`.
pub fn caster_sphere(o: Vec3, (g, rho): (Vec3, f32)) -> (f32, f32) {
    ((o - g).length(), rho)
}

/// The hull rule's margin per (view sample, caster) (`HULL_MARGIN`).
pub const HULL_MARGIN: f32 = 1e-5;
/// The hull rule's margin per (subgroup's ball, caster)
/// (`HULL_MARGIN_BOX`).
pub const HULL_MARGIN_BOX: f32 = 1e-4;

/// `hull_distance` in clusters_common.glsl: the signed distance from `p`
/// to the convex hull of balls (a, r1) and (b, r2) (a round cone, after
/// Quilez), in units of `len + r1 + r2` (`len` = `|b - a|`); NaN where
/// one ball nearly holds the other (no rule).
pub fn hull_distance(p: Vec3, a: Vec3, r1: f32, b: Vec3, r2: f32, len: f32) -> f32 {
    let s = 1.0 / (len + r1 + r2);
    let (ba, pa) = ((b - a) * s, (p - a) * s);
    let (r1, r2) = (r1 * s, r2 * s);
    let l2 = ba.dot(ba);
    let rr = r1 - r2;
    let a2 = l2 - rr * rr;
    let il2 = 1.0 / l2;
    let y = pa.dot(ba);
    let z = y - l2;
    let xv = pa * l2 - ba * y;
    let x2 = xv.dot(xv);
    let (y2, z2) = (y * y * l2, z * z * l2);
    let sign = |v: f32| {
        if v > 0.0 {
            1.0
        } else if v < 0.0 {
            -1.0
        } else {
            0.0
        }
    };
    let k = sign(rr) * rr * rr * x2;
    let d = if sign(z) * a2 * z2 > k {
        (x2 + z2).sqrt() * il2 - r2
    } else if sign(y) * a2 * y2 < k {
        (x2 + y2).sqrt() * il2 - r1
    } else {
        ((x2 * a2 * il2).sqrt() + y * rr) * il2 - r1
    };
    if a2 > 1e-2 * l2 {
        d
    } else {
        f32::NAN
    }
}

/// The hull rule (`outside_hull`): whether the caster's ball `(g, rho)`
/// ([`caster_ball`]) lies outside the convex hull of ball `(c, rc)` (view
/// samples) and the light's bounding sphere `(o, r)` by `margin` of the
/// lengths involved, and the samples clear of the light's sphere (1.01 of
/// its radius for a point, 1.02 for a ball). Every segment from such a
/// sample to a light sample lies in that hull (it is convex), so then the
/// caster hides nothing.
pub fn outside_hull((g, rho): (Vec3, f32), c: Vec3, rc: f32, o: Vec3, r: f32, margin: f32) -> bool {
    let len = (o - c).length();
    let scale = len + r + rc;
    let d = hull_distance(g, c, rc, o, r, len) * scale;
    // Samples near the light's sphere: no rule; a ball's guard is wider
    // than a point's, so that the rule of every point in it applies too.
    let clear = len - rc > if rc > 0.0 { 1.02 } else { 1.01 } * r;
    clear && d > rho + margin * (scale + (g - c).length() + rho)
}

/// The reach rule (`beyond_reach`): whether a caster whose
/// [`caster_sphere`] is `s` lies farther than `reach` from the light's
/// centre by `margin` of the magnitudes. `reach` is the larger of the
/// light's bounding radius and the distance from the centre of every view
/// sample the test stands for; then no segment from such a sample to a
/// light sample meets the caster (every point of it is within `reach` of
/// the centre: a ball is convex). NaN or infinite: false.
pub fn beyond_reach((dg, rho): (f32, f32), reach: f32, margin: f32) -> bool {
    dg - rho > reach + margin * (dg + rho + reach)
}

/// The reach of a box of view samples for a light of radius `r` centred
/// at `o`: the distance from `o` of the box's farthest corner, or `r`.
pub fn box_reach(b: &TileBox, o: Vec3, r: f32) -> f32 {
    (b.lo - o).abs().max((b.hi - o).abs()).length().max(r)
}

/// The rule (if any) that drops the caster for every sample of `b`.
pub fn cull_rule(p: &ClusterPlane, b: &TileBox, light: &ClusterLight) -> Option<ClusterRule> {
    if p.n == Vec3::ZERO {
        return None;
    }
    let c = 0.5 * (b.lo + b.hi);
    let h = 0.5 * (b.hi - b.lo);
    let dc = p.n.dot(c - p.a);
    let r = p.n.abs().dot(h);
    let r_light = light.radius();
    let scale =
        p.a.length() + light.origin().length() + r_light + b.lo.abs().max(b.hi.abs()).length();
    let m = CLUSTER_MARGIN * scale;
    if (p.side > 0.0 && dc - r >= m) || (p.side < 0.0 && dc + r <= -m) {
        return Some(ClusterRule::LightSide);
    }
    let soft = matches!(light, ClusterLight::Sphere(..));
    (soft && p.closed && dc + r <= -m).then_some(ClusterRule::BehindClosed)
}

/// Tile binning's rule for a tile's box (`bin_rule`): [`cull_rule`], and
/// for soft shadows [`far_rule`]. (The penumbra rule is left to the
/// chunks: per tile it cost more than it saved.)
pub fn bin_rule(p: &ClusterPlane, b: &TileBox, light: &ClusterLight) -> Option<ClusterRule> {
    let rule = cull_rule(p, b, light);
    match *light {
        ClusterLight::Sphere(o, r_light) if rule.is_none() => far_rule(p, b, o, r_light),
        _ => rule,
    }
}

/// Soft occlusion's rule for a chunk of samples (`chunk_rule`):
/// [`cull_rule`], the box outside the caster's penumbra volume, then
/// [`far_rule`].
pub fn chunk_rule(p: &ClusterPlane, b: &TileBox, light: &ClusterLight) -> Option<ClusterRule> {
    let rule = cull_rule(p, b, light);
    let ClusterLight::Sphere(o, r_light) = *light else {
        return rule;
    };
    if rule.is_some() {
        return rule;
    }
    let c = 0.5 * (b.lo + b.hi);
    let h = 0.5 * (b.hi - b.lo);
    let scale = p.a.length() + o.length() + r_light + b.lo.abs().max(b.hi.abs()).length();
    let m = CLUSTER_MARGIN * scale;
    if p.n != Vec3::ZERO && outside_penumbra(p, c, h, o, r_light, m) {
        return Some(ClusterRule::OutsidePenumbra);
    }
    far_rule(p, b, o, r_light)
}

/// The rules that need no plane (`far_rule`), for the box `b` and a light
/// of radius `r_light` centred at `o`: the caster beyond the box's reach
/// ([`beyond_reach`] with [`REACH_MARGIN_BOX`]), or outside the hull of
/// the box's ball and the light ([`outside_hull`] with
/// [`HULL_MARGIN_BOX`]).
pub fn far_rule(p: &ClusterPlane, b: &TileBox, o: Vec3, r_light: f32) -> Option<ClusterRule> {
    let c = 0.5 * (b.lo + b.hi);
    let reach = box_reach(b, o, r_light);
    let ball = caster_ball([p.a, p.b, p.c]);
    if beyond_reach(caster_sphere(o, ball), reach, REACH_MARGIN_BOX) {
        return Some(ClusterRule::BeyondReach);
    }
    // A ball holding the box: its radius measured from the rounded centre,
    // and rounded up.
    let rb = (b.hi - c).abs().max((b.lo - c).abs()).length() * (1.0 + 1e-6);
    outside_hull(ball, c, rb, o, r_light, HULL_MARGIN_BOX).then_some(ClusterRule::OutsideHull)
}

/// The bounds of `dot(g, x - p)` over the box (centre `bc`, half extent `bh`).
fn box_range(g: Vec3, p: Vec3, bc: Vec3, bh: Vec3) -> (f32, f32) {
    let c = g.dot(bc - p);
    let r = g.abs().dot(bh);
    (c - r, c + r)
}

/// `edge_rule` in clusters_common.glsl: for edge (p, q) with third vertex
/// r, whether the plane through every box point and the edge leaves the
/// sphere (o, rr) wholly outside the caster's cone (bit 0) or wholly
/// inside it (bit 1, the orientation flipped).
#[allow(clippy::too_many_arguments)]
fn edge_rule(p: Vec3, q: Vec3, r: Vec3, o: Vec3, rr: f32, bc: Vec3, bh: Vec3, m: f32) -> u32 {
    let d = q - p;
    let dd = d.dot(d);
    let w = o - p;
    let wp = w - d * (w.dot(d) / dd);
    let h = wp.length();
    // (NaN-safe: a NaN distance or length gives no plane.)
    if h.partial_cmp(&rr) != Some(std::cmp::Ordering::Greater)
        || dd.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
    {
        return 0;
    }
    let e1 = wp / h;
    let e2 = d.cross(e1).normalize();
    let sa = rr / h;
    let ca = (1.0 - sa * sa).max(0.0).sqrt();
    let rp = r - p;
    let (ru, rw) = (rp.dot(e1), rp.dot(e2));
    let g_p = rw * e1 - ru * e2;
    let ra = box_range(ca * e2 - sa * e1, p, bc, bh);
    let rb = box_range(ca * e2 + sa * e1, p, bc, bh);
    let rpl = box_range(g_p, p, bc, bh);
    let mp = m * g_p.length();
    let upper = ra.0 >= m && rb.0 >= m;
    let lower = ra.1 <= -m && rb.1 <= -m;
    let (pos, neg) = (rpl.0 >= mp, rpl.1 <= -mp);
    let outside = (upper && pos) || (lower && neg);
    let inside = (upper && neg) || (lower && pos);
    outside as u32 | (inside as u32) << 1
}

/// `outside_penumbra` in clusters_common.glsl: no sample of the box can
/// pass soft occlusion's edge tests for this caster, whatever orientation
/// the rounding gives its three planes where it is not sure.
fn outside_penumbra(cp: &ClusterPlane, bc: Vec3, bh: Vec3, o: Vec3, r_light: f32, m: f32) -> bool {
    let ext = bh.length();
    let (da, db, dc) = (
        (cp.a - bc).length() + ext,
        (cp.b - bc).length() + ext,
        (cp.c - bc).length() + ext,
    );
    let (lab, lbc, lca) = (
        (cp.b - cp.a).length(),
        (cp.c - cp.b).length(),
        (cp.a - cp.c).length(),
    );
    let plane_dist = cp.n.dot(bc - cp.a).abs()
        - cp.n.abs().dot(bh)
        - CLUSTER_ROUNDING * (1.0 + lab * lca / cp.area2) * da;
    let sure = plane_dist > 0.0 && cp.area2 * plane_dist > CLUSTER_CROSS_ROUNDING * da * db * dc;
    let reach = (bc - o).length() + ext;
    let grow = r_light * (1.0 + 1e-5) + 1e-5 * reach + CLUSTER_ROUNDING * (reach + r_light);
    let k = CLUSTER_CROSS_ROUNDING * reach;
    let edges = [
        (cp.a, cp.b, cp.c, da, db, lab),
        (cp.b, cp.c, cp.a, db, dc, lbc),
        (cp.c, cp.a, cp.b, dc, da, lca),
    ];
    let mut rules = 0;
    for (p, q, r, dp, dq, len) in edges {
        let (v, e) = (bc - p, q - p);
        let line_dist = (v - e * (v.dot(e) / e.dot(e))).length() - ext;
        if line_dist > 0.0 {
            let rr = grow + k * dp * dq / (len * line_dist);
            rules |= edge_rule(p, q, r, o, rr, bc, bh, m);
        }
    }
    rules & 1 != 0 && (sure || rules & 2 != 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box(center: Vec3, half: f32) -> TileBox {
        TileBox {
            lo: center - Vec3::splat(half),
            hi: center + Vec3::splat(half),
        }
    }

    // A triangle in the plane y = 0 facing +y; the light above it.
    const TRI: [Vec3; 3] = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(1.0, 0.0, 0.0),
    ];

    #[test]
    fn boxes_above_the_plane_are_on_the_light_side() {
        let light = ClusterLight::Sphere(Vec3::new(0.0, 5.0, 0.0), 1.0);
        let p = cluster_plane(TRI, false, &light);
        let above = unit_box(Vec3::new(0.0, 2.0, 0.0), 0.5);
        assert_eq!(cull_rule(&p, &above, &light), Some(ClusterRule::LightSide));
        let below = unit_box(Vec3::new(0.0, -2.0, 0.0), 0.5);
        assert_eq!(cull_rule(&p, &below, &light), None);
        // A box straddling the plane keeps the caster.
        let straddling = unit_box(Vec3::new(3.0, 0.2, 0.0), 0.5);
        assert_eq!(cull_rule(&p, &straddling, &light), None);
        // Closed: the samples behind it are dropped too (soft only).
        let closed = cluster_plane(TRI, true, &light);
        assert_eq!(
            cull_rule(&closed, &below, &light),
            Some(ClusterRule::BehindClosed)
        );
        let point = ClusterLight::Point(Vec3::new(0.0, 5.0, 0.0));
        let closed_hard = cluster_plane(TRI, true, &point);
        assert_eq!(cull_rule(&closed_hard, &below, &point), None);
    }

    #[test]
    fn a_light_straddling_the_plane_drops_nothing_on_its_side() {
        // The sphere reaches below the plane: no light-side rule.
        let light = ClusterLight::Sphere(Vec3::new(0.0, 0.5, 0.0), 1.0);
        let p = cluster_plane(TRI, false, &light);
        let above = unit_box(Vec3::new(0.0, 2.0, 0.0), 0.5);
        assert_eq!(cull_rule(&p, &above, &light), None);
        // Within the margin of the sphere touching the plane: kept as well.
        let touching = ClusterLight::Sphere(Vec3::new(0.0, 1.0 + 1e-6, 0.0), 1.0);
        let p = cluster_plane(TRI, false, &touching);
        assert_eq!(cull_rule(&p, &above, &touching), None);
    }

    #[test]
    fn a_box_just_above_the_plane_is_kept() {
        let light = ClusterLight::Point(Vec3::new(0.0, 5.0, 0.0));
        let p = cluster_plane(TRI, false, &light);
        let b = TileBox {
            lo: Vec3::new(0.0, 1e-6, 0.0),
            hi: Vec3::new(1.0, 1.0, 1.0),
        };
        assert_eq!(cull_rule(&p, &b, &light), None);
        let b = TileBox {
            lo: Vec3::new(0.0, 1e-2, 0.0),
            ..b
        };
        assert_eq!(cull_rule(&p, &b, &light), Some(ClusterRule::LightSide));
    }

    #[test]
    fn boxes_skip_empty_crowded_and_non_finite_tiles() {
        let pos = vec![
            Vec3::ONE,
            Vec3::ZERO,
            Vec3::ONE,
            Vec3::new(f32::NAN, 0.0, 0.0),
        ];
        let boxes = tile_boxes(&[0, 0, 2, 4], &pos);
        assert_eq!(boxes[0], None);
        assert_eq!(
            boxes[1],
            Some(TileBox {
                lo: Vec3::ZERO,
                hi: Vec3::ONE
            })
        );
        assert_eq!(boxes[2], None);
    }

    #[test]
    fn blocks_unite_their_occupied_tiles_and_need_every_box() {
        // Tiles per row 5: blocks of 4 per side, 2 per row, one face.
        let unit = |v: f32| {
            Some(TileBox {
                lo: Vec3::splat(v),
                hi: Vec3::splat(v + 1.0),
            })
        };
        let mut boxes = vec![None; 25];
        let mut occupied = vec![false; 25];
        for (t, v) in [(0, 0.0), (18, 2.0), (4, 5.0)] {
            boxes[t] = unit(v);
            occupied[t] = true;
        }
        // Tile 24 holds samples but has no box: its block (1, 1) gets none.
        occupied[24] = true;
        // Tile 1 has a stale box but no samples: left out.
        boxes[1] = unit(-9.0);
        let blocks = block_boxes(&boxes, &occupied, 5);
        assert_eq!(blocks.len(), 4);
        assert_eq!(
            blocks[0],
            Some(TileBox {
                lo: Vec3::splat(0.0),
                hi: Vec3::splat(3.0)
            })
        );
        assert_eq!(blocks[1], unit(5.0));
        assert_eq!(blocks[2], None);
        assert_eq!(blocks[3], None);
    }

    /// Soft occlusion's per-sample early outs for (x, caster) in f64, as
    /// soft_occlusion.comp computes them: whether some edge's plane through
    /// x leaves the whole sphere (o, r) outside the caster's cone.
    fn edge_test_rejects(v: [glam::DVec3; 3], o: glam::DVec3, r: f64, x: glam::DVec3) -> bool {
        let [a, b, c] = v;
        let m = [
            (a - x).cross(b - x),
            (b - x).cross(c - x),
            (c - x).cross(a - x),
        ];
        let se = if m[0].dot(c - x) < 0.0 { -1.0 } else { 1.0 };
        m.iter()
            .any(|mi| (-se * *mi / mi.length()).dot(x - o) / r <= -1.0)
    }

    #[test]
    fn boxes_outside_the_penumbra_volume_are_dropped_and_only_those() {
        // Random casters, sphere lights and boxes: wherever the rule drops
        // a box, every point tried in it must meet the per-sample early out
        // (in f64); and the rule must drop some boxes, or this proves nothing.
        let mut seed = 0x2545f4914f6cdd1du64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
        };
        let (mut dropped, mut tried) = (0, 0);
        for _ in 0..4000 {
            let mut v3 = || Vec3::new(rnd(), rnd(), rnd());
            let tri = [v3() * 0.5, v3() * 0.5, v3() * 0.5];
            let o = Vec3::new(0.0, 3.0, 0.0) + v3();
            let r = 0.05 + 0.5 * v3().x.abs();
            let centre = v3() * 3.0;
            let half = v3().abs() * 0.3;
            let light = ClusterLight::Sphere(o, r);
            let p = cluster_plane(tri, false, &light);
            let b = TileBox {
                lo: centre - half,
                hi: centre + half,
            };
            tried += 1;
            if chunk_rule(&p, &b, &light) != Some(ClusterRule::OutsidePenumbra) {
                continue;
            }
            dropped += 1;
            let v = tri.map(|t| t.as_dvec3());
            for k in 0..27 {
                let t = Vec3::new((k % 3) as f32, (k / 3 % 3) as f32, (k / 9) as f32) * 0.5;
                let x = b.lo + (b.hi - b.lo) * t;
                assert!(
                    edge_test_rejects(v, o.as_dvec3(), r as f64, x.as_dvec3()),
                    "{tri:?}, light {o} r {r}, point {x} of a dropped box"
                );
            }
        }
        assert!(dropped * 10 > tried, "{dropped} of {tried} boxes dropped");
    }

    /// The distance in f64 from `p` to triangle `v` (its nearest point:
    /// Ericson, Real-Time Collision Detection §5.1.5).
    fn triangle_distance(p: glam::DVec3, [a, b, c]: [glam::DVec3; 3]) -> f64 {
        let (ab, ac, ap) = (b - a, c - a, p - a);
        let (d1, d2) = (ab.dot(ap), ac.dot(ap));
        let q = 'q: {
            if d1 <= 0.0 && d2 <= 0.0 {
                break 'q a;
            }
            let bp = p - b;
            let (d3, d4) = (ab.dot(bp), ac.dot(bp));
            if d3 >= 0.0 && d4 <= d3 {
                break 'q b;
            }
            let vc = d1 * d4 - d3 * d2;
            if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
                break 'q a + ab * (d1 / (d1 - d3));
            }
            let cp = p - c;
            let (d5, d6) = (ab.dot(cp), ac.dot(cp));
            if d6 >= 0.0 && d5 <= d6 {
                break 'q c;
            }
            let vb = d5 * d2 - d1 * d6;
            if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
                break 'q a + ac * (d2 / (d2 - d6));
            }
            let va = d3 * d6 - d5 * d4;
            if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
                break 'q b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
            }
            let den = 1.0 / (va + vb + vc);
            a + ab * (vb * den) + ac * (vc * den)
        };
        let d = (p - q).length();
        // A triangle of zero area (f32 vertices that coincide): its edges.
        let segment = |u: glam::DVec3, w: glam::DVec3| {
            let e = w - u;
            let t = if e.length_squared() > 0.0 {
                ((p - u).dot(e) / e.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p - (u + e * t)).length()
        };
        let edges = segment(a, b).min(segment(b, c)).min(segment(c, a));
        if d.is_nan() {
            edges
        } else {
            d.min(edges)
        }
    }

    /// The tests' random numbers (xorshift64): uniform in [-1, 1), vectors
    /// of three, and unit directions.
    struct Xorshift(u64);
    impl Xorshift {
        fn f(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
        fn v(&mut self) -> glam::DVec3 {
            glam::DVec3::new(self.f(), self.f(), self.f())
        }
        fn dir(&mut self) -> glam::DVec3 {
            self.v().normalize_or(glam::DVec3::X)
        }
    }

    /// Whether the segment from `x` to `l` meets triangle `v` (f64,
    /// Möller–Trumbore, edges included).
    fn segment_meets(x: glam::DVec3, l: glam::DVec3, [a, b, c]: [glam::DVec3; 3]) -> bool {
        let d = l - x;
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-300 {
            return false;
        }
        let t = x - a;
        let u = t.dot(p) / det;
        let q = t.cross(e1);
        let v = d.dot(q) / det;
        let s = e2.dot(q) / det;
        u >= -1e-9 && v >= -1e-9 && u + v <= 1.0 + 1e-9 && (-1e-9..=1.0 + 1e-9).contains(&s)
    }

    #[test]
    fn the_hull_rule_drops_only_casters_outside_the_samples_and_the_light() {
        // Random lights, balls of samples and casters (small, large,
        // slivers) placed around the segment between them, near the camera
        // and 1e5 away: wherever the rule culls a (sample, caster), the f64
        // distance (the same formula) passes the caster's ball and no
        // segment from the sample to the light's sphere tried meets the
        // caster; wherever it drops one for a ball of samples, every point
        // tried in the ball culls it. It must cull some and keep some just
        // outside the hull, or this proves nothing.
        let mut g = Xorshift(0x1234_5678_9abc_def1);
        let (mut culled, mut dropped, mut kept, mut tried) = (0u32, 0u32, 0u32, 0u32);
        let mut box_dropped = 0u32;
        for case in 0..6000 {
            let offset = if case % 2 == 0 {
                glam::DVec3::ZERO
            } else {
                g.v() * 1e5
            };
            let o32 = (offset + g.v()).as_vec3();
            let r32 = (0.01 + g.f().abs()) as f32;
            let c32 = (o32.as_dvec3() + g.dir() * (0.5 + 5.0 * g.f().abs())).as_vec3();
            let rc32 = (0.3 * g.f().abs()) as f32;
            let (o, r, c, rc) = (o32.as_dvec3(), r32 as f64, c32.as_dvec3(), rc32 as f64);
            // A caster around a point between the ball and the light, off
            // the axis by up to twice the larger radius.
            let t = g.f().abs();
            let off = g.dir() * (2.0 * r.max(rc) * g.f().abs());
            let at = c + (o - c) * t + off;
            let size = match case % 3 {
                0 => 1e-3,
                1 => 0.05,
                _ => 0.5,
            } * (o - c).length();
            let mut tri = [at + g.v() * size, at + g.v() * size, at + g.v() * size];
            if case % 7 == 0 {
                tri[2] = tri[0] + (tri[1] - tri[0]) * 0.5 + g.v() * size * 1e-6;
            }
            let tri32 = tri.map(|v| v.as_vec3());
            let trid = tri32.map(|v| v.as_dvec3());
            let ball = caster_ball(tri32);
            tried += 1;
            let ball_drops = outside_hull(ball, c32, rc32, o32, r32, HULL_MARGIN_BOX);
            dropped += ball_drops as u32;
            // A chunk's box inside the samples' ball: where chunk_rule
            // drops the caster by the hull, every corner culls it.
            let half = rc32 * 0.5;
            let b = TileBox {
                lo: c32 - Vec3::splat(half),
                hi: c32 + Vec3::splat(half),
            };
            let light = ClusterLight::Sphere(o32, r32);
            if chunk_rule(&cluster_plane(tri32, false, &light), &b, &light)
                == Some(ClusterRule::OutsideHull)
            {
                box_dropped += 1;
                for k in 0..8 {
                    let x = Vec3::new(
                        if k & 1 == 0 { b.lo.x } else { b.hi.x },
                        if k & 2 == 0 { b.lo.y } else { b.hi.y },
                        if k & 4 == 0 { b.lo.z } else { b.hi.z },
                    );
                    assert!(
                        outside_hull(ball, x, 0.0, o32, r32, HULL_MARGIN),
                        "case {case}: {tri32:?} dropped for the box {b:?} but not culled for {x}"
                    );
                }
            }
            for k in 0..12 {
                // Points of the samples' ball: its centre and just inside its surface.
                let x = if k == 0 {
                    c32
                } else {
                    (c + g.dir() * rc * (1.0 - 1e-6)).as_vec3()
                };
                let xd = x.as_dvec3();
                let culls = outside_hull(ball, x, 0.0, o32, r32, HULL_MARGIN);
                assert!(
                    !ball_drops || culls || (xd - c).length() > rc,
                    "case {case}: {tri32:?} dropped for the ball ({c32}, {rc32}) but not culled for {x}"
                );
                if !culls {
                    kept += 1;
                    continue;
                }
                culled += 1;
                let (gd, rho) = (ball.0.as_dvec3(), ball.1 as f64);
                let scale = (o - xd).length() + r;
                let d = {
                    // The formula in f64.
                    let s = 1.0 / scale;
                    let (ba, pa) = ((o - xd) * s, (gd - xd) * s);
                    let (r1, r2) = (0.0, r * s);
                    let l2 = ba.dot(ba);
                    let rr: f64 = r1 - r2;
                    let a2 = l2 - rr * rr;
                    let y = pa.dot(ba);
                    let z = y - l2;
                    let xv = pa * l2 - ba * y;
                    let x2 = xv.dot(xv);
                    let k = rr.signum() * rr * rr * x2;
                    let v = if z.signum() * a2 * z * z * l2 > k {
                        (x2 + z * z * l2).sqrt() / l2 - r2
                    } else if y.signum() * a2 * y * y * l2 < k {
                        (x2 + y * y * l2).sqrt() / l2 - r1
                    } else {
                        ((x2 * a2 / l2).sqrt() + y * rr) / l2 - r1
                    };
                    v * scale
                };
                assert!(
                    d > rho,
                    "case {case}: {tri32:?} culled for {x}: f64 distance {d}, ball {rho}"
                );
                for _ in 0..40 {
                    let l = o + g.dir() * r * g.f().abs().cbrt();
                    assert!(
                        !segment_meets(xd, l, trid),
                        "case {case}: {tri32:?} culled for {x} meets the segment to {l}"
                    );
                }
                // The light's points nearest each vertex's direction from x.
                for v in trid {
                    let q = xd + (v - xd).normalize_or(glam::DVec3::X) * (o - xd).length();
                    let l = o + (q - o).normalize_or(glam::DVec3::Y) * r * (1.0 - 1e-9);
                    assert!(
                        !segment_meets(xd, l, trid),
                        "case {case}: {tri32:?} culled for {x} meets the segment to {l}"
                    );
                }
            }
        }
        eprintln!(
            "hull rule: culled {culled}, kept {kept}, dropped for a ball {dropped} and for a box {box_dropped} of {tried}"
        );
        assert!(
            culled > 10000 && kept > 10000 && dropped > 500 && box_dropped > 100,
            "culled {culled}, kept {kept}, dropped {dropped} of {tried}"
        );
    }

    #[test]
    fn the_reach_rule_drops_only_casters_beyond_the_samples_and_the_light() {
        // Random casters (small, large, slivers), light spheres and boxes,
        // near the camera and 1e5 away from it, with casters placed just
        // beyond or just within the reach: wherever the rule culls a
        // (sample, caster), the caster's true (f64) distance from the
        // light's centre passes both the sample's and the light's radius
        // (so no segment between them meets it); wherever it drops a
        // (box, caster), it culls every point tried in the box. And it must
        // cull and drop some, and keep some just inside, or this proves nothing.
        let mut g = Xorshift(0x9e3779b97f4a7c15);
        let (mut culled, mut kept_near, mut dropped, mut tried) = (0, 0, 0, 0);
        for case in 0..20000 {
            let offset = if case % 2 == 0 {
                glam::DVec3::ZERO
            } else {
                g.v() * 1e5
            };
            let o = offset + g.v();
            let r = 0.01 + g.f().abs();
            // A box of samples around o, sometimes inside the light's sphere.
            let centre = o + g.v() * (0.5 + 4.0 * g.f().abs());
            let half = g.v().abs() * 0.5 * g.f().abs();
            let b = TileBox {
                lo: (centre - half).as_vec3(),
                hi: (centre + half).as_vec3(),
            };
            // The light as the GPU has it: a centre and a radius in f32
            // (the radius rounded up over the samples: soft_light.rs).
            let o32 = o.as_vec3();
            let r32 = r as f32;
            let (o, r) = (o32.as_dvec3(), r32 as f64);
            let reach_box = box_reach(&b, o32, r32) as f64;
            // A caster around a point at the box's reach times 1 + s, s
            // from -0.01 to 0.01 (and a few within 1e-6): small, large or
            // a sliver.
            let s = if case % 5 == 0 {
                g.f() * 1e-6
            } else {
                g.f() * 0.01
            };
            let dir = g.v().normalize_or(glam::DVec3::X);
            let at = o + dir * reach_box * (1.0 + s);
            let size = match case % 3 {
                0 => 1e-3,
                1 => 0.3,
                _ => 3.0,
            } * reach_box;
            let mut tri = [at + g.v() * size, at + g.v() * size, at + g.v() * size];
            if case % 7 == 0 {
                tri[2] = tri[0] + (tri[1] - tri[0]) * 0.5 + g.v() * size * 1e-6;
            }
            let tri32 = tri.map(|t| t.as_vec3());
            let sphere = caster_sphere(o32, caster_ball(tri32));
            let distance = triangle_distance(o, tri32.map(|t| t.as_dvec3()));
            tried += 1;
            let box_drops = beyond_reach(sphere, box_reach(&b, o32, r32), REACH_MARGIN_BOX);
            dropped += box_drops as u32;
            for k in 0..27 {
                let t = Vec3::new((k % 3) as f32, (k / 3 % 3) as f32, (k / 9) as f32) * 0.5;
                let x = b.lo + (b.hi - b.lo) * t;
                let reach = (x - o32).length().max(r32);
                let culls = beyond_reach(sphere, reach, REACH_MARGIN);
                let true_reach = (x.as_dvec3() - o).length().max(r);
                if culls {
                    culled += 1;
                    assert!(
                        distance > true_reach,
                        "case {case}: {tri32:?} culled for {x} (light {o} r {r}): distance {distance}, reach {true_reach}"
                    );
                } else if distance < true_reach * 1.01 && distance > true_reach {
                    kept_near += 1;
                }
                assert!(
                    !box_drops || culls,
                    "case {case}: {tri32:?} dropped for the box {b:?} but not culled for {x}"
                );
            }
        }
        eprintln!(
            "reach rule: culled {culled}, dropped {dropped} of {tried}, kept near {kept_near}"
        );
        assert!(
            culled > 10000 && dropped > 1000 && kept_near > 100,
            "culled {culled}, dropped {dropped} of {tried}, kept near the reach {kept_near}"
        );
    }
}
