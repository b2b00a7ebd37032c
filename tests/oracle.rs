//! Tests of the CPU oracle against analytic truth: hard shadows of a square,
//! the closed-form penumbra of a disk occluder under a disk light, the rules
//! of the visibility definition, precision far from the origin, primary
//! view samples and directional lights.

use std::f64::consts::{PI, TAU};

use alias_free_shadows::light::LightSamples;
use alias_free_shadows::oracle::{LightTarget, Oracle, ViewSample, ViewSamples, NO_TRIANGLE};
use alias_free_shadows::scene::{Camera, Mesh, Scene};
use glam::DVec3;

/// splitmix64, uniform in [0, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A quad of two triangles (0, 1, 2) and (0, 2, 3).
fn quad(name: &str, c: [DVec3; 4]) -> Mesh {
    let mut m = Mesh::new(name, c.to_vec(), vec![[0, 1, 2], [0, 2, 3]]);
    m.closed = false;
    m
}

fn translate(scene: &mut Scene, t: DVec3) {
    for m in &mut scene.meshes {
        for p in &mut m.positions {
            *p += t;
        }
    }
}

fn up() -> DVec3 {
    DVec3::Y
}

/// The axis-aligned square occluder of the hard-shadow tests, at y = 2.
const SQ: [f64; 4] = [-1.0, 1.3, -0.7, 1.1]; // x0, x1, z0, z1
const SQ_Y: f64 = 2.0;

/// Signed distance inside the occluder square of a point on its plane
/// (positive inside).
fn square_margin(q: DVec3) -> f64 {
    (q.x - SQ[0])
        .min(SQ[1] - q.x)
        .min(q.z - SQ[2])
        .min(SQ[3] - q.z)
}

/// Square occluder (ids 0, 1) over a ground plane (ids 2, 3), everything
/// shifted by `offset`; the camera looks straight down from above.
fn square_scene(offset: DVec3, size: u32) -> (Scene, Camera) {
    let mut scene = Scene::default();
    let (x0, x1, z0, z1) = (SQ[0], SQ[1], SQ[2], SQ[3]);
    scene.meshes.push(quad(
        "square",
        [
            DVec3::new(x0, SQ_Y, z0),
            DVec3::new(x0, SQ_Y, z1),
            DVec3::new(x1, SQ_Y, z1),
            DVec3::new(x1, SQ_Y, z0),
        ],
    ));
    scene.add_ground(0.0, 10.0);
    translate(&mut scene, offset);
    let camera = Camera {
        eye: DVec3::new(0.0, 12.0, 0.0) + offset,
        target: offset,
        up: DVec3::new(0.0, 0.0, -1.0),
        fov_y_deg: 60.0,
        width: size,
        height: size,
    };
    (scene, camera)
}

/// The result of the hard-shadow comparison.
struct HardShadow {
    visibility: Vec<f32>,
    view: ViewSamples,
    ambiguous: usize,
    shadowed: usize,
    lit_ground: usize,
    occluder: usize,
}

