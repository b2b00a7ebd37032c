//! CPU twin of `caster_setup.comp`: which triangles cast, their four planes
//! (paper §3.3), and for every light face the conservative texel rectangle
//! and texel-space edge functions of their projection.
//!
//! Rules (no bias anywhere):
//! - a degenerate triangle (zero or non-finite normal) never casts;
//! - a triangle whose plane contains the light cannot block any segment to the light;
//! - a triangle of a closed mesh casts only when it faces away from the light
//!   (then no triangle is both caster and receiver: no acne);
//! - per face, the triangle is clipped to the face's fitted window pyramid;
//!   nothing left, or everything left farther than the farthest sample: culled there.

use glam::{Vec2, Vec3};

use super::light_view::{FaceWindow, LightView};

/// A caster's planes. The supporting plane is evaluated on the
/// camera-relative sample position `p`, the edge planes on `q = p - origin`
/// (the light position for a point light, 0 for a directional light):
/// blocked ⇔ `dot(support.xyz, p) + support.w < 0` and every
/// `dot(edge.xyz, q) + edge.w > 0` (and `p` is not on the caster itself).
///
/// Conditioning: every normal is a cross product with one short edge
/// vector (`(v_a - L) × (v_b - v_a)`, not `(v_a - L) × (v_b - L)`), so a
/// small triangle far from the light keeps f32-accurate planes.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct CasterPlanes {
    /// Supporting plane, positive on the light's side.
    pub support: [f32; 4],
    /// The three planes through the light and each edge (through each
    /// edge along the direction for a directional light), computed from the
    /// edge's endpoints in canonical (lexicographic) order so that the two
    /// triangles sharing an edge get exactly negated planes.
    pub edges: [[f32; 4]; 3],
    /// Per edge: +1 when the plane's positive side is inside, -1 otherwise.
    /// A point exactly on an edge plane is inside for the +1 side only, so a
    /// ray through a shared edge is claimed by exactly one triangle.
    pub side: [f32; 3],
}

impl CasterPlanes {
    /// Whether the caster blocks the light from camera-relative `p`, with
    /// `origin` = [`LightView::origin`].
    pub fn blocks(&self, p: Vec3, origin: Vec3) -> bool {
        let q = p - origin;
        let d = |pl: &[f32; 4], x: Vec3| pl[0] * x.x + pl[1] * x.y + pl[2] * x.z + pl[3];
        d(&self.support, p) < 0.0
            && self.edges.iter().zip(self.side).all(|(e, side)| {
                let v = d(e, q);
                if side > 0.0 {
                    v >= 0.0
                } else {
                    v < 0.0
                }
            })
    }
}

/// Texel-space edge functions (a, b, c) of a projected triangle, inside ≥ 0.
pub type TexelEdges = [[f32; 3]; 3];

/// One (caster, face) pair to rasterize.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CasterFace {
    /// Index of the caster in the triangles given to [`setup_casters`].
    pub triangle: u32,
    /// Light face the pair rasterizes in (0 to 5 for a point light's cube
    /// faces, 0 for a directional light).
    pub face: u32,
    /// Inclusive texel rectangle (x0, y0, x1, y1).
    pub rect: [u32; 4],
    /// Texel-space edge functions a·x + b·y + c ≥ 0 inside, when the whole
    /// triangle lies in front of the light (`None`: use the rectangle only),
    /// and the margin (texels along x and y) their tests allow.
    pub edges: Option<(TexelEdges, [f32; 2])>,
}

/// What the setup decided for the counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CasterCounts {
    /// Triangles given to the setup.
    pub submitted: u32,
    /// Triangles skipped as [`Skip::Degenerate`] (`COUNTER_DEGENERATE`).
    pub degenerate: u32,
    /// Triangles skipped as [`Skip::FrontFacingClosed`]
    /// (`COUNTER_FRONT_FACING_CLOSED`).
    pub front_facing_closed: u32,
    /// Casting triangles that overlap no light face's window pyramid, so
    /// produced no pair (`COUNTER_CULLED`).
    pub culled_frustum: u32,
    /// Casting triangles with at least one (caster, face) pair
    /// (`COUNTER_RASTERIZED`).
    pub rasterized: u32,
}

/// Margin in texels that keeps rectangles and edge tests conservative
/// against f32 rounding between this pass and the sample projection.
pub const TEXEL_MARGIN: f32 = 0.01;

