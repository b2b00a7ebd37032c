//! CPU twin of the view-sample clusters (`clusters_bounds.comp`,
//! `clusters_common.glsl`): per tile, the box of its listed samples, and
//! the rules by which tile binning drops a caster for a whole box. Same f32
//! arithmetic as the shaders. The GPU builds boxes for soft shadows only
//! (for hard shadows they did not pay, `gpu::clusters`); the rules hold for
//! point and directional lights as well.

use glam::Vec3;

/// Box margins, relative to the magnitudes involved (`CLUSTER_MARGIN`).
pub const CLUSTER_MARGIN: f32 = 1e-4;
/// Tiles with more listed samples get no box (`CLUSTER_MAX_SAMPLES`).
pub const CLUSTER_MAX_SAMPLES: usize = 16384;

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
            if s.is_empty() || s.len() > CLUSTER_MAX_SAMPLES || !s.iter().all(|x| x.is_finite()) {
                return None;
            }
            let lo = s.iter().fold(Vec3::INFINITY, |a, &x| a.min(x));
            let hi = s.iter().fold(Vec3::NEG_INFINITY, |a, &x| a.max(x));
            Some(TileBox { lo, hi })
        })
        .collect()
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
}

/// A caster's supporting plane as the rules see it (`ClusterPlane`).
#[derive(Clone, Copy, Debug)]
pub struct ClusterPlane {
    n: Vec3,
    a: Vec3,
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
}