/// Checks primary view samples and visibility of the square scene against
/// the analytic answer; `shadow_point` maps a ground point (local
/// coordinates) to where its shadow ray crosses the occluder plane.
fn check_square(
    offset: DVec3,
    light: LightSamples,
    shadow_point: impl Fn(DVec3) -> DVec3,
) -> HardShadow {
    let size = 160;
    let (scene, camera) = square_scene(offset, size);
    let oracle = Oracle::new(&scene.triangles(), camera.eye);
    let view = oracle.primary_view_samples(&camera);
    let visibility = oracle.visibility(&view, &light, None);
    assert_eq!(visibility.len(), (size * size) as usize);
    let tol = 1e-9 * 10.0;
    let mut r = HardShadow {
        visibility: visibility.clone(),
        view: view.clone(),
        ambiguous: 0,
        shadowed: 0,
        lit_ground: 0,
        occluder: 0,
    };
    let eye = camera.eye - offset;
    for y in 0..size {
        for x in 0..size {
            let i = (y * size + x) as usize;
            let dir = camera.ray_direction(x, y);
            let s = view.samples[i].expect("every pixel sees the ground or the square");
            let p = s.position - offset;
            // Analytic primary hit.
            let q_occ = eye + dir * ((SQ_Y - eye.y) / dir.y);
            let m = square_margin(q_occ);
            if m.abs() < tol {
                r.ambiguous += 1;
                continue;
            }
            if m > 0.0 {
                assert!(
                    s.triangle <= 1,
                    "pixel ({x},{y}) should see the square: {s:?}"
                );
                assert!((p - q_occ).length() < 1e-9, "{p} vs {q_occ}");
                assert!((s.normal - up()).length() < 1e-12, "{:?}", s.normal);
                assert_eq!(visibility[i], 1.0, "the square's top is lit at ({x},{y})");
                r.occluder += 1;
                continue;
            }
            let q_ground = eye + dir * (-eye.y / dir.y);
            assert!(s.triangle == 2 || s.triangle == 3, "pixel ({x},{y}): {s:?}");
            assert!((p - q_ground).length() < 1e-9, "{p} vs {q_ground}");
            assert!((s.normal - up()).length() < 1e-12, "{:?}", s.normal);
            let m = square_margin(shadow_point(p));
            if m.abs() < tol {
                r.ambiguous += 1;
                continue;
            }
            let expected = if m > 0.0 { 0.0 } else { 1.0 };
            assert_eq!(
                visibility[i], expected,
                "pixel ({x},{y}) at {p}: margin {m}"
            );
            if expected == 0.0 {
                r.shadowed += 1;
            } else {
                r.lit_ground += 1;
            }
        }
    }
    // The scene must exercise all three cases.
    eprintln!(
        "shadowed {}, lit ground {}, occluder {}, ambiguous {}",
        r.shadowed, r.lit_ground, r.occluder, r.ambiguous
    );
    assert!(r.shadowed > 300 && r.lit_ground > 5000 && r.occluder > 500);
    assert!(r.ambiguous <= 4, "{} ambiguous samples", r.ambiguous);
    r
}

const POINT_LIGHT: DVec3 = DVec3::new(0.3, 6.0, -0.2);

fn point_light_shadow(p: DVec3) -> DVec3 {
    let l = POINT_LIGHT;
    l + (p - l) * ((l.y - SQ_Y) / (l.y - p.y))
}

/// 1. A point light's hard shadow of a square is exactly the square's
///    central projection onto the ground.
#[test]
fn point_light_square_shadow_is_exact() {
    check_square(
        DVec3::ZERO,
        LightSamples::Positions(vec![POINT_LIGHT]),
        point_light_shadow,
    );
}

/// 6. The same scene 10⁴ units away from the world origin gives the same
///    answers (the oracle works relative to the camera eye).
#[test]
fn far_from_origin_is_as_exact() {
    let offset = DVec3::splat(1e4);
    let near = check_square(
        DVec3::ZERO,
        LightSamples::Positions(vec![POINT_LIGHT]),
        point_light_shadow,
    );
    let far = check_square(
        offset,
        LightSamples::Positions(vec![POINT_LIGHT + offset]),
        point_light_shadow,
    );
    assert_eq!(near.visibility, far.visibility);
    for (a, b) in near.view.samples.iter().zip(&far.view.samples) {
        let (a, b) = (a.unwrap(), b.unwrap());
        assert_eq!(a.triangle, b.triangle);
        assert!((a.normal - b.normal).length() < 1e-12);
        assert!((a.position + offset - b.position).length() < 1e-9);
    }
    assert_eq!(near.shadowed, far.shadowed);

    // Ground points whose shadow rays pass 1e-7 inside or outside the
    // square's edges (1e-8 of the scene size) are decided exactly at both
    // places.
    for offset in [DVec3::ZERO, offset, DVec3::new(-1e4, 3e3, 1e4)] {
        let (scene, camera) = square_scene(offset, 4);
        let oracle = Oracle::new(&scene.triangles(), camera.eye);
        let l = POINT_LIGHT;
        let corners = [
            DVec3::new(SQ[0], SQ_Y, SQ[2]),
            DVec3::new(SQ[1], SQ_Y, SQ[2]),
            DVec3::new(SQ[1], SQ_Y, SQ[3]),
            DVec3::new(SQ[0], SQ_Y, SQ[3]),
        ];
        let mut samples = Vec::new();
        let mut expected = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            // The in-plane normal of the edge that points out of the square.
            let outward = (b - a).cross(DVec3::Y).normalize();
            let outward = if square_margin((a + b) * 0.5 + outward * 0.1) < 0.0 {
                outward
            } else {
                -outward
            };
            for i in 0..50 {
                let f = 0.05 + 0.9 * i as f64 / 49.0;
                for delta in [1e-7, -1e-7] {
                    let e = a + (b - a) * f + outward * delta;
                    let g = l + (e - l) * (l.y / (l.y - SQ_Y));
                    samples.push(Some(ViewSample {
                        position: DVec3::new(g.x, 0.0, g.z) + offset,
                        normal: up(),
                        triangle: NO_TRIANGLE,
                    }));
                    expected.push(if delta > 0.0 { 1.0 } else { 0.0 });
                }
            }
        }
        let view = ViewSamples::from_user(samples.len() as u32, 1, camera.eye, samples).unwrap();
        let vis = oracle.visibility(&view, &LightSamples::Positions(vec![l + offset]), None);
        assert_eq!(vis, expected, "offset {offset}");
    }
}

