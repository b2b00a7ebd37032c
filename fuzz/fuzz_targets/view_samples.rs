//! The public API's view-sample input: bytes decoded into an eye, view
//! samples (position, normal, triangle id), a light of any kind, shadow
//! settings and a small scene (which may be corrupted), then the CPU-side
//! checks that `Engine::hard_shadows` and `Engine::soft_shadows` make
//! before any GPU work (`render::validate_shadow_inputs`, then
//! `ShadowSettings::validate` for lights with extent), then the CPU
//! conversion to what the GPU would receive.
//!
//! Driving lavapipe from inside libFuzzer is impractical (seconds per
//! Vulkan context, a few hundred ms per call), so instead the invariant
//! is checked: whatever the checks accept converts to finite `f32` GPU
//! inputs (camera-relative positions, unit normals, light samples and
//! their bounds). A failed invariant panics, which libFuzzer reports.
#![no_main]

use alias_free_shadows::cpu::light_view::LightView;
use alias_free_shadows::light::{Distribution, Light, LightShape, MAX_LIGHT_SAMPLES};
use alias_free_shadows::oracle::{ViewSample, NO_TRIANGLE};
use alias_free_shadows::render::{self, gpu_triangles, light_view, soft_light};
use alias_free_shadows::scene::file::{LightTexels, ShadowSettings, SoftMode};
use alias_free_shadows::scene::{Mesh, Scene};
use glam::{DVec2, DVec3, Vec3};
use libfuzzer_sys::fuzz_target;

/// Reads values from the input; past its end, zeros.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((b, rest)) => {
                self.0 = rest;
                *b
            }
            None => 0,
        }
    }

    fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }

    /// A number: raw bits, a small value, or one of the edge cases.
    fn f64(&mut self) -> f64 {
        const EDGES: [f64; 16] = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e18,
            1.000_000_000_000_001e18,
            -1e18,
            1e154,
            1e300,
            f32::MAX as f64,
            f32::MIN_POSITIVE as f64,
            1e-300,
            f64::MIN_POSITIVE,
        ];
        match self.u8() % 4 {
            0 => f64::from_bits(u64::from_le_bytes(std::array::from_fn(|_| self.u8()))),
            1 => EDGES[(self.u8() % 16) as usize],
            _ => (self.u8() as i8) as f64 / 16.0,
        }
    }

    fn f32(&mut self) -> f32 {
        self.f64() as f32
    }

    fn vec3(&mut self) -> DVec3 {
        DVec3::new(self.f64(), self.f64(), self.f64())
    }
}

fn square() -> Scene {
    let positions = vec![
        DVec3::new(-0.5, 1.0, -0.5),
        DVec3::new(0.5, 1.0, -0.5),
        DVec3::new(0.5, 1.0, 0.5),
        DVec3::new(-0.5, 1.0, 0.5),
    ];
    Scene {
        meshes: vec![Mesh::new("square", positions, vec![[0, 3, 2], [0, 2, 1]])],
        ..Default::default()
    }
}

/// A light-texel setting: auto for one value in 64, else a fixed number
/// (in range or not).
fn texels(v: u32) -> LightTexels {
    if v.is_multiple_of(64) {
        LightTexels::Auto
    } else {
        LightTexels::Fixed(v % 20000)
    }
}

