//! A light's passes timed with GPU timestamps, as on every device with
//! timestamps that is not a CPU (lavapipe times them on the host): look-up
//! mode's table build and read (host work beside the recorded passes), and
//! runs with more timed passes than one query pool holds. Any validation
//! message fails, and every pass has a time.
//!
//! Its own test binary: it sets `AFS_PROFILE_WALL=0` for the whole process.

mod common;

use alias_free_shadows::bench::{bench_light, load_scene};
use alias_free_shadows::oracle::Oracle;
use alias_free_shadows::render::Engine;
use alias_free_shadows::scene::file::SoftMode;
use alias_free_shadows::vulkan::ContextOptions;
use common::{engine_view_samples, soft_in_mode};

#[test]
fn timestamp_mode_times_every_pass_of_both_soft_modes() {
    // SAFETY: set before any other thread runs (the only test here).
    unsafe { std::env::set_var("AFS_PROFILE_WALL", "0") };
    let dir = tempfile::tempdir().unwrap();
    let desc = load_scene("builtin:demo", 24).unwrap();
    let oracle = Oracle::new(&desc.scene.triangles(), desc.camera.eye);
    let view = engine_view_samples(&oracle, &desc);
    for (samples, mode, host_pass) in [
        (64, SoftMode::Lut, "lut_build"),
        (64, SoftMode::Lut, "lut_read"),
        (1024, SoftMode::Exact, ""),
        (1024, SoftMode::Lut, "lut_build"),
    ] {
        // A fresh engine per run: the second look-up run reads the table
        // the first one kept on disk.
        let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
        engine.set_table_cache(Some(dir.path().to_path_buf()));
        engine.set_table_mapping(false);
        let light = bench_light(&desc, samples).unwrap();
        let r = soft_in_mode(&mut engine, &desc, &view, &light, mode);
        engine.context().check_validation().unwrap();
        let ms = &r.stats.ms;
        let what = format!("{samples} samples, {mode:?}: {ms:?}");
        assert!(ms.contains_key("occlusion"), "{what}");
        if !host_pass.is_empty() {
            assert!(ms.contains_key(host_pass), "{what}");
        }
        let timed = engine.context().info().timestamp_valid_bits > 0;
        for (name, t) in ms {
            assert_eq!(t.is_some(), timed, "{name}: {what}");
        }
    }
}
