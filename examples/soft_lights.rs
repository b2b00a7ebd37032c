//! Several coloured area lights over the built-in demo scene: a red sphere,
//! a green disk and a blue rectangle, each with its own soft shadows,
//! rendered and written as a PNG.
//!
//! `cargo run --example soft_lights [-- OUT.png [SIZE]]` (default
//! `soft_lights.png`, 256 pixels).
use alias_free_shadows::light::{Distribution, Light, LightShape};
use alias_free_shadows::render::{Engine, FrameOptions};
use alias_free_shadows::scene::file::{self, SoftMode};
use alias_free_shadows::vulkan::ContextOptions;
use glam::{DVec2, DVec3};

fn main() -> alias_free_shadows::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = args.next().unwrap_or_else(|| "soft_lights.png".into());
    let size: u32 = args.next().and_then(|s| s.parse().ok()).unwrap_or(256);

    let mut desc = file::load("builtin:demo")?;
    desc.camera.width = size;
    desc.camera.height = size;
    let (lo, hi) = desc.scene.bounds().expect("the demo has triangles");
    let (centre, extent) = ((lo + hi) * 0.5, (hi - lo).length());
    let above = |x: f64, z: f64| centre + DVec3::new(x, 0.8, z) * extent;
    let down = |from: DVec3| (centre - from).normalize();
    let light = |shape, color| Light {
        shape,
        samples: 256,
        distribution: Distribution::Sobol,
        seed: 7,
        color,
        intensity: 0.6,
        emission: None,
        per_pixel_rotation: false,
    };
    let (red, green, blue) = (above(-0.4, 0.1), above(0.4, 0.1), above(0.0, -0.4));
    desc.lights = vec![
        light(
            LightShape::Sphere {
                position: red,
                radius: 0.06 * extent,
            },
            [1.0, 0.25, 0.2],
        ),
        light(
            LightShape::Disk {
                position: green,
                radius: 0.08 * extent,
                normal: down(green),
                tangent: DVec3::X,
            },
            [0.25, 1.0, 0.3],
        ),
        light(
            LightShape::Rect {
                position: blue,
                size: DVec2::new(0.2, 0.05) * extent,
                normal: down(blue),
                tangent: DVec3::X,
            },
            [0.25, 0.35, 1.0],
        ),
    ];
    // The default mode: exact masks through the look-up table.
    desc.shadows.mode = SoftMode::Lut;
    desc.validate()?;

    let mut engine = Engine::new(&ContextOptions::default())?;
    let frame = engine.render(&desc, FrameOptions::default())?;
    frame
        .image
        .save(&out)
        .map_err(|e| alias_free_shadows::Error::Image(format!("{out}: {e}")))?;
    for (k, v) in frame.dump.visibility.iter().enumerate() {
        let penumbra = v.iter().filter(|p| p[0] > 0.0 && p[0] < 1.0).count();
        println!("light {k}: {penumbra} pixels in penumbra");
    }
    println!("wrote {out} ({size}x{size})");
    engine.context().check_validation()
}