/// Rounding of projected coordinates that the texel margins absorb on top
/// of [`TEXEL_MARGIN`], in ulps of the coordinates' magnitude.
pub const ROUNDING_ULPS: f32 = 32.0;

/// The magnitude of a face's projected coordinates, whose f32 rounding
/// (ulps of it, times texels per unit) the texel margins absorb: the
/// window's corners, plus 1 for a perspective face (x = X/Z carries the
/// error of X and of Z) or the depth for an orthographic one. Without it a
/// window zoomed onto a tight cluster of samples (a texel a few ulps wide)
/// misses casters. As `face_scale` in caster_common.glsl.
pub fn face_scale(window: &FaceWindow, point: bool, resolution: u32) -> f32 {
    let x1 = window.x0 + resolution as f32 / window.sx;
    let y1 = window.y0 + resolution as f32 / window.sy;
    window
        .x0
        .abs()
        .max(x1.abs())
        .max(window.y0.abs().max(y1.abs()))
        + if point { 1.0 } else { window.z_far.abs() }
}

/// The texel margin (x, y) for projected coordinates of magnitude `scale`.
pub fn texel_margin(window: &FaceWindow, scale: f32) -> Vec2 {
    Vec2::splat(TEXEL_MARGIN)
        + Vec2::new(window.sx, window.sy) * (ROUNDING_ULPS * f32::EPSILON * scale)
}

/// Planes of triangle `v` (camera-relative), or why it cannot cast.
pub fn caster_planes(light: &LightView, v: [Vec3; 3], closed: bool) -> Result<CasterPlanes, Skip> {
    let o = light.origin();
    let n = (v[1] - v[0]).cross(v[2] - v[0]);
    if !n.is_finite() || n == Vec3::ZERO {
        return Err(Skip::Degenerate);
    }
    // Signed distance of the light from the plane (times |n|).
    let s_light = match light {
        LightView::Point { .. } => n.dot(o - v[0]),
        LightView::Directional { direction } => n.dot(-*direction),
    };
    if s_light == 0.0 || !s_light.is_finite() {
        return Err(Skip::Degenerate);
    }
    if closed && s_light > 0.0 {
        return Err(Skip::FrontFacingClosed);
    }
    let ns = n * s_light.signum();
    let support = [ns.x, ns.y, ns.z, -ns.dot(v[0])];
    let mut edges = [[0.0; 4]; 3];
    let mut side = [1.0; 3];
    // Every edge plane's inside is the triangle's side of it, which one
    // determinant gives for all three: (a − o)·n = −s_light for a point
    // light, (c − a)·((b − a) × d) = s_light for a directional one. Taken
    // per edge from its opposite vertex instead, a sliver's short side
    // rounds the wrong way and its region becomes an unbounded wedge.
    let inside_side = match light {
        LightView::Point { .. } => -s_light.signum(),
        LightView::Directional { .. } => s_light.signum(),
    };
    for k in 0..3 {
        let a = v[k];
        let b = v[(k + 1) % 3];
        let swap = a.x > b.x || (a.x == b.x && (a.y > b.y || (a.y == b.y && a.z > b.z)));
        let (lo, hi) = if swap { (b, a) } else { (a, b) };
        let (m, w) = match light {
            // Plane through the light and the edge, in light-relative coordinates.
            LightView::Point { .. } => ((lo - o).cross(hi - lo), 0.0),
            LightView::Directional { direction } => {
                let m = (hi - lo).cross(*direction);
                (m, -m.dot(lo))
            }
        };
        edges[k] = [m.x, m.y, m.z, w];
        side[k] = if swap { -inside_side } else { inside_side };
    }
    Ok(CasterPlanes {
        support,
        edges,
        side,
    })
}

/// Why a triangle does not cast.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skip {
    /// A zero or non-finite normal, or a plane that contains the light (or
    /// is parallel to a directional light's direction).
    Degenerate,
    /// A triangle of a closed mesh whose front faces the light: the mesh's
    /// back faces shadow everything it would.
    FrontFacingClosed,
}

/// Clips the polygon `poly` (face coordinates X, Y, z) to `a·X + b·Y + c·w ≥ -slack`
/// where w = z (perspective) or w = 1 (`ortho`), as `clip()` in caster_clip.comp.
fn clip(poly: &[Vec3], plane: Vec3, ortho: bool, slack: f32) -> Vec<Vec3> {
    let d = |p: Vec3| {
        slack
            + if ortho {
                plane.x * p.x + plane.y * p.y + plane.z
            } else {
                plane.dot(p)
            }
    };
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let p = poly[i];
        let q = poly[(i + 1) % poly.len()];
        let (dp, dq) = (d(p), d(q));
        if dp >= 0.0 {
            out.push(p);
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            out.push(p + (q - p) * (dp / (dp - dq)));
        }
    }
    out
}