/// 8. A directional light casts the square's exact parallel projection.
#[test]
fn directional_light_square_shadow_is_exact() {
    let d = DVec3::new(0.8, -1.0, 0.5).normalize();
    let r = check_square(DVec3::ZERO, LightSamples::Direction(d), |p| {
        p - d * ((SQ_Y - p.y) / -d.y)
    });
    // And far from the origin.
    let offset = DVec3::new(-1e4, 1e4, 1e4);
    let far = check_square(offset, LightSamples::Direction(d), |p| {
        p - d * ((SQ_Y - p.y) / -d.y)
    });
    assert_eq!(r.visibility, far.visibility);
}

/// Area of the intersection of two disks with radii `a`, `b` whose centres
/// are `d` apart.
fn lens_area(a: f64, b: f64, d: f64) -> f64 {
    if d >= a + b {
        return 0.0;
    }
    if d <= (a - b).abs() {
        return PI * a.min(b).powi(2);
    }
    let alpha = ((d * d + a * a - b * b) / (2.0 * d * a))
        .clamp(-1.0, 1.0)
        .acos();
    let beta = ((d * d + b * b - a * a) / (2.0 * d * b))
        .clamp(-1.0, 1.0)
        .acos();
    let k = ((-d + a + b) * (d + a - b) * (d - a + b) * (d + a + b))
        .max(0.0)
        .sqrt();
    a * a * alpha + b * b * beta - 0.5 * k
}

#[test]
fn lens_area_is_right() {
    // Two unit disks with centres 1 apart: 2π/3 − √3/2.
    assert!((lens_area(1.0, 1.0, 1.0) - (2.0 * PI / 3.0 - 3f64.sqrt() / 2.0)).abs() < 1e-12);
    assert_eq!(lens_area(1.0, 2.0, 0.5), PI);
    assert_eq!(lens_area(1.0, 2.0, 3.0), 0.0);
}