fn light(b: &mut Bytes) -> Light {
    let kind = b.u8() % 7;
    let distribution = [
        Distribution::Uniform,
        Distribution::Stratified,
        Distribution::Poisson,
        Distribution::Sobol,
    ][(b.u8() % 4) as usize];
    // Counts past the limit stay (the checks reject them); within it, at
    // most 64, so that generating the samples stays fast.
    let raw = b.u32();
    let samples = if raw > MAX_LIGHT_SAMPLES {
        raw
    } else {
        raw % 65
    };
    let position = b.vec3();
    let shape = match kind {
        0 => LightShape::Point { position },
        1 => LightShape::Directional {
            direction: b.vec3(),
        },
        2 => LightShape::Sphere {
            position,
            radius: b.f64(),
        },
        3 => LightShape::Disk {
            position,
            radius: b.f64(),
            normal: b.vec3(),
            tangent: b.vec3(),
        },
        4 => LightShape::Rect {
            position,
            size: DVec2::new(b.f64(), b.f64()),
            normal: b.vec3(),
            tangent: b.vec3(),
        },
        5 => LightShape::Ellipsoid {
            position,
            semi_axes: b.vec3(),
            normal: b.vec3(),
            tangent: b.vec3(),
        },
        _ => {
            let n = b.u8() % 9;
            LightShape::Explicit {
                positions: (0..n).map(|_| b.vec3()).collect(),
            }
        }
    };
    Light {
        shape,
        samples,
        distribution,
        seed: b.u32() as u64,
        color: [b.f32(), b.f32(), b.f32()],
        intensity: b.f32(),
        emission: None,
        per_pixel_rotation: false,
    }
}

fn finite3(v: Vec3) -> bool {
    v.is_finite()
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let eye = b.vec3();
    let light = light(&mut b);
    let settings = ShadowSettings {
        light_texels: texels(b.u32()),
        soft_light_texels: texels(b.u32()),
        mode: match b.u8() % 3 {
            0 => SoftMode::Lut,
            1 => SoftMode::Exact,
            _ => SoftMode::Approx,
        },
        lut_resolution: b.u32() % 1100,
        clusters: b.u8() % 2 == 0,
        wedge_rule: b.u8() % 2 == 0,
    };
    let mut scene = square();
    match b.u8() % 4 {
        1 => {
            let k = (b.u8() % 4) as usize;
            scene.meshes[0].positions[k] = b.vec3();
        }
        2 => scene.meshes[0].indices[1][2] = b.u32() % 8,
        _ => {}
    }
    let n = b.u8() % 17;
    let samples: Vec<Option<ViewSample>> = (0..n)
        .map(|_| {
            let present = b.u8();
            let position = b.vec3();
            let normal = b.vec3();
            let triangle = match b.u8() % 3 {
                0 => NO_TRIANGLE,
                1 => b.u32() % 4,
                _ => b.u32(),
            };
            (present % 8 != 0).then_some(ViewSample {
                position,
                normal,
                triangle,
            })
        })
        .collect();

    // What Engine::hard_shadows and Engine::soft_shadows check first.
    if render::validate_shadow_inputs(&scene, eye, &samples, &light).is_err() {
        return;
    }
    // Accepted: then everything the GPU would get is finite.
    let triangles = scene.triangle_count();
    for s in samples.iter().flatten() {
        let p = (s.position - eye).as_vec3();
        let n = s.normal.as_vec3().normalize_or_zero();
        assert!(finite3(p), "position {s:?} -> {p:?}");
        assert!(n != Vec3::ZERO && finite3(n), "normal {s:?} -> {n:?}");
        assert!(s.triangle == NO_TRIANGLE || (s.triangle as usize) < triangles);
        // Squared camera-relative distances stay finite in f32.
        assert!(p.length_squared().is_finite(), "{p:?}");
    }
    for (v, _) in gpu_triangles(&scene, eye) {
        assert!(v.iter().all(|v| finite3(*v)), "{v:?}");
    }
    match light_view(&light, eye) {
        Some(LightView::Point { position }) => {
            assert!(finite3(position) && position.length_squared().is_finite())
        }
        Some(LightView::Directional { direction }) => {
            assert!(finite3(direction) && direction.length_squared() > 0.0)
        }
        None => {
            if settings.validate().is_err() {
                return;
            }
            let (sl, lv) = soft_light(&light, eye, &settings).expect("a light with extent");
            assert!(!sl.samples.is_empty());
            assert!(sl.samples.iter().all(|s| finite3(*s)), "{light:?}");
            let (c, r) = sl.bounds();
            assert!(
                finite3(c) && r.is_finite() && r > 0.0,
                "{light:?}: {c:?} {r}"
            );
            let LightView::Point { position } = lv else {
                panic!("soft shadows are seen from a point")
            };
            assert!(finite3(position));
        }
    }
});
