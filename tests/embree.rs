//! Embree's shadow rays (the baseline of `afs bench` and `benches/embree.rs`)
//! against the CPU oracle, per (view sample, light sample) pair, fed the
//! same view samples (the oracle's primary hits rounded through
//! camera-relative f32, as the engine gets them) and the same light samples.
//!
//! Embree is f32 with a ray-origin offset, so it cannot agree everywhere:
//! the test counts the disagreements and explains each one, and fails on
//! any it cannot explain. A disagreement is explained when
//! - **contact**: the oracle, asked about the segment without its first
//!   and last `offset` (what Embree traces), gives Embree's answer: a
//!   blocker lies within the offset of the view sample (or light sample);
//! - **own surface**: the same, with the view sample's own triangle counted
//!   as a blocker: Embree, which cannot skip the sample's own triangle by
//!   id as the oracle does, hit it (the f32 view sample lies a rounding off
//!   its plane, and a ray leaving at a grazing angle crosses the plane
//!   beyond the offset: the ray tracer's self-intersection);
//! - **band**: the pair lies in one of the conformance bands
//!   (`tests/common/bands.rs`: the oracle's answer flips when the light
//!   sample moves by 1e-5 of its distance, and the other bands), where f32
//!   and f64 may differ;
//! - **grazing**: the light sample lies so near the surface's plane that a
//!   ray leaving the f32 view sample (a few ulps off that plane) may cross
//!   the plane again beyond the offset: sin(angle) below
//!   16 ulps of the sample's camera-relative distance / `offset` (the ray
//!   tracer's self-intersection; the normal rule's f32/f64 difference lies
//!   inside it too).
#![cfg(feature = "embree")]

use alias_free_shadows::baselines::embree::{light_shadows, EmbreeScene, RayMode};
use alias_free_shadows::light::LightSamples;
use alias_free_shadows::oracle::{LightTarget, Oracle, ViewSample, NO_TRIANGLE};
use alias_free_shadows::scene::file;

mod common;
use common::{bands, engine_view_samples, sphere_light};

#[derive(Default, Debug)]
struct Tally {
    pairs: u64,
    differ: u64,
    contact: u64,
    own_surface: u64,
    band: u64,
    grazing: u64,
}

fn compare(spec: &str, size: u32, samples: u32, mode: RayMode) -> Tally {
    let mut desc = file::load(spec).unwrap();
    desc.camera.width = size;
    desc.camera.height = size;
    let eye = desc.camera.eye;
    let light = sphere_light(&desc, samples);
    let oracle = Oracle::new(&desc.scene.triangles(), eye);
    let view = engine_view_samples(&oracle, &desc);
    let embree = EmbreeScene::from_scene(&desc.scene, eye, 2).unwrap();
    let got = light_shadows(&embree, &desc.scene, eye, &view.samples, &light, 2, mode).unwrap();
    let LightSamples::Positions(targets) = light.light_samples() else {
        unreachable!()
    };
    let want = oracle.visibility_masks(&view, &LightSamples::Positions(targets.clone()));
    let offset = embree.offset as f64;
    let mut t = Tally::default();
    for (i, s) in view.samples.iter().enumerate() {
        let Some(s) = s else { continue };
        for (j, &l) in targets.iter().enumerate() {
            t.pairs += 1;
            let e = got.visible[i * got.mask_words + j / 32] >> (j % 32) & 1 == 1;
            let o = want[i][j / 64] >> (j % 64) & 1 == 1;
            if e == o {
                continue;
            }
            t.differ += 1;
            let d = (l - s.position).normalize();
            let shortened = ViewSample {
                position: s.position + d * offset,
                ..*s
            };
            let end = LightTarget::Point(l - d * offset);
            let counting_own = ViewSample {
                triangle: NO_TRIANGLE,
                ..shortened
            };
            if oracle.sample_visible(&shortened, end) == e {
                t.contact += 1;
            } else if oracle.sample_visible(&counting_own, end) == e {
                t.own_surface += 1;
            } else if bands::in_any_band(&oracle, &desc.scene, eye, s, LightTarget::Point(l)) {
                t.band += 1;
            } else if s.normal.normalize().dot(d).abs()
                < 16.0 * f32::EPSILON as f64 * (s.position - eye).length() / offset
            {
                t.grazing += 1;
            } else {
                panic!("{spec}: view sample {i}, light sample {j}: Embree {e}, oracle {o}, unexplained");
            }
        }
    }
    t
}

#[test]
fn embree_agrees_with_the_oracle_but_near_contacts() {
    let mut total = Tally::default();
    for (spec, mode) in [
        ("builtin:demo", RayMode::Single),
        ("builtin:columns", RayMode::Packets8),
        ("builtin:hairball", RayMode::Single),
        ("builtin:stairs", RayMode::Packets8),
    ] {
        let t = compare(spec, 48, 64, mode);
        eprintln!(
            "{spec} ({mode:?}): {} pairs, {} differ ({:.2e}): {} contact, {} own surface, {} band, {} grazing",
            t.pairs,
            t.differ,
            t.differ as f64 / t.pairs as f64,
            t.contact,
            t.own_surface,
            t.band,
            t.grazing
        );
        total.pairs += t.pairs;
        total.differ += t.differ;
        total.contact += t.contact;
        total.own_surface += t.own_surface;
        total.band += t.band;
        total.grazing += t.grazing;
    }
    eprintln!("all: {total:?}");
    assert!(total.pairs > 500_000, "the scenes must cast enough rays");
    // Contacts are where Embree's offset hides a blocker: few, never most.
    assert!(
        (total.differ as f64) < 1e-4 * total.pairs as f64,
        "{total:?}"
    );
}