/// 2. Disk light over a disk occluder (a 1024-gon) over a ground plane:
///    the fraction of visible light samples follows the closed form, and
///    every single sample agrees with the analytic segment/polygon test.
#[test]
fn disk_light_penumbra_matches_closed_form() {
    let n_light: usize = 20000;
    let (light_c, light_r) = (DVec3::new(0.0, 5.0, 0.0), 1.0);
    let (occ_c, occ_r, sides) = (DVec3::new(0.2, 2.5, -0.1), 0.8, 1024usize);
    let mut rng = Rng(0x5EED);
    let samples: Vec<DVec3> = (0..n_light)
        .map(|_| {
            let (u, v) = (rng.next(), rng.next());
            let (r, a) = (light_r * u.sqrt(), TAU * v);
            light_c + DVec3::new(r * a.cos(), 0.0, r * a.sin())
        })
        .collect();
    let rim = |k: usize| {
        let a = (k % sides) as f64 / sides as f64 * TAU;
        occ_c + DVec3::new(occ_r * a.cos(), 0.0, occ_r * a.sin())
    };
    let mut positions = vec![occ_c];
    positions.extend((0..sides).map(rim));
    let indices = (0..sides as u32)
        .map(|k| [0, 1 + k, 1 + (k + 1) % sides as u32])
        .collect();
    let mut scene = Scene::default();
    scene.meshes.push(Mesh::new("disk", positions, indices));
    scene.add_ground(0.0, 20.0);
    let ground_ids = [sides as u32, sides as u32 + 1];
    let oracle = Oracle::new(&scene.triangles(), DVec3::new(0.0, 8.0, 3.0));

    // Ground points whose projected occluder is at distance d from the
    // light's centre: umbra (d ≤ 0.6), penumbra, fully lit (d ≥ 2.6).
    let scale = light_c.y / occ_c.y; // (h_light − 0) / (h_occ − 0)
    let proj_r = occ_r * scale;
    let mut points = Vec::new();
    for (k, d) in [0.0, 0.3, 0.7, 1.0, 1.3, 1.6, 1.9, 2.2, 2.5, 2.7, 3.5]
        .iter()
        .enumerate()
    {
        let phi = 0.7 + 2.1 * k as f64;
        // Projected centre 2·c − p (in xz) must be at distance d from the light centre.
        let pc = light_c + DVec3::new(d * phi.cos(), 0.0, d * phi.sin());
        let p = (occ_c * scale - pc) / (scale - 1.0);
        points.push(DVec3::new(p.x, 0.0, p.z));
    }
    let view_samples: Vec<Option<ViewSample>> = points
        .iter()
        .map(|&p| {
            Some(ViewSample {
                position: p,
                normal: up(),
                triangle: if p.z >= p.x {
                    ground_ids[0]
                } else {
                    ground_ids[1]
                },
            })
        })
        .collect();
    let view = ViewSamples::from_user(
        points.len() as u32,
        1,
        DVec3::new(0.0, 8.0, 3.0),
        view_samples,
    )
    .unwrap();
    let light = LightSamples::Positions(samples.clone());
    let vis = oracle.visibility(&view, &light, None);
    let masks = oracle.visibility_masks(&view, &light);

    let inradius = occ_r * (PI / sides as f64).cos();
    let mut ambiguous = 0;
    let mut penumbra_points = 0;
    for (i, &p) in points.iter().enumerate() {
        // Closed form for a true disk.
        let pc = p + (occ_c - p) * scale;
        let d = ((pc - light_c) * DVec3::new(1.0, 0.0, 1.0)).length();
        let expected = 1.0 - lens_area(light_r, proj_r, d) / (PI * light_r * light_r);
        let sigma = (expected * (1.0 - expected) / n_light as f64).sqrt();
        let got = vis[i] as f64;
        assert!(
            (got - expected).abs() <= 4.0 * sigma + 1e-4,
            "point {i} ({p}), d = {d}: oracle {got}, closed form {expected} (σ {sigma})"
        );
        if expected > 0.0 && expected < 1.0 {
            penumbra_points += 1;
        }
        // Per sample: where does the segment cross the occluder's plane,
        // and is that inside the regular polygon?
        let mut visible = 0;
        for (s_i, &s) in samples.iter().enumerate() {
            let q = p + (s - p) * ((occ_c.y - p.y) / (s.y - p.y)) - occ_c;
            let step = TAU / sides as f64;
            let a = q.z.atan2(q.x).rem_euclid(TAU);
            let k = (a / step).floor();
            let rho = (q.x * q.x + q.z * q.z).sqrt();
            let margin = inradius - rho * (a - (k + 0.5) * step).cos();
            let bit = (masks[i][s_i / 64] >> (s_i % 64)) & 1 == 1;
            visible += bit as usize;
            if margin.abs() < 1e-9 {
                ambiguous += 1;
                continue;
            }
            assert_eq!(
                bit,
                margin < 0.0,
                "point {i}, light sample {s_i}: margin {margin}"
            );
        }
        assert_eq!(visible as f32 / n_light as f32, vis[i]);
    }
    assert!(penumbra_points >= 6);
    assert!(ambiguous <= 3, "{ambiguous}");
    assert_eq!(masks[0].len(), n_light.div_ceil(64));
}

