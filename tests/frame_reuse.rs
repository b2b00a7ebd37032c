//! Frames that reuse what did not change (issue 17 item 5):
//! `Engine::render_reusing` against frames rendered from scratch by a
//! second engine, after each kind of change; the statistics say what was
//! reused.

use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::render::{Engine, Frame, FrameOptions, FrameReuse, Generations};
use alias_free_shadows::scene::file::{self, SceneDescription};
use alias_free_shadows::stats::{Reused, Stats};
use alias_free_shadows::vulkan::ContextOptions;
use glam::DVec3;

fn reused(f: &Frame) -> Reused {
    match &f.stats {
        Stats::Gpu(s) => s
            .reused
            .clone()
            .expect("render_reusing says what it reused"),
        _ => panic!("a GPU frame"),
    }
}

/// The frame's host time for its inputs (0 where it reused its view).
fn inputs_ms(f: &Frame) -> f64 {
    match &f.stats {
        Stats::Gpu(s) => s.ms.inputs_cpu,
        _ => panic!("a GPU frame"),
    }
}

/// Every light's visibility, bit for bit, and the image.
fn assert_same(a: &Frame, b: &Frame, what: &str) {
    assert_eq!(a.dump.visibility.len(), b.dump.visibility.len());
    for (k, (x, y)) in a.dump.visibility.iter().zip(&b.dump.visibility).enumerate() {
        let differ = x
            .iter()
            .zip(y)
            .filter(|(p, q)| p[0].to_bits() != q[0].to_bits())
            .count();
        assert_eq!(differ, 0, "{what}: light {k}: {differ} pixels differ");
    }
    assert!(a.image == b.image, "{what}: images differ");
}

fn scene() -> SceneDescription {
    let mut desc = file::load("builtin:demo").unwrap();
    desc.camera.width = 40;
    desc.camera.height = 40;
    let base = desc.lights[0].clone();
    let p = base.center().unwrap();
    desc.lights = vec![
        Light {
            shape: LightShape::Sphere {
                position: p,
                radius: 0.4,
            },
            samples: 64,
            color: [1.0, 0.6, 0.3],
            ..base.clone()
        },
        Light {
            shape: LightShape::Sphere {
                position: p + DVec3::new(-2.0, 0.0, 1.0),
                radius: 0.3,
            },
            samples: 64,
            color: [0.3, 0.6, 1.0],
            ..base
        },
    ];
    desc
}

#[test]
fn reused_frames_equal_frames_from_scratch() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut fresh = Engine::new(&ContextOptions::validated()).unwrap();
    let opts = FrameOptions::default();
    let mut desc = scene();
    let mut gens = Generations::new(desc.lights.len());
    let mut reuse = FrameReuse::new();

    let first = engine
        .render_reusing(&desc, &gens, &mut reuse, opts)
        .unwrap();
    let want = Reused {
        frame: false,
        view_samples: false,
        lights: vec![false, false],
    };
    assert_eq!(reused(&first), want);
    assert!(inputs_ms(&first) > 0.0);
    assert_same(&first, &fresh.render(&desc, opts).unwrap(), "first frame");

    // Nothing changed: the same frame.
    let same = engine
        .render_reusing(&desc, &gens, &mut reuse, opts)
        .unwrap();
    assert_eq!(
        reused(&same),
        Reused {
            frame: true,
            view_samples: true,
            lights: vec![true, true]
        }
    );
    assert_same(&same, &first, "unchanged frame");

    // One light moved: the other light's result and the view are kept.
    if let LightShape::Sphere { position, .. } = &mut desc.lights[1].shape {
        *position += DVec3::new(0.5, 0.0, -0.3);
    }
    gens.lights[1] += 1;
    let moved = engine
        .render_reusing(&desc, &gens, &mut reuse, opts)
        .unwrap();
    assert_eq!(
        reused(&moved),
        Reused {
            frame: false,
            view_samples: true,
            lights: vec![true, false]
        }
    );
    assert_eq!(inputs_ms(&moved), 0.0, "the view's inputs were kept");
    assert_same(
        &moved,
        &fresh.render(&desc, opts).unwrap(),
        "one light moved",
    );

    // The camera moved: every light again.
    desc.camera.eye += DVec3::new(0.3, 0.2, 0.0);
    gens.camera += 1;
    let turned = engine
        .render_reusing(&desc, &gens, &mut reuse, opts)
        .unwrap();
    assert_eq!(
        reused(&turned),
        Reused {
            frame: false,
            view_samples: false,
            lights: vec![false, false]
        }
    );
    assert!(inputs_ms(&turned) > 0.0);
    assert_same(&turned, &fresh.render(&desc, opts).unwrap(), "camera moved");

    // Another frame in between overwrites the engine's buffers: a light
    // change then makes the view again (a stale view would differ).
    let other = file::load("builtin:plane_sphere").unwrap();
    let mut other = other;
    other.camera.width = 40;
    other.camera.height = 40;
    engine.render(&other, opts).unwrap();
    desc.lights[0].color = [0.9, 0.9, 0.2];
    if let LightShape::Sphere { radius, .. } = &mut desc.lights[0].shape {
        *radius = 0.6;
    }
    gens.lights[0] += 1;
    let after = engine
        .render_reusing(&desc, &gens, &mut reuse, opts)
        .unwrap();
    assert_eq!(
        reused(&after),
        Reused {
            frame: false,
            view_samples: false,
            lights: vec![false, false]
        }
    );
    assert_same(
        &after,
        &fresh.render(&desc, opts).unwrap(),
        "after another frame",
    );

    // A light count that does not match is refused.
    let e = engine
        .render_reusing(&desc, &Generations::new(1), &mut reuse, opts)
        .err()
        .expect("refused");
    assert!(e.to_string().contains("generations"), "{e}");
    engine.context().check_validation().unwrap();
    fresh.context().check_validation().unwrap();
}
