//! The public API on bad input: NaN, infinite or out-of-range view samples,
//! eyes, lights and vertices; zero and too many samples; settings out of
//! range. Each is an `Err` whose message names what is wrong, never a
//! panic, and never a Vulkan validation message (the engine runs with the
//! validation layer on and is checked after every case). After the bad
//! calls the same engine still computes a correct answer.

use alias_free_shadows::light::{Distribution, Light, LightShape, MAX_LIGHT_SAMPLES};
use alias_free_shadows::oracle::{ViewSample, NO_TRIANGLE};
use alias_free_shadows::render::{render_reference, Engine, FrameOptions};
use alias_free_shadows::scene::file::{self, ShadowSettings, SoftMode};
use alias_free_shadows::scene::{Mesh, Scene};
use alias_free_shadows::vulkan::ContextOptions;
use glam::{DVec2, DVec3};

const NAN: f64 = f64::NAN;
const INF: f64 = f64::INFINITY;

/// A unit square occluder at y = 1 over the origin; the view samples lie on
/// the ground y = 0 (not part of the scene).
fn scene() -> Scene {
    let positions = vec![
        DVec3::new(-0.5, 1.0, -0.5),
        DVec3::new(0.5, 1.0, -0.5),
        DVec3::new(0.5, 1.0, 0.5),
        DVec3::new(-0.5, 1.0, 0.5),
    ];
    let mut m = Mesh::new("square", positions, vec![[0, 3, 2], [0, 2, 1]]);
    m.closed = false;
    Scene {
        meshes: vec![m],
        ..Default::default()
    }
}

const EYE: DVec3 = DVec3::new(0.0, 3.0, 4.0);

/// 8 x 8 samples on the ground, facing up; the middle ones under the square.
fn samples() -> Vec<Option<ViewSample>> {
    (0..64)
        .map(|i| {
            let (x, z) = ((i % 8) as f64 - 3.5, (i / 8) as f64 - 3.5);
            Some(ViewSample::user(
                DVec3::new(x * 0.3, 0.0, z * 0.3),
                DVec3::Y,
            ))
        })
        .collect()
}

fn light(shape: LightShape, samples: u32) -> Light {
    Light {
        shape,
        samples,
        distribution: Distribution::Poisson,
        seed: 7,
        color: [1.0; 3],
        intensity: 1.0,
        emission: None,
        per_pixel_rotation: false,
    }
}

fn point() -> Light {
    light(
        LightShape::Point {
            position: DVec3::new(0.0, 4.0, 0.0),
        },
        1,
    )
}

fn sphere() -> Light {
    light(
        LightShape::Sphere {
            position: DVec3::new(0.0, 4.0, 0.0),
            radius: 0.3,
        },
        64,
    )
}

/// Every light shape with extent, valid, for the field-by-field cases.
fn area_lights() -> Vec<Light> {
    let (n, t) = (DVec3::NEG_Y, DVec3::X);
    let p = DVec3::new(0.0, 4.0, 0.0);
    vec![
        sphere(),
        light(
            LightShape::Disk {
                position: p,
                radius: 0.3,
                normal: n,
                tangent: t,
            },
            32,
        ),
        light(
            LightShape::Rect {
                position: p,
                size: DVec2::new(0.5, 0.3),
                normal: n,
                tangent: t,
            },
            32,
        ),
        light(
            LightShape::Ellipsoid {
                position: p,
                semi_axes: DVec3::new(0.3, 0.2, 0.1),
                normal: n,
                tangent: t,
            },
            32,
        ),
        light(
            LightShape::Explicit {
                positions: vec![p, p + DVec3::X * 0.1, p + DVec3::Z * 0.1],
            },
            3,
        ),
    ]
}

/// Bad values for a field: NaN, both infinities, and a finite value too
/// far from the camera for the f32 GPU passes.
const BAD: [f64; 4] = [NAN, INF, -INF, 1e300];