/// How far (in the plane's units) clipping widens a window side `plane`
/// for a triangle whose face coordinates are at most `t_max`: the f32
/// rounding of evaluating the plane (a few ulps of each term) and of the
/// vertices that earlier clips made (a few ulps of `t_max` each). A window
/// fitted to one sample is a pyramid thinner than that rounding; clipped
/// exactly, a triangle that covers the sample could come out empty.
/// As `clip_slack` in caster_common.glsl.
pub fn clip_slack(plane: Vec3, ortho: bool, t_max: f32) -> f32 {
    let terms = if ortho {
        t_max * (plane.x.abs() + plane.y.abs()) + plane.z.abs()
    } else {
        t_max * (plane.x.abs() + plane.y.abs() + plane.z.abs())
    };
    ROUNDING_ULPS * f32::EPSILON * terms
}

/// The texel rectangle and edge functions of triangle `v` in face `f`, or
/// `None` when nothing of it can block a sample of that face.
#[allow(clippy::type_complexity)]
pub fn caster_face(
    light: &LightView,
    window: &FaceWindow,
    f: usize,
    v: [Vec3; 3],
    resolution: u32,
) -> Option<([u32; 4], Option<(TexelEdges, [f32; 2])>)> {
    if !window.valid {
        return None;
    }
    let (r, u, w) = light.basis(f);
    let o = light.origin();
    let face = |p: Vec3| {
        let d = p - o;
        Vec3::new(d.dot(r), d.dot(u), d.dot(w))
    };
    let tri = [face(v[0]), face(v[1]), face(v[2])];
    // Window bounds in projected coordinates.
    let x1 = window.x0 + resolution as f32 / window.sx;
    let y1 = window.y0 + resolution as f32 / window.sy;
    let point = matches!(light, LightView::Point { .. });
    // Perspective: z >= 0 and x0·z <= X <= x1·z, y0·z <= Y <= y1·z (the
    // window pyramid); orthographic: the window's four sides.
    let mut poly = tri.to_vec();
    let sides = [
        Vec3::new(1.0, 0.0, -window.x0),
        Vec3::new(-1.0, 0.0, x1),
        Vec3::new(0.0, 1.0, -window.y0),
        Vec3::new(0.0, -1.0, y1),
    ];
    let near = point.then_some(Vec3::new(0.0, 0.0, 1.0));
    let t_max = tri
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0f32, f32::max);
    let mut clipped = false;
    for (k, plane) in near.into_iter().chain(sides).enumerate() {
        let before = poly.len();
        // The window's sides are widened by the rounding of the clip (see
        // `clip_slack`); the near plane (a point light's) is kept exact,
        // as the widened sides would reach behind the light.
        let slack = if point && k == 0 {
            0.0
        } else {
            clip_slack(plane, !point, t_max)
        };
        poly = clip(&poly, plane, !point, slack);
        clipped |= poly.len() != before || poly.iter().zip(&tri).any(|(a, b)| a != b);
        if poly.is_empty() {
            return None;
        }
    }
    let z_min = poly.iter().map(|p| p.z).fold(f32::INFINITY, f32::min);
    // A blocking point lies strictly nearer to the light than its sample.
    if z_min > window.z_far * (1.0 + 1e-5) + 1e-30 {
        return None;
    }
    let z_eps = window.z_far * 1e-6;
    let project = |p: Vec3| -> Option<Vec2> {
        if point {
            (p.z > z_eps).then(|| Vec2::new(p.x / p.z, p.y / p.z))
        } else {
            Some(Vec2::new(p.x, p.y))
        }
    };
    let full = [0, 0, resolution - 1, resolution - 1];
    let to_texel =
        |q: Vec2| Vec2::new((q.x - window.x0) * window.sx, (q.y - window.y0) * window.sy);
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    let mut touches_light = false;
    for p in &poly {
        match project(*p) {
            Some(q) => {
                let t = to_texel(q);
                lo = lo.min(t);
                hi = hi.max(t);
            }
            None => touches_light = true,
        }
    }
    let max = resolution as f32 - 1.0;
    let scale = face_scale(window, point, resolution);
    // A clipped vertex carries the rounding of the whole edge it cuts: a
    // few ulps of the vertices' magnitude, over its depth when projected.
    let clip_scale = if clipped {
        if point {
            2.0 * t_max * scale / z_min.max(1e-30)
        } else {
            2.0 * t_max
        }
    } else {
        0.0
    };
    let m = texel_margin(window, scale + clip_scale);
    let rect = if touches_light || !lo.is_finite() || !hi.is_finite() || !m.is_finite() {
        full
    } else {
        let cl = |x: f32| x.clamp(0.0, max) as u32;
        [
            cl((lo.x - m.x).floor()),
            cl((lo.y - m.y).floor()),
            cl((hi.x + m.x).floor()),
            cl((hi.y + m.y).floor()),
        ]
    };
    let edges = texel_edges(&tri, project, to_texel, window, scale);
    Some((rect, edges))
}