/// 3. The open-segment rule.
#[test]
fn open_segment_rule() {
    let mut scene = Scene::default();
    // A horizontal triangle at y = 2 over the point (0.1, ·, 0.1).
    scene.meshes.push(Mesh::new(
        "blocker",
        vec![
            DVec3::new(-1.0, 2.0, -1.0),
            DVec3::new(-1.0, 2.0, 1.0),
            DVec3::new(1.5, 2.0, 0.5),
        ],
        vec![[0, 1, 2]],
    ));
    scene.add_ground(0.0, 5.0);
    // A small triangle 1e-4 above the ground around (3, 0, -3).
    scene.meshes.push(Mesh::new(
        "low",
        vec![
            DVec3::new(2.9, 1e-4, -3.1),
            DVec3::new(3.0, 1e-4, -2.8),
            DVec3::new(3.1, 1e-4, -3.1),
        ],
        vec![[0, 1, 2]],
    ));
    let oracle = Oracle::new(&scene.triangles(), DVec3::new(0.0, 3.0, 4.0));
    // A user sample exactly on the ground (not ignored: NO_TRIANGLE); the
    // ground is "hit" at t = 0, which does not count.
    let p = ViewSample::user(DVec3::new(0.1, 0.0, 0.1), up());
    let at = |x, y, z| LightTarget::Point(DVec3::new(x, y, z));
    // The light sample lies exactly on the blocker: a hit at t = 1 does not count.
    assert!(oracle.sample_visible(&p, at(0.1, 2.0, 0.1)));
    assert!(oracle.sample_visible(&p, at(0.3, 2.0, 0.2)));
    // Beyond the blocker it blocks, even just beyond.
    assert!(!oracle.sample_visible(&p, at(0.1, 4.0, 0.1)));
    assert!(!oracle.sample_visible(&p, at(0.1, 2.0 + 1e-6, 0.1)));
    // A blocker beyond the light sample does not block.
    assert!(oracle.sample_visible(&p, at(0.1, 1.0, 0.1)));
    assert!(oracle.sample_visible(&p, at(0.1, 2.0 - 1e-6, 0.1)));
    // Beside the blocker nothing blocks.
    assert!(oracle.sample_visible(&p, at(3.0, 4.0, 0.1)));
    // A directional light: the ray towards −direction is blocked...
    assert!(!oracle.sample_visible(&p, LightTarget::Direction(-up())));
    // ...but from a point above the blocker, the blocker is behind the ray.
    let above = ViewSample::user(DVec3::new(0.1, 3.0, 0.1), up());
    assert!(oracle.sample_visible(&above, LightTarget::Direction(-up())));
    // And a sample exactly on the blocker's plane sees the light above it.
    let on = ViewSample::user(DVec3::new(0.1, 2.0, 0.1), up());
    assert!(oracle.sample_visible(&on, at(0.1, 4.0, 0.1)));
    assert!(oracle.sample_visible(&on, LightTarget::Direction(-up())));
    // The tolerance at the view sample does not grow with the distance to
    // the light: an occluder 1e-4 above the sample blocks a light 1e6 away.
    let low = ViewSample::user(DVec3::new(3.0, 0.0, -3.0), up());
    assert!(!oracle.sample_visible(&low, at(3.0, 1e6, -3.0)));
    assert!(!oracle.sample_visible(&low, at(3.0, 1e-4 + 1e-6, -3.0)));
    assert!(oracle.sample_visible(&low, at(3.0, 1e-4 - 1e-6, -3.0)));
    assert_eq!(oracle.shadow_rays_cast(), 14);
}

/// 4. The own-triangle rule.
#[test]
fn own_triangle_rule() {
    let tri = [
        DVec3::new(-1.0, 1.0, -1.0),
        DVec3::new(0.0, 1.5, 1.0),
        DVec3::new(1.0, 1.2, -1.0),
    ];
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
    let n = if n.y < 0.0 { -n } else { n };
    let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
    // A point slightly behind the triangle (as a numerically curved surface
    // or rounding would put it), with the triangle's normal.
    let p = centre - n * 1e-3;
    let light = LightTarget::Point(centre + n * 3.0 + DVec3::new(0.1, 0.0, 0.05));

    let mut scene = Scene::default();
    scene.add_ground(-3.0, 5.0); // ids 0, 1: below everything
    scene
        .meshes
        .push(Mesh::new("tri", tri.to_vec(), vec![[0, 1, 2]])); // id 2
    let oracle = Oracle::new(&scene.triangles(), DVec3::new(2.0, 5.0, 2.0));
    let on = |triangle| ViewSample {
        position: p,
        normal: n,
        triangle,
    };
    assert!(
        oracle.sample_visible(&on(2), light),
        "own triangle must be ignored"
    );
    assert!(
        !oracle.sample_visible(&on(NO_TRIANGLE), light),
        "nothing ignored: blocked"
    );
    assert!(
        !oracle.sample_visible(&on(0), light),
        "another id ignored: blocked"
    );

    // A second triangle with the same corners but another id still blocks.
    scene
        .meshes
        .push(Mesh::new("copy", tri.to_vec(), vec![[0, 2, 1]])); // id 3
    let oracle = Oracle::new(&scene.triangles(), DVec3::ZERO);
    assert!(!oracle.sample_visible(&on(2), light));
    assert!(!oracle.sample_visible(&on(3), light));
    let view = ViewSamples::from_user(2, 1, DVec3::ZERO, vec![Some(on(2)), Some(on(NO_TRIANGLE))])
        .unwrap();
    assert_eq!(
        oracle.visibility(
            &view,
            &LightSamples::Positions(vec![centre + n * 3.0]),
            None
        ),
        vec![0.0, 0.0]
    );
}

