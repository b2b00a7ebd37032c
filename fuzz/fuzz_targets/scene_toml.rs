//! TOML scene files: any bytes through the scene-file parser and its
//! validation, and `SceneDescription::validate` on what it accepts. The
//! `scene` key is resolved without file I/O: every `builtin:` scene is
//! `builtin:plane_sphere` (generating e.g. a 2M-triangle torus knot per
//! input would only slow the fuzzer down), anything else is an error. A
//! light's `texture` is read relative to `fuzz/` (the seeds name
//! `glass.png`, which is not there: the error path).
#![no_main]

use std::path::Path;
use std::sync::OnceLock;

use alias_free_shadows::scene::file::{self, SceneDescription};
use alias_free_shadows::{Error, Result};
use libfuzzer_sys::fuzz_target;

fn geometry(spec: &str, _base: &Path) -> Result<SceneDescription> {
    static PLANE_SPHERE: OnceLock<SceneDescription> = OnceLock::new();
    if spec.starts_with("builtin:") {
        Ok(PLANE_SPHERE
            .get_or_init(|| file::load("builtin:plane_sphere").unwrap())
            .clone())
    } else {
        Err(Error::InvalidInput(format!(
            "{spec}: no files while fuzzing"
        )))
    }
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz/scene.toml");
    match file::parse_scene_file_with(text, path, &geometry) {
        Ok(desc) => {
            // What the parser accepts, the frame accepts.
            if let Err(e) = desc.validate() {
                panic!("parsed, but the description is invalid: {e}");
            }
            // And every light's samples are finite (up to 128 samples: a
            // 1024-sample Poisson set takes ~0.1 s to generate).
            for l in desc.lights.iter().filter(|l| l.samples <= 128) {
                if let alias_free_shadows::light::LightSamples::Positions(p) = l.light_samples() {
                    assert!(p.iter().all(|p| p.is_finite()), "{l:?}");
                }
            }
        }
        Err(e) => {
            // Errors name the file.
            let m = e.to_string();
            assert!(!m.is_empty());
        }
    }
});