/// Edge functions of the unclipped triangle's projection in texel space,
/// when every vertex is in front of the light (then the projection is a
/// triangle containing the clipped polygon's), with their margin.
fn texel_edges(
    tri: &[Vec3; 3],
    project: impl Fn(Vec3) -> Option<Vec2>,
    to_texel: impl Fn(Vec2) -> Vec2,
    window: &FaceWindow,
    scale: f32,
) -> Option<(TexelEdges, [f32; 2])> {
    let pr: Vec<Vec2> = tri.iter().map(|p| project(*p)).collect::<Option<_>>()?;
    let reach = pr
        .iter()
        .map(|q| q.x.abs().max(q.y.abs()))
        .fold(0.0f32, f32::max);
    let t: Vec<Vec2> = pr.into_iter().map(to_texel).collect();
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    let em = texel_margin(window, scale + reach);
    if !area.is_finite() || area.abs() < 1e-6 || !em.is_finite() {
        return None;
    }
    let s = area.signum();
    let mut e = [[0.0f32; 3]; 3];
    for k in 0..3 {
        let a = t[k];
        let b = t[(k + 1) % 3];
        // Inside: s · cross(b - a, x - a) >= 0.
        let ea = -(b.y - a.y) * s;
        let eb = (b.x - a.x) * s;
        e[k] = [ea, eb, -(ea * a.x + eb * a.y)];
    }
    Some((e, em.to_array()))
}

/// Whether the texel-space square [x0, x1] × [y0, y1] may overlap a triangle
/// with these edge functions (conservative, with `margin` texels).
pub fn square_overlaps(
    edges: &[[f32; 3]; 3],
    margin: [f32; 2],
    x0: f32,
    y0: f32,
    x1: f32,
    y1: f32,
) -> bool {
    let cx = 0.5 * (x0 + x1);
    let cy = 0.5 * (y0 + y1);
    let hx = 0.5 * (x1 - x0) + margin[0];
    let hy = 0.5 * (y1 - y0) + margin[1];
    edges
        .iter()
        .all(|e| e[0] * cx + e[1] * cy + e[2] + e[0].abs() * hx + e[1].abs() * hy >= 0.0)
}

/// Runs the setup over all triangles: planes per triangle (`None` when it
/// does not cast) and the (caster, face) pairs to rasterize.
pub fn setup_casters(
    light: &LightView,
    windows: &[FaceWindow],
    triangles: &[([Vec3; 3], bool)],
    resolution: u32,
) -> (Vec<Option<CasterPlanes>>, Vec<CasterFace>, CasterCounts) {
    let mut planes = Vec::with_capacity(triangles.len());
    let mut faces = Vec::new();
    let mut counts = CasterCounts {
        submitted: triangles.len() as u32,
        ..Default::default()
    };
    for (i, &(v, closed)) in triangles.iter().enumerate() {
        match caster_planes(light, v, closed) {
            Err(Skip::Degenerate) => {
                counts.degenerate += 1;
                planes.push(None);
            }
            Err(Skip::FrontFacingClosed) => {
                counts.front_facing_closed += 1;
                planes.push(None);
            }
            Ok(p) => {
                let before = faces.len();
                for (f, w) in windows.iter().enumerate() {
                    if let Some((rect, edges)) = caster_face(light, w, f, v, resolution) {
                        faces.push(CasterFace {
                            triangle: i as u32,
                            face: f as u32,
                            rect,
                            edges,
                        });
                    }
                }
                if faces.len() == before {
                    counts.culled_frustum += 1;
                    planes.push(None);
                } else {
                    counts.rasterized += 1;
                    planes.push(Some(p));
                }
            }
        }
    }
    (planes, faces, counts)
}