/// The light with one of its fields (named as in the error) replaced by `v`.
fn with_bad_field(l: &Light, v: f64) -> Vec<(String, Light)> {
    let mut out = Vec::new();
    let bad3 = DVec3::new(0.0, v, 0.0);
    let mut push = |name: &str, f: &dyn Fn(&mut Light)| {
        let mut m = l.clone();
        f(&mut m);
        out.push((name.to_string(), m));
    };
    match &l.shape {
        LightShape::Point { .. } => {
            push("position", &|m| {
                m.shape = LightShape::Point { position: bad3 }
            });
        }
        LightShape::Directional { .. } => {
            push("direction", &|m| {
                m.shape = LightShape::Directional { direction: bad3 }
            });
        }
        LightShape::Sphere { position, radius } => {
            let (p, r) = (*position, *radius);
            push("position", &|m| {
                m.shape = LightShape::Sphere {
                    position: p + bad3,
                    radius: r,
                }
            });
            push("radius", &|m| {
                m.shape = LightShape::Sphere {
                    position: p,
                    radius: v,
                }
            });
        }
        LightShape::Disk {
            position,
            radius,
            normal,
            tangent,
        } => {
            let (p, r, n, t) = (*position, *radius, *normal, *tangent);
            let disk = |p, r, n, t| LightShape::Disk {
                position: p,
                radius: r,
                normal: n,
                tangent: t,
            };
            push("position", &|m| m.shape = disk(p + bad3, r, n, t));
            push("radius", &|m| m.shape = disk(p, v, n, t));
            push("normal", &|m| m.shape = disk(p, r, n + bad3, t));
            push("tangent", &|m| m.shape = disk(p, r, n, t + bad3));
        }
        LightShape::Rect {
            position,
            size,
            normal,
            tangent,
        } => {
            let (p, s, n, t) = (*position, *size, *normal, *tangent);
            let rect = |p, s, n, t| LightShape::Rect {
                position: p,
                size: s,
                normal: n,
                tangent: t,
            };
            push("position", &|m| m.shape = rect(p + bad3, s, n, t));
            push("size", &|m| m.shape = rect(p, DVec2::new(s.x, v), n, t));
            push("normal", &|m| m.shape = rect(p, s, n + bad3, t));
            push("tangent", &|m| m.shape = rect(p, s, n, t + bad3));
        }
        LightShape::Ellipsoid {
            position,
            semi_axes,
            normal,
            tangent,
        } => {
            let (p, a, n, t) = (*position, *semi_axes, *normal, *tangent);
            let ell = |p, a, n, t| LightShape::Ellipsoid {
                position: p,
                semi_axes: a,
                normal: n,
                tangent: t,
            };
            push("position", &|m| m.shape = ell(p + bad3, a, n, t));
            push("semi_axes", &|m| m.shape = ell(p, a + bad3, n, t));
            push("normal", &|m| m.shape = ell(p, a, n + bad3, t));
            push("tangent", &|m| m.shape = ell(p, a, n, t + bad3));
        }
        LightShape::Explicit { positions } => {
            let mut ps = positions.clone();
            ps[1] += bad3;
            push("positions", &|m| {
                m.shape = LightShape::Explicit {
                    positions: ps.clone(),
                }
            });
        }
    }
    if v.is_nan() || v.is_infinite() || v.abs() > f32::MAX as f64 {
        let c = v as f32;
        push("color", &|m| m.color = [1.0, c, 1.0]);
        push("intensity", &|m| m.intensity = c);
    }
    out
}

fn assert_err<T: std::fmt::Debug>(
    r: alias_free_shadows::Result<T>,
    needles: &[&str],
    what: &str,
) -> String {
    let e = match r {
        Ok(v) => panic!("{what}: expected an error, got {v:?}"),
        Err(e) => e.to_string(),
    };
    eprintln!("{what}: {e}");
    for n in needles {
        assert!(e.contains(n), "{what}: the error should mention {n:?}: {e}");
    }
    assert!(!e.contains("panicked"), "{what}: {e}");
    e
}

/// Runs `f` and fails when it panics, naming the case.
fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> T {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(v) => v,
        Err(_) => panic!("{what}: panicked"),
    }
}

fn engine() -> Engine {
    Engine::new(&ContextOptions::validated()).unwrap()
}

