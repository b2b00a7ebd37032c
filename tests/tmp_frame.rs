use alias_free_shadows::scene::builtin::builtin;
use alias_free_shadows::scene::Camera;
use glam::DVec3;
/// Möller-Trumbore; the hit distance along `d`.
fn hit(o: DVec3, d: DVec3, [a, b, c]: [DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 1e-9).then_some(t)
}

/// Nearest hit: (distance, mesh index).
fn trace(tris: &[([DVec3; 3], usize)], o: DVec3, d: DVec3) -> Option<(f64, usize)> {
    tris.iter()
        .filter_map(|(t, m)| hit(o, d, *t).map(|h| (h, *m)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

fn metrics(name: &str, cam: Camera, light: DVec3) -> (f64, f64, f64) {
    let b = builtin(name).unwrap();
    let mut cam = cam;
    cam.width = 24;
    cam.height = 24;
    let tris: Vec<([DVec3; 3], usize)> = b
        .scene
        .meshes
        .iter()
        .enumerate()
        .flat_map(|(mi, m)| (0..m.indices.len()).map(move |t| (m.triangle(t), mi)))
        .collect();
    let ground = b
        .scene
        .meshes
        .iter()
        .position(|m| m.name == "ground")
        .unwrap();
    let (mut covered, mut objects, mut ground_px, mut shadowed) = (0, 0, 0, 0);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let d = cam.ray_direction(x, y);
            let Some((t, m)) = trace(&tris, cam.eye, d) else {
                continue;
            };
            covered += 1;
            if m != ground {
                objects += 1;
                continue;
            }
            ground_px += 1;
            let p = cam.eye + d * t;
            let tl = light - p;
            let dist = tl.length();
            if trace(&tris, p, tl / dist).is_some_and(|(h, _)| h < dist) {
                shadowed += 1;
            }
        }
    }
    let px = (cam.width * cam.height) as f64;
    (
        covered as f64 / px,
        objects as f64 / px,
        shadowed as f64 / ground_px.max(1) as f64,
    )
}
fn orbit(target: DVec3, dist: f64, az: f64, el: f64) -> Camera {
    let (a, e) = (az.to_radians(), el.to_radians());
    let eye = target + DVec3::new(a.sin() * e.cos(), e.sin(), a.cos() * e.cos()) * dist;
    Camera {
        eye,
        target,
        up: DVec3::Y,
        fov_y_deg: 45.0,
        width: 512,
        height: 512,
    }
}
#[test]
fn explore() {
    let spec = std::env::var("EXPLORE").unwrap();
    for line in spec.split(';') {
        let v: Vec<&str> = line.split(',').collect();
        let f = |i: usize| v[i].trim().parse::<f64>().unwrap();
        let name = v[0].trim();
        let cam = orbit(DVec3::new(f(1), f(2), f(3)), f(4), f(5), f(6));
        let light = DVec3::new(f(7), f(8), f(9));
        let (c, o, s) = metrics(name, cam, light);
        println!("{line} => covered {c:.2} objects {o:.2} shadow {s:.2}");
    }
}
