//! The documented epsilon bands in which a GPU answer may disagree with the
//! oracle for one (view sample, light sample) pair. Outside them every
//! disagreement is a bug.
//!
//! Light band: the pair may disagree only if the oracle's own answer flips
//! when the light sample is moved by [`BAND`] times its distance from the
//! view sample (for a directional light: when the direction is tilted by
//! [`BAND`] radians). This covers a caster's three edge planes (through the
//! light sample) and the sample's facing test. It is checked two ways:
//! moving the light along the six axis directions ([`in_light_band`]), and,
//! for casters thinner than the band, which those six moves step over, a
//! geometric test that the answer for that caster flips ([`near_thin_caster`]).
//!
//! Terminator band (paper §3.3: problems may remain "where front- and
//! back-faces touch"): the pair may also disagree if its shadow segment (ray,
//! for a directional light) passes within [`TERMINATOR_ULPS`] f32 ulps of the
//! camera-relative sample position (`TERMINATOR_ULPS · 2⁻²³ · ‖p − eye‖∞`)
//! of an edge of a closed mesh whose two triangles face the light oppositely.
//! There a view sample rounded a fraction of an ulp inside the solid slips
//! past the back-facing casters under a concave crease, while the
//! both-sided oracle sees the exit face.
//!
//! Caster-plane band: the pair may also disagree if its view sample lies
//! within [`CASTER_PLANE_ULPS`] f32 ulps (`CASTER_PLANE_ULPS · 2⁻²³ · ‖p − eye‖∞`)
//! of the supporting plane of a triangle that its shadow segment meets
//! (crosses, passes within that distance of one of its edges, or starts on
//! it: the sample's projection onto the plane lies inside the triangle, as
//! on TransmissionTest's coplanar backdrop, 8e-8 from another mesh's plane,
//! 0.7 ulps). A
//! triangle's shadow volume is bounded by its three edge planes, which the
//! light band covers, and by its own supporting plane, which moving the
//! light does not move: this band is that fourth boundary. The GPU
//! evaluates the plane in f32 (an error of a few ulps of ‖p‖·‖n‖), and an
//! f32 view sample can sit on the far side of it: rounded a fraction of an
//! ulp inside a closed solid, or (the rasterizer's triangle choice at a
//! pixel centre next to an edge) resolved on the plane of its triangle just
//! past the edge, under the neighbour. Measured on the GPU's own view
//! samples (`rendered_frames_conform`): 0.25, 0.38, 1.2 and 8.8 ulps.

use alias_free_shadows::oracle::{LightTarget, Oracle, ViewSample};
use alias_free_shadows::scene::Scene;
use glam::DVec3;

/// Relative size of the light band.
pub const BAND: f64 = 1e-5;
/// Width of the terminator band in f32 ulps of the camera-relative position.
pub const TERMINATOR_ULPS: f64 = 8.0;
/// Width of the caster-plane band in f32 ulps of the camera-relative position.
pub const CASTER_PLANE_ULPS: f64 = 16.0;

const AXES: [DVec3; 6] = [
    DVec3::X,
    DVec3::NEG_X,
    DVec3::Y,
    DVec3::NEG_Y,
    DVec3::Z,
    DVec3::NEG_Z,
];

/// Whether a disagreement of the pair (`s`, `target`) lies in one of the bands.
pub fn in_any_band(
    oracle: &Oracle,
    scene: &Scene,
    eye: DVec3,
    s: &ViewSample,
    target: LightTarget,
) -> bool {
    in_light_band(oracle, s, target)
        || near_thin_caster(scene, s, target)
        || near_closed_terminator(scene, eye, s, target)
        || near_caster_plane(scene, eye, s, target)
}

/// Whether the oracle's answer for the pair flips within the light band.
pub fn in_light_band(oracle: &Oracle, s: &ViewSample, target: LightTarget) -> bool {
    let v = oracle.sample_visible(s, target);
    match target {
        LightTarget::Point(p) => {
            let d = p.distance(s.position) * BAND;
            AXES.iter()
                .any(|a| oracle.sample_visible(s, LightTarget::Point(p + *a * d)) != v)
        }
        LightTarget::Direction(dir) => AXES.iter().any(|a| {
            oracle.sample_visible(s, LightTarget::Direction((dir + *a * BAND).normalize())) != v
        }),
    }
}

/// The light band's second half: whether the shadow segment passes near a
/// caster thinner than the band, which the six probes of [`in_light_band`]
/// step over (found by the randomized test: a collinear triangle 1.7e-11
/// wide, 9e-11 from the segment, where the probes move the segment 1.6e-8).
///
/// Moving the light by [`BAND`] of its distance moves the segment's point
/// `X` by ρ = `BAND`·‖X − p‖ (for a directional light, tilting it by `BAND`
/// radians does the same). If a triangle lies within ρ/2 of `X` and its
/// smallest altitude is at most ρ/2, the rays through the ball of radius ρ
/// about `X` both hit it (through its nearest point `Y`) and miss it
/// (through the points of its plane in the disc of radius ρ/2 about `Y`,
/// which a strip that narrow cannot cover): the answer for that triangle
/// flips within the light band, exactly as the band's definition says.
pub fn near_thin_caster(scene: &Scene, s: &ViewSample, target: LightTarget) -> bool {
    let end = segment_end(scene, s, target);
    scene.triangles().iter().enumerate().any(|(k, t)| {
        let v = t.vertices;
        if k as u32 == s.triangle {
            return false;
        }
        let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
        let longest = edges.iter().map(|e| e.length()).fold(0.0, f64::max);
        let altitude = if longest > 0.0 {
            edges[0].cross(edges[2]).length() / longest
        } else {
            0.0
        };
        if segment_crosses(s.position, end, v) {
            // Crossing: Y = X is on the triangle, at the crossing point.
            let n = edges[0].cross(-edges[2]);
            let (d, r) = (end - s.position, v[0] - s.position);
            let den = n.dot(d);
            let t = if den != 0.0 { n.dot(r) / den } else { 0.0 };
            let rho = BAND * (d * t.clamp(0.0, 1.0)).length();
            return altitude <= rho / 2.0;
        }
        (0..3).any(|e| {
            let (dist, x) = segment_closest(s.position, end, v[e], v[(e + 1) % 3]);
            let rho = BAND * (x - s.position).length();
            dist <= rho / 2.0 && altitude <= rho / 2.0
        })
    })
}