#[test]
fn hard_shadows_reject_bad_view_samples_eyes_and_scenes() {
    let mut engine = engine();
    let (scene, light) = (scene(), point());
    let good = engine
        .hard_shadows(&scene, EYE, &samples(), &light, 64)
        .unwrap();
    assert_eq!(good.lit.len(), 64);
    // Some samples under the square are shadowed, the corners are lit.
    assert_eq!(good.lit[0], Some(true));
    assert!(good.lit.contains(&Some(false)));

    // Non-finite and out-of-range positions and normals, at sample 5.
    let cases: Vec<(&str, DVec3, DVec3, &[&str])> = vec![
        (
            "NaN position",
            DVec3::new(NAN, 0.0, 0.0),
            DVec3::Y,
            &["view sample 5", "not finite"],
        ),
        (
            "inf position",
            DVec3::new(0.0, INF, 0.0),
            DVec3::Y,
            &["view sample 5", "not finite"],
        ),
        (
            "-inf position",
            DVec3::new(0.0, 0.0, -INF),
            DVec3::Y,
            &["view sample 5", "not finite"],
        ),
        (
            "far position",
            DVec3::new(1e300, 0.0, 0.0),
            DVec3::Y,
            &["view sample 5", "position"],
        ),
        (
            "NaN normal",
            DVec3::ZERO,
            DVec3::new(0.0, NAN, 0.0),
            &["view sample 5", "not finite"],
        ),
        (
            "inf normal",
            DVec3::ZERO,
            DVec3::new(INF, 1.0, 0.0),
            &["view sample 5", "not finite"],
        ),
        (
            "zero normal",
            DVec3::ZERO,
            DVec3::ZERO,
            &["view sample 5", "normal"],
        ),
        (
            "huge normal",
            DVec3::ZERO,
            DVec3::new(0.0, 1e300, 0.0),
            &["view sample 5", "normal"],
        ),
    ];
    for (what, p, n, needles) in cases {
        let mut s = samples();
        // Not ViewSample::user: that normalises the normal.
        s[5] = Some(ViewSample {
            position: p,
            normal: n,
            triangle: NO_TRIANGLE,
        });
        let r = no_panic(what, || engine.hard_shadows(&scene, EYE, &s, &light, 64));
        assert_err(r, needles, what);
        engine.context().check_validation().unwrap();
    }
    // A triangle id the scene does not have.
    let mut s = samples();
    s[2] = Some(ViewSample {
        position: DVec3::ZERO,
        normal: DVec3::Y,
        triangle: 2,
    });
    let r = no_panic("triangle id", || {
        engine.hard_shadows(&scene, EYE, &s, &light, 64)
    });
    assert_err(r, &["view sample 2", "triangle 2"], "triangle id");

    // The eye.
    for v in BAD {
        let eye = DVec3::new(v, 3.0, 4.0);
        let r = no_panic("eye", || {
            engine.hard_shadows(&scene, eye, &samples(), &light, 64)
        });
        assert_err(r, &["eye"], &format!("eye {eye:?}"));
    }

    // Vertices of a scene built in code: non-finite, too far, indices
    // past the vertices.
    for v in BAD {
        let mut bad = scene.clone();
        bad.meshes[0].positions[2].y = v;
        let r = no_panic("vertex", || {
            engine.hard_shadows(&bad, EYE, &samples(), &light, 64)
        });
        assert_err(r, &["square", "vertex 2"], &format!("vertex {v}"));
    }
    let mut bad = scene.clone();
    bad.meshes[0].indices[1] = [0, 2, 4];
    let r = no_panic("index", || {
        engine.hard_shadows(&bad, EYE, &samples(), &light, 64)
    });
    assert_err(r, &["square", "index 4"], "index past the vertices");

    // Light-texel resolutions.
    for texels in [0, 16385, u32::MAX] {
        let r = no_panic("light_texels", || {
            engine.hard_shadows(&scene, EYE, &samples(), &light, texels)
        });
        assert_err(r, &["light_texels"], &format!("light_texels {texels}"));
    }

    // No view samples at all, and only empty ones: nothing to do, no error.
    let r = engine.hard_shadows(&scene, EYE, &[], &light, 64).unwrap();
    assert!(r.lit.is_empty());
    let r = engine
        .hard_shadows(&scene, EYE, &[None; 5], &light, 64)
        .unwrap();
    assert_eq!(r.lit, vec![None; 5]);

    engine.context().check_validation().unwrap();
    // The engine still works and gives the same answer.
    let again = engine
        .hard_shadows(&scene, EYE, &samples(), &light, 64)
        .unwrap();
    assert_eq!(again.lit, good.lit);
    engine.context().check_validation().unwrap();
}