/// Neighbouring triangles sharing an edge with the view sample's triangle do
/// not block it, although a sample computed in floating point lies on the
/// shared edge only to within rounding (see `ENDPOINT_EPSILON`).
#[test]
fn shared_edge_neighbour_does_not_block() {
    let n = DVec3::new(0.31, 1.0, -0.47).normalize();
    let a = n.cross(DVec3::X).normalize();
    let b = n.cross(a);
    let c = DVec3::new(0.37, -0.71, 0.13);
    let corners = [
        c - a * 3.1 - b * 2.9,
        c + a * 3.3 - b * 2.7,
        c + a * 2.9 + b * 3.1,
        c - a * 3.0 + b * 3.2,
    ];
    let mut scene = Scene::default();
    scene.meshes.push(quad("tilted", corners));
    let oracle = Oracle::new(&scene.triangles(), DVec3::new(1.0, 7.0, 3.0));
    let mut rng = Rng(11);
    let mut samples = Vec::new();
    for k in 0..2000 {
        let f = rng.next();
        let p = corners[0] + (corners[2] - corners[0]) * f; // on the shared diagonal
        samples.push(Some(ViewSample {
            position: p,
            normal: n,
            triangle: k % 2,
        }));
    }
    let view = ViewSamples::from_user(2000, 1, DVec3::ZERO, samples).unwrap();
    let lights: Vec<DVec3> = (0..8)
        .map(|_| c + n * 4.0 + a * (6.0 * rng.next() - 3.0) + b * (6.0 * rng.next() - 3.0))
        .collect();
    let vis = oracle.visibility(&view, &LightSamples::Positions(lights), None);
    assert!(vis.iter().all(|&v| v == 1.0));
    // Almost grazing light too.
    let graze = LightSamples::Positions(vec![c + a * 100.0 + n * 0.5]);
    assert!(oracle
        .visibility(&view, &graze, None)
        .iter()
        .all(|&v| v == 1.0));
}

/// 5. The normal rule: light samples behind (or in the plane of) the view
///    sample's geometric normal are not visible.
#[test]
fn normal_rule() {
    let oracle = Oracle::new(&[], DVec3::ZERO);
    let p = ViewSample::user(DVec3::new(0.5, 1.0, 0.5), up());
    let at = |x, y, z| LightTarget::Point(DVec3::new(x, y, z));
    assert!(oracle.sample_visible(&p, at(0.0, 2.0, 0.0)));
    assert!(!oracle.sample_visible(&p, at(0.0, 0.0, 0.0)));
    assert!(
        !oracle.sample_visible(&p, at(9.0, 1.0, -3.0)),
        "in the tangent plane"
    );
    assert!(oracle.sample_visible(&p, at(9.0, 1.0 + 1e-9, -3.0)));
    assert!(!oracle.sample_visible(&p, LightTarget::Direction(up())));
    assert!(oracle.sample_visible(&p, LightTarget::Direction(DVec3::new(1.0, -0.01, 0.0))));
    let flipped = ViewSample::user(p.position, -up());
    assert!(!oracle.sample_visible(&flipped, at(0.0, 2.0, 0.0)));
    assert!(oracle.sample_visible(&flipped, at(0.0, 0.0, 0.0)));

    let view =
        ViewSamples::from_user(3, 1, DVec3::ZERO, vec![Some(p), None, Some(flipped)]).unwrap();
    let light = LightSamples::Positions(vec![
        DVec3::new(0.0, 2.0, 0.0),
        DVec3::new(0.0, -2.0, 0.0),
        DVec3::new(3.0, 1.0, 0.0),
        DVec3::new(1.0, 5.0, 1.0),
    ]);
    assert_eq!(oracle.visibility(&view, &light, None), vec![0.5, 0.0, 0.25]);
    let masks = oracle.visibility_masks(&view, &light);
    assert_eq!(masks, vec![vec![0b1001], vec![], vec![0b0010]]);
}

