//! Issue 17, textured and coloured area lights: each light sample emits the
//! emission texture's texel under it, and each channel's visibility is the
//! visible share of that channel's emission. Checked against the oracle per
//! channel on the frame's own view samples, plus the texture's mapping, the
//! dump, the picture and the errors.

use alias_free_shadows::dump::{compare, Dump};
use alias_free_shadows::light::{LightSamples, LightShape};
use alias_free_shadows::render::{render_reference, Engine, FrameOptions};
use alias_free_shadows::scene::file::{self, SceneDescription};
use alias_free_shadows::vulkan::ContextOptions;

mod common;
use common::pixels_off_the_oracle;

fn stained_glass(size: u32, samples: u32) -> SceneDescription {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/stained_glass.toml");
    let mut desc = file::load(path).unwrap();
    desc.camera.width = size;
    desc.camera.height = size;
    desc.lights[0].samples = samples;
    desc
}

/// The sample colours follow the texture: the quarter a sample lies in (in
/// the light's tangent / bitangent frame) gives its colour, and the white
/// cross is white.
#[test]
fn samples_take_the_texel_under_them() {
    let desc = stained_glass(8, 256);
    let light = &desc.lights[0];
    let colors = light.sample_colors().expect("a textured light");
    let LightShape::Rect {
        position,
        size,
        normal,
        tangent,
    } = light.shape
    else {
        panic!("a rect light")
    };
    let LightSamples::Positions(points) = light.light_samples() else {
        panic!()
    };
    let bitangent = normal.cross(tangent);
    let mut seen = [0; 5];
    for (p, c) in points.iter().zip(&colors) {
        // Texel column and row of the 8x8 image (row 0 at +bitangent).
        let u = 0.5 + (*p - position).dot(tangent) / size.x;
        let v = 0.5 + (*p - position).dot(bitangent) / size.y;
        let (x, y) = ((u * 8.0).floor() as i32, ((1.0 - v) * 8.0).floor() as i32);
        let class = if x == 3 || x == 4 || y == 3 || y == 4 {
            0 // white
        } else if x < 3 && y < 3 {
            1 // red
        } else if x > 4 && y < 3 {
            2 // green
        } else if x < 3 {
            3 // blue
        } else {
            4 // amber
        };
        seen[class] += 1;
        let ok = match class {
            0 => c.iter().all(|&v| v > 0.99),
            1 => c[0] > 0.7 && c[1] < 0.05 && c[2] < 0.05,
            2 => c[1] > 0.5 && c[0] < 0.05 && c[2] < 0.05,
            3 => c[2] > 0.8 && c[0] < 0.05 && c[1] < 0.1,
            _ => c[0] > 0.9 && c[1] > 0.3 && c[2] < 0.05,
        };
        assert!(ok, "sample at ({x}, {y}), class {class}: colour {c:?}");
    }
    assert!(
        seen.iter().all(|&n| n > 10),
        "every region sampled: {seen:?}"
    );
}

/// Per channel, the GPU frame's visibility is the weighted count of the
/// oracle's visible samples at every pixel whose count agrees; the others
/// lie in the bands. The dump holds the channels, and a coloured shadow
/// differs from channel to channel.
#[test]
fn channels_match_the_oracle() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = stained_glass(48, 128);
    let colors = desc.lights[0].sample_colors().unwrap();
    let frame = engine.render(&desc, FrameOptions::default()).unwrap();
    engine.context().check_validation().unwrap();
    let rgb = frame.dump.visibility_rgb[0]
        .as_ref()
        .expect("per-channel visibility");
    let (mut compared, mut coloured) = (0, 0);
    let (off, pixels) = pixels_off_the_oracle(&desc, &frame, 0, |i, mask| {
        // Independent of the library's sum: per channel, f64 over the bits.
        let mut want = [0.0f64; 3];
        let mut all = [0.0f64; 3];
        for (j, c) in colors.iter().enumerate() {
            for k in 0..3 {
                all[k] += c[k] as f64;
                if !mask.is_empty() && mask[j / 64] >> (j % 64) & 1 == 1 {
                    want[k] += c[k] as f64;
                }
            }
        }
        for k in 0..3 {
            let w = (want[k] / all[k]) as f32;
            assert!(
                (rgb[i][k] - w).abs() <= 1e-6,
                "pixel {i} channel {k}: {} against the oracle's {w}",
                rgb[i][k]
            );
        }
        compared += 1;
        let (lo, hi) = (
            rgb[i][..3].iter().cloned().fold(f32::MAX, f32::min),
            rgb[i][..3].iter().cloned().fold(0.0, f32::max),
        );
        if hi - lo > 0.05 {
            coloured += 1;
        }
    });
    assert_eq!(off, 0, "{off} of {pixels} pixels off the oracle");
    assert!(compared > 1000, "{compared} pixels compared");
    assert!(
        coloured > 20,
        "only {coloured} pixels with coloured penumbrae"
    );

    // The dump: written and read back with its channels.
    let dir = tempfile::tempdir().unwrap();
    frame.dump.write(dir.path(), &frame.image).unwrap();
    assert!(dir.path().join("visibility_0_rgb.exr").is_file());
    let back = Dump::read(dir.path()).unwrap();
    assert_eq!(back.visibility_rgb, frame.dump.visibility_rgb);

    // `afs compare` compares the channels too: the oracle's frame (its own
    // view samples) is close, and a changed channel shows.
    let reference = render_reference(&desc, FrameOptions::default()).unwrap();
    let rows = compare(&frame.dump, &reference.dump).unwrap();
    let c = rows[0].channels.as_ref().expect("both dumps have channels");
    assert!(c.rmse.iter().all(|&e| e < 0.05), "{c:?}");
    let mut changed = frame.dump.clone();
    for p in changed.visibility_rgb[0].as_mut().unwrap() {
        p[1] = (p[1] + 0.25).min(1.0);
    }
    let rows = compare(&frame.dump, &changed).unwrap();
    let c = rows[0].channels.as_ref().unwrap();
    assert_eq!((c.rmse[0], c.rmse[2]), (0.0, 0.0));
    assert!(c.rmse[1] > 0.05 && c.max_abs[1] > 0.2, "{c:?}");
    assert_eq!(rows[0].rmse, 0.0, "the visible fraction did not change");
}