#[test]
fn more_view_samples_than_the_device_binds_are_split() {
    // Issue 5: more view samples than one storage buffer binds (32 bytes
    // each) run in batches, not into an error; every copy of the same
    // sample gets the answer a single sample gets.
    let mut engine = engine();
    let range = engine.context().info().limits.max_storage_buffer_range as usize;
    let n = range / 32 + 1;
    let one = vec![Some(ViewSample::user(DVec3::ZERO, DVec3::Y))];
    let s = vec![one[0]; n];
    let r = no_panic("many view samples (hard)", || {
        engine.hard_shadows(&scene(), EYE, &s, &point(), 64)
    })
    .unwrap();
    let want = engine
        .hard_shadows(&scene(), EYE, &one, &point(), 64)
        .unwrap();
    let want_hard = want.lit[0];
    assert_eq!(r.lit.len(), n);
    assert!(
        r.lit.iter().all(|l| *l == want.lit[0]),
        "hard: a batch differs"
    );
    let settings = ShadowSettings::default();
    let r = no_panic("many view samples (soft)", || {
        engine.soft_shadows(&scene(), EYE, &s, &sphere(), &settings)
    })
    .unwrap();
    let want = engine
        .soft_shadows(&scene(), EYE, &one, &sphere(), &settings)
        .unwrap();
    assert_eq!(r.visibility.len(), n);
    assert!(
        r.visibility.iter().all(|v| *v == want.visibility[0]),
        "soft: a batch differs"
    );
    eprintln!(
        "{n} copies of one view sample, in batches: hard {:?}, soft {:?}",
        want_hard, want.visibility[0]
    );
    engine.context().check_validation().unwrap();
}

#[test]
fn every_light_field_is_checked_by_both_paths() {
    let mut engine = engine();
    let (scene, s) = (scene(), samples());
    let settings = ShadowSettings {
        lut_resolution: 16,
        ..Default::default()
    };
    let good = engine
        .soft_shadows(&scene, EYE, &s, &sphere(), &settings)
        .unwrap();
    let directional = light(
        LightShape::Directional {
            direction: DVec3::NEG_Y,
        },
        1,
    );
    let mut lights = vec![point(), directional];
    lights.extend(area_lights());
    let mut cases = 0;
    for l in &lights {
        for v in BAD {
            for (field, bad) in with_bad_field(l, v) {
                let what = format!("{:?} light, `{field}` = {v}", l.shape);
                let r = no_panic(&what, || {
                    if l.is_area() {
                        engine
                            .soft_shadows(&scene, EYE, &s, &bad, &settings)
                            .map(|_| ())
                    } else {
                        engine.hard_shadows(&scene, EYE, &s, &bad, 64).map(|_| ())
                    }
                });
                // The first word of a `size` or `semi_axes` field is enough.
                assert_err(r, &[&field], &what);
                cases += 1;
            }
        }
        engine.context().check_validation().unwrap();
    }
    assert!(cases > 80, "{cases} cases");

    // Sample counts: zero and more than supported.
    for (l, n) in [
        (sphere(), 0),
        (sphere(), MAX_LIGHT_SAMPLES + 1),
        (sphere(), u32::MAX),
        (point(), 0),
        (point(), u32::MAX),
    ] {
        let bad = Light { samples: n, ..l };
        let what = format!("{:?} with {n} samples", bad.shape);
        let r = no_panic(&what, || {
            if bad.is_area() {
                engine
                    .soft_shadows(&scene, EYE, &s, &bad, &settings)
                    .map(|_| ())
            } else {
                engine.hard_shadows(&scene, EYE, &s, &bad, 64).map(|_| ())
            }
        });
        assert_err(r, &["samples"], &what);
    }
    // Explicit lights with no positions or more than supported.
    let p = DVec3::new(0.0, 4.0, 0.0);
    for k in [0usize, MAX_LIGHT_SAMPLES as usize + 1] {
        let bad = light(
            LightShape::Explicit {
                positions: vec![p; k],
            },
            // A valid count: the positions are what is wrong.
            1,
        );
        let r = no_panic("explicit", || {
            engine.soft_shadows(&scene, EYE, &s, &bad, &settings)
        });
        assert_err(r, &["explicit", "positions"], &format!("{k} positions"));
    }
    // The wrong path for the light.
    let r = engine.hard_shadows(&scene, EYE, &s, &sphere(), 64);
    assert_err(r, &["point or directional"], "area light, hard path");
    let r = engine.soft_shadows(&scene, EYE, &s, &point(), &settings);
    assert_err(r, &["extent"], "point light, soft path");

    // Settings out of range.
    for (bad, key) in [
        (
            ShadowSettings {
                soft_light_texels: 0.into(),
                ..settings
            },
            "soft_light_texels",
        ),
        (
            ShadowSettings {
                soft_light_texels: (1 << 20).into(),
                ..settings
            },
            "soft_light_texels",
        ),
        (
            ShadowSettings {
                lut_resolution: 0,
                ..settings
            },
            "lut_resolution",
        ),
        (
            ShadowSettings {
                lut_resolution: 100_000,
                ..settings
            },
            "lut_resolution",
        ),
        (
            ShadowSettings {
                lut_resolution: 100_000,
                mode: SoftMode::Exact,
                ..settings
            },
            "lut_resolution",
        ),
    ] {
        let r = no_panic(key, || {
            engine.soft_shadows(&scene, EYE, &s, &sphere(), &bad)
        });
        assert_err(r, &[key], &format!("{bad:?}"));
    }
    engine.context().check_validation().unwrap();
    let again = engine
        .soft_shadows(&scene, EYE, &s, &sphere(), &settings)
        .unwrap();
    assert_eq!(again.visibility, good.visibility);
    engine.context().check_validation().unwrap();
}