/// 7. Primary view samples of a tilted quad: on its plane, with the right
///    triangle ids and normals, and `None` where the rays miss.
#[test]
fn primary_view_samples_hit_the_plane() {
    let n = DVec3::new(0.2, 1.0, 0.4).normalize();
    let a = n.cross(DVec3::X).normalize();
    let b = n.cross(a);
    let c = DVec3::new(0.3, -1.0, 0.2);
    let h = 3.0;
    // Corner k at (α, β) = (∓h, ∓h), (+h, −h), (+h, +h), (−h, +h).
    let corners = [
        c - a * h - b * h,
        c + a * h - b * h,
        c + a * h + b * h,
        c - a * h + b * h,
    ];
    for offset in [DVec3::ZERO, DVec3::new(1e4, -1e4, 1e4)] {
        let mut scene = Scene::default();
        scene.add_ground(60.0, 1.0); // ids 0, 1: above the camera, never seen
        scene.meshes.push(quad("tilted", corners)); // ids 2, 3
        translate(&mut scene, offset);
        let camera = Camera {
            eye: DVec3::new(0.5, 4.0, 6.0) + offset,
            target: c + offset,
            up: DVec3::Y,
            fov_y_deg: 70.0,
            width: 96,
            height: 64,
        };
        let oracle = Oracle::new(&scene.triangles(), camera.eye);
        let view = oracle.primary_view_samples(&camera);
        assert_eq!(
            (view.width, view.height, view.samples.len()),
            (96, 64, 96 * 64)
        );
        assert_eq!(view.eye, camera.eye);
        let eye = camera.eye - offset;
        let (mut hits, mut misses) = (0, 0);
        for y in 0..64 {
            for x in 0..96 {
                let dir = camera.ray_direction(x, y);
                let t = n.dot(c - eye) / n.dot(dir);
                let q = eye + dir * t;
                let (al, be) = ((q - c).dot(a), (q - c).dot(b));
                let margin = (h - al.abs()).min(h - be.abs());
                let s = view.get(x, y);
                if margin.abs() < 1e-9 || (al - be).abs() < 1e-9 {
                    continue;
                }
                if t <= 0.0 || margin < 0.0 {
                    assert!(s.is_none(), "pixel ({x},{y}) should miss: {s:?}");
                    misses += 1;
                    continue;
                }
                let s = s.unwrap_or_else(|| panic!("pixel ({x},{y}) should hit"));
                let p = s.position - offset;
                assert!(
                    n.dot(p - c).abs() < 1e-12 * (1.0 + offset.length()),
                    "off the plane"
                );
                assert!((p - q).length() < 1e-9 * (1.0 + offset.length() * 1e-3));
                assert_eq!(s.triangle, if al > be { 2 } else { 3 }, "pixel ({x},{y})");
                assert!((s.normal - n).length() < 1e-10, "{} vs {n}", s.normal);
                hits += 1;
            }
        }
        assert!(hits > 1000 && misses > 500, "{hits} hits, {misses} misses");
    }
    // Looking away from everything: no samples.
    let oracle = Oracle::new(&Scene::default().triangles(), DVec3::ZERO);
    let camera = Camera {
        eye: DVec3::ZERO,
        target: DVec3::Z,
        up: DVec3::Y,
        fov_y_deg: 40.0,
        width: 4,
        height: 3,
    };
    assert!(oracle
        .primary_view_samples(&camera)
        .samples
        .iter()
        .all(Option::is_none));
}