/// The far end of the shadow segment of `s` (for a directional light, a
/// point well beyond the scene).
pub fn segment_end(scene: &Scene, s: &ViewSample, target: LightTarget) -> DVec3 {
    match target {
        LightTarget::Point(p) => p,
        LightTarget::Direction(dir) => {
            let (lo, hi) = scene.bounds().unwrap_or((s.position, s.position));
            let reach = (hi - lo).length() + (s.position - lo).length() + 1.0;
            s.position - dir * reach * 4.0
        }
    }
}

/// Closest distance between segments [p0, p1] and [q0, q1].
pub fn segment_distance(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> f64 {
    segment_closest(p0, p1, q0, q1).0
}

/// Closest distance between segments [p0, p1] and [q0, q1], and the point
/// of [p0, p1] where it is reached.
pub fn segment_closest(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> (f64, DVec3) {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let (c, b) = (d1.dot(r), d1.dot(d2));
    if e == 0.0 {
        // A point: its distance to [p0, p1].
        let s = if a > 0.0 {
            (-c / a).clamp(0.0, 1.0)
        } else {
            0.0
        };
        return ((p0 + d1 * s).distance(q0), p0 + d1 * s);
    }
    let den = a * e - b * b;
    let mut s = if den > 0.0 {
        ((b * f - c * e) / den).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = if a > 0.0 {
            (-c / a).clamp(0.0, 1.0)
        } else {
            0.0
        };
    } else if t > 1.0 {
        t = 1.0;
        s = if a > 0.0 {
            ((b - c) / a).clamp(0.0, 1.0)
        } else {
            0.0
        };
    }
    ((p0 + d1 * s).distance(q0 + d2 * t), p0 + d1 * s)
}

/// Whether the segment [p, q] crosses triangle `v` (f64, closed barycentric range).
pub fn segment_crosses(p: DVec3, q: DVec3, v: [DVec3; 3]) -> bool {
    let d = q - p;
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det == 0.0 {
        return false;
    }
    let r = p - v[0];
    let u = r.dot(h) / det;
    let k = r.cross(e1);
    let w = d.dot(k) / det;
    let t = e2.dot(k) / det;
    (0.0..=1.0).contains(&t) && u >= 0.0 && w >= 0.0 && u + w <= 1.0
}

fn ulps(eye: DVec3, s: &ViewSample, count: f64) -> f64 {
    count * f32::EPSILON as f64 * (s.position - eye).abs().max_element()
}

/// Whether the shadow segment of `s` passes within the terminator band of
/// a closed mesh's light-silhouette edge.
pub fn near_closed_terminator(
    scene: &Scene,
    eye: DVec3,
    s: &ViewSample,
    target: LightTarget,
) -> bool {
    let eps = ulps(eye, s, TERMINATOR_ULPS);
    let end = segment_end(scene, s, target);
    // Towards the light from a point v.
    let towards = |v: DVec3| match target {
        LightTarget::Direction(dir) => -dir,
        LightTarget::Point(_) => end - v,
    };
    for m in scene.meshes.iter().filter(|m| m.closed) {
        let mut first = std::collections::HashMap::new();
        for (ti, t) in m.indices.iter().enumerate() {
            let [a, b, c] = m.triangle(ti);
            let front = (b - a).cross(c - a).dot(towards(a)) > 0.0;
            for k in 0..3 {
                let (i, j) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                if let Some(f) = first.insert((i, j), front) {
                    if f != front {
                        let (pi, pj) = (m.positions[i as usize], m.positions[j as usize]);
                        if segment_distance(s.position, end, pi, pj) <= eps {
                            return true;
                        }
                    }
                }
            }
        }
    }
    false
}

/// Whether `s` lies in the caster-plane band.
pub fn near_caster_plane(scene: &Scene, eye: DVec3, s: &ViewSample, target: LightTarget) -> bool {
    let eps = ulps(eye, s, CASTER_PLANE_ULPS);
    let end = segment_end(scene, s, target);
    scene.triangles().iter().enumerate().any(|(k, t)| {
        let v = t.vertices;
        let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
        k as u32 != s.triangle
            && n != DVec3::ZERO
            && n.dot(s.position - v[0]).abs() <= eps
            && (segment_crosses(s.position, end, v)
                || (0..3).any(|e| segment_distance(s.position, end, v[e], v[(e + 1) % 3]) <= eps)
                || projects_inside(s.position, v))
    })
}

/// Whether `p`'s projection onto the plane of `v` lies inside it: a sample
/// that close to the plane starts its segment on the triangle, as far as
/// the band can tell (a decal, or another surface coplanar with the
/// sample's: the GPU's f32 plane may put the sample behind it).
fn projects_inside(p: DVec3, v: [DVec3; 3]) -> bool {
    let n = (v[1] - v[0]).cross(v[2] - v[0]);
    (0..3).all(|e| {
        let (a, b) = (v[e], v[(e + 1) % 3]);
        (b - a).cross(p - a).dot(n) >= 0.0
    })
}