#[test]
fn frames_of_bad_scene_descriptions_are_errors() {
    let mut engine = engine();
    let mut desc = file::load("builtin:plane_sphere").unwrap();
    desc.camera.width = 16;
    desc.camera.height = 16;
    assert!(engine.render(&desc, FrameOptions::default()).is_ok());
    let mut cases: Vec<(String, file::SceneDescription, &str)> = Vec::new();
    for v in BAD {
        let mut d = desc.clone();
        d.lights[0].shape = LightShape::Point {
            position: DVec3::new(0.0, v, 0.0),
        };
        cases.push((format!("light position {v}"), d, "position"));
        let mut d = desc.clone();
        d.camera.eye.x = v;
        cases.push((format!("eye {v}"), d, "eye"));
        // A target or up vector far away is only a direction.
        if !v.is_finite() {
            let mut d = desc.clone();
            d.camera.target.z = v;
            cases.push((format!("target {v}"), d, "target"));
            let mut d = desc.clone();
            d.camera.up.y = v;
            cases.push((format!("up {v}"), d, "up"));
        }
        let mut d = desc.clone();
        d.camera.fov_y_deg = v;
        cases.push((format!("fov {v}"), d, "fov_y_deg"));
        let mut d = desc.clone();
        d.scene.meshes[0].positions[0].x = v;
        cases.push((format!("vertex {v}"), d, "vertex 0"));
    }
    // Finite, but so far that the view direction overflows.
    let mut d = desc.clone();
    d.camera.target = DVec3::new(1e300, 0.0, 1e300);
    cases.push(("target [1e300, 0, 1e300]".into(), d, "target"));
    for (w, h) in [(0, 16), (16, 0), (100_000, 16), (16, u32::MAX)] {
        let mut d = desc.clone();
        d.camera.width = w;
        d.camera.height = h;
        cases.push((format!("{w}x{h}"), d, "size"));
    }
    for (what, d, needle) in &cases {
        let r = no_panic(what, || {
            engine.render(d, FrameOptions::default()).map(|_| ())
        });
        assert_err(r, &[needle], what);
        let r = no_panic(what, || {
            render_reference(d, FrameOptions::default()).map(|_| ())
        });
        assert_err(r, &[needle], &format!("{what} (reference)"));
    }
    engine.context().check_validation().unwrap();
}