/// Only rect and disk lights take a texture, and a missing file is named.
#[test]
fn texture_errors_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let png = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/stained_glass.png");
    std::fs::copy(png, dir.path().join("glass.png")).unwrap();
    let scene = |light: &str| {
        let path = dir.path().join("s.toml");
        std::fs::write(
            &path,
            format!("scene = \"builtin:plane_sphere\"\n[[light]]\n{light}"),
        )
        .unwrap();
        file::load(path.to_str().unwrap())
            .map(|_| ())
            .unwrap_err()
            .to_string()
    };
    let e = scene(
        "kind = \"sphere\"\nposition = [0.0, 5.0, 0.0]\nradius = 0.5\ntexture = \"glass.png\"\n",
    );
    assert!(
        e.contains("only rect and disk lights take an emission texture"),
        "{e}"
    );
    let e = scene("kind = \"disk\"\nposition = [0.0, 5.0, 0.0]\nradius = 0.5\nnormal = [0.0, -1.0, 0.0]\ntexture = \"nothing.png\"\n");
    assert!(e.contains("light 0") && e.contains("nothing.png"), "{e}");
}

/// Accumulated frames of a textured light: each channel is the visible
/// emission of all the frames' samples over their total emission (each
/// frame's samples emit a different total, so this is not the mean of the
/// frames' shares).
#[test]
fn accumulated_channels_weigh_each_frame_by_its_emission() {
    use alias_free_shadows::render::Accumulator;
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let desc = stained_glass(24, 32);
    let mut acc = Accumulator::new();
    let n = desc.camera.width as usize * desc.camera.height as usize;
    let (mut seen, mut all) = (vec![[0.0f64; 3]; n], [0.0f64; 3]);
    let mut totals = Vec::new();
    for _ in 0..3 {
        let d = acc.next_frame(&desc);
        let colors = d.lights[0].sample_colors().unwrap();
        let total: [f64; 3] =
            std::array::from_fn(|k| colors.iter().map(|c| c[k] as f64).sum::<f64>());
        let frame = engine.render(&d, FrameOptions::default()).unwrap();
        let rgb = frame.dump.visibility_rgb[0].as_ref().unwrap();
        for (s, p) in seen.iter_mut().zip(rgb) {
            for k in 0..3 {
                s[k] += p[k] as f64 * total[k];
            }
        }
        for k in 0..3 {
            all[k] += total[k];
        }
        totals.push(total);
        acc.add(&frame);
    }
    engine.context().check_validation().unwrap();
    assert_ne!(
        totals[0], totals[1],
        "the frames' samples emit different totals"
    );
    let got = &acc.visibility_rgb()[0].clone().unwrap();
    for (i, (g, s)) in got.iter().zip(&seen).enumerate() {
        for k in 0..3 {
            let want = (s[k] / all[k]) as f32;
            assert!(
                (g[k] - want).abs() <= 1e-6,
                "pixel {i} channel {k}: {} against {want}",
                g[k]
            );
        }
    }
}