/// A UV sphere of `stacks` × `slices` quads (2 triangles each, degenerate at
/// the poles).
fn uv_sphere(c: DVec3, r: f64, stacks: u32, slices: u32) -> Mesh {
    let mut pos = Vec::new();
    for i in 0..=stacks {
        let th = PI * i as f64 / stacks as f64;
        for j in 0..slices {
            let ph = TAU * j as f64 / slices as f64;
            pos.push(c + DVec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * r);
        }
    }
    let mut idx = Vec::new();
    for i in 0..stacks {
        for j in 0..slices {
            let a = i * slices + j;
            let b = i * slices + (j + 1) % slices;
            let (c2, d) = (a + slices, b + slices);
            idx.push([a, b, d]);
            idx.push([a, d, c2]);
        }
    }
    Mesh::new("sphere", pos, idx)
}

/// A 100k-triangle sphere over a ground plane under a disk light: ground
/// samples agree per light sample with the analytic segment/ball test, and
/// the shadow-ray rate is reported.
#[test]
fn large_scene_soft_shadows_and_speed() {
    let (stacks, slices) = (160u32, 320u32);
    let (sc, sr) = (DVec3::new(0.0, 2.0, 0.0), 1.0);
    let mut scene = Scene::default();
    scene.add_ground(0.0, 10.0);
    scene.meshes.push(uv_sphere(sc, sr, stacks, slices));
    let tris = scene.triangles();
    assert!(tris.len() > 100_000);
    let camera = Camera {
        eye: DVec3::new(6.0, 7.0, 5.0),
        target: DVec3::new(0.0, 0.5, 0.0),
        up: DVec3::Y,
        fov_y_deg: 50.0,
        width: 128,
        height: 128,
    };
    let t0 = std::time::Instant::now();
    let oracle = Oracle::new(&tris, camera.eye);
    let build = t0.elapsed();
    let view = oracle.primary_view_samples(&camera);
    let mut rng = Rng(3);
    let (lc, lr) = (DVec3::new(0.5, 8.0, 0.3), 1.0);
    let lights: Vec<DVec3> = (0..64)
        .map(|_| {
            let (r, a) = (lr * rng.next().sqrt(), TAU * rng.next());
            lc + DVec3::new(r * a.cos(), 0.0, r * a.sin())
        })
        .collect();
    let light = LightSamples::Positions(lights.clone());
    let t1 = std::time::Instant::now();
    let rays0 = oracle.shadow_rays_cast();
    let progress = indicatif::ProgressBar::hidden();
    let vis = oracle.visibility(&view, &light, Some(&progress));
    let secs = t1.elapsed().as_secs_f64();
    assert_eq!(progress.position(), 128, "one step per row");
    let rays = oracle.shadow_rays_cast() - rays0;
    eprintln!(
        "oracle: {} triangles, BVH build {:.1} ms, {} shadow rays in {:.3} s = {:.2} M rays/s",
        tris.len(),
        build.as_secs_f64() * 1e3,
        rays,
        secs,
        rays as f64 / secs / 1e6
    );
    assert!(rays > 500_000);

    // Analytic check of ground pixels: a segment that passes closer to the
    // centre than the polyhedron's inner radius crosses it, one that stays
    // outside the circumscribed ball does not.
    let r_in = sr * (PI / stacks as f64 + TAU / slices as f64).cos() - 1e-9;
    let masks = oracle.visibility_masks(&view, &light);
    let (mut checked, mut ambiguous, mut umbra, mut lit) = (0, 0, 0, 0);
    for (i, s) in view.samples.iter().enumerate() {
        let Some(s) = s else { continue };
        if s.triangle > 1 {
            continue; // on the sphere
        }
        let p = s.position;
        for (k, &l) in lights.iter().enumerate() {
            let d = l - p;
            let t = ((sc - p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
            let dist = (p + d * t - sc).length();
            let bit = (masks[i][k / 64] >> (k % 64)) & 1 == 1;
            if dist > r_in && dist < sr {
                ambiguous += 1;
                continue;
            }
            assert_eq!(
                bit,
                dist >= sr,
                "pixel {i}, light sample {k}, distance {dist}"
            );
            checked += 1;
        }
        if vis[i] == 0.0 {
            umbra += 1;
        } else if vis[i] == 1.0 {
            lit += 1;
        }
    }
    assert!(
        checked > 500_000 && ambiguous * 50 < checked,
        "{checked} {ambiguous}"
    );
    assert!(umbra > 20 && lit > 1000, "{umbra} {lit}");
}
