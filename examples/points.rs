//! The visibility of your own points: a square caster over a grid of floor
//! points, under a point light (hard shadows) and a sphere light (soft),
//! printed as characters. `cargo run --example points`
use alias_free_shadows::light::{Distribution, Light, LightShape};
use alias_free_shadows::oracle::ViewSample;
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::{LightTexels, ShadowSettings};
use alias_free_shadows::scene::{Mesh, Scene};
use alias_free_shadows::vulkan::ContextOptions;
use glam::DVec3;

fn main() -> alias_free_shadows::Result<()> {
    // The caster: a unit square 1 above the floor (y = 0).
    let square = [
        [-0.5, 1.0, -0.5],
        [0.5, 1.0, -0.5],
        [0.5, 1.0, 0.5],
        [-0.5, 1.0, 0.5],
    ];
    let positions = square.iter().map(|&p| DVec3::from_array(p)).collect();
    let scene = Scene {
        meshes: vec![Mesh::new("square", positions, vec![[0, 1, 2], [0, 2, 3]])],
        ..Default::default()
    };
    // The points: a 40 x 20 grid on the floor, normals up.
    let (w, h) = (40, 20);
    let points: Vec<Option<ViewSample>> = (0..w * h)
        .map(|i| {
            let (x, z) = (
                (i % w) as f64 / w as f64 - 0.5,
                (i / w) as f64 / h as f64 - 0.5,
            );
            Some(ViewSample::user(
                DVec3::new(3.0 * x, 0.0, 3.0 * z),
                DVec3::Y,
            ))
        })
        .collect();
    let eye = DVec3::new(0.0, 5.0, 5.0);
    let mut engine = Engine::new(&ContextOptions::default())?;

    let light = |shape, samples| Light {
        shape,
        samples,
        distribution: Distribution::Sobol,
        seed: 1,
        color: [1.0; 3],
        intensity: 1.0,
        emission: None,
        per_pixel_rotation: false,
    };
    let centre = DVec3::new(0.3, 3.0, 0.0);
    let hard = engine.hard_shadows(
        &scene,
        eye,
        &points,
        &light(LightShape::Point { position: centre }, 1),
        LightTexels::Auto,
    )?;
    let sphere = LightShape::Sphere {
        position: centre,
        radius: 0.5,
    };
    let soft = engine.soft_shadows(
        &scene,
        eye,
        &points,
        &light(sphere, 128),
        &ShadowSettings::default(),
    )?;

    let hard: Vec<f32> = hard
        .lit
        .iter()
        .map(|l| f32::from(u8::from(l.unwrap_or(false))))
        .collect();
    let soft: Vec<f32> = soft.visibility.iter().map(|v| v.unwrap_or(0.0)).collect();
    for (name, v) in [("point light", hard), ("sphere light, 128 samples", soft)] {
        println!("{name}:");
        for row in v.chunks(w) {
            println!(
                "{}",
                row.iter()
                    .map(|&x| b"@%#*+=-:,."[(x * 9.0).round() as usize] as char)
                    .collect::<String>()
            );
        }
    }
    // With AFS_VALIDATION=1 (as CI runs it) any validation error fails here.
    engine.context().check_validation()
}
