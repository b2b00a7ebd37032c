//! Issue 5, resources: a request larger than the device's memory is an
//! error (the device still works after it), and every Vulkan object is
//! destroyed on error paths: the validation layers report objects still
//! alive when the device is destroyed, and they report none.

use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::oracle::ViewSample;
use alias_free_shadows::render::{Engine, FrameOptions};
use alias_free_shadows::scene::file::{self, ShadowSettings};
use alias_free_shadows::vulkan::{BufferDesc, ContextOptions, GpuContext};
use glam::DVec3;

/// The validation messages left after `ctx` is dropped, having checked
/// that its device was destroyed then (no object kept it alive).
fn messages_after_shutdown(ctx: GpuContext) -> Vec<String> {
    let messages = ctx.validation_messages();
    let device = std::sync::Arc::downgrade(ctx.device());
    drop(ctx);
    assert!(
        device.upgrade().is_none(),
        "the device outlived its context"
    );
    let out = std::mem::take(&mut *messages.lock().unwrap());
    out
}

#[test]
fn a_buffer_larger_than_device_memory_is_an_error() {
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let heap: u64 = ctx
        .info()
        .memory_heaps
        .iter()
        .map(|h| h.size)
        .max()
        .unwrap();
    for size in [heap + (1 << 20), heap.saturating_mul(4), u64::MAX / 2] {
        let r = ctx.create_buffer(BufferDesc::storage("too_large", size));
        let e = r
            .err()
            .unwrap_or_else(|| panic!("a {size}-byte buffer was created"));
        eprintln!("{size} bytes: {e}");
    }
    // The device is not lost: a buffer round trip still works.
    let b = ctx
        .create_buffer_with_data(BufferDesc::storage("after", 16), &[1u32, 2, 3, 4])
        .unwrap();
    let back: Vec<u32> = ctx.read_buffer_staged(&b, 0, 4).unwrap();
    assert_eq!(back, [1, 2, 3, 4]);
    drop(b);
    ctx.check_validation().unwrap();
    let left = messages_after_shutdown(ctx);
    assert!(left.is_empty(), "{left:#?}");
}

/// The check below can fail: a buffer leaked on purpose (a raw handle,
/// never destroyed) is reported when the device is destroyed.
#[test]
fn a_leaked_buffer_is_reported_at_shutdown() {
    use alias_free_shadows::vulkan::vk;
    let ctx = GpuContext::new(&ContextOptions::validated()).unwrap();
    let info = vk::BufferCreateInfo::default()
        .size(256)
        .usage(vk::BufferUsageFlags::STORAGE_BUFFER);
    // SAFETY: a valid create info on a live device; the handle is leaked on purpose.
    let _leaked = unsafe { ctx.raw().create_buffer(&info, None) }.unwrap();
    let left = messages_after_shutdown(ctx);
    eprintln!("{left:#?}");
    assert!(
        left.iter().any(|m| m.contains("not been destroyed")),
        "the leak was not reported: {left:#?}"
    );
}

#[test]
fn error_paths_destroy_every_vulkan_object() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    let mut desc = file::load("builtin:demo").unwrap();
    desc.camera.width = 32;
    desc.camera.height = 32;
    let eye = desc.camera.eye;
    let scene = desc.scene.clone();
    let light = desc.lights[0].clone();
    let good = ViewSample::user(DVec3::new(0.0, 0.01, 0.0), DVec3::Y);
    let nan = ViewSample::user(DVec3::new(f64::NAN, 0.0, 0.0), DVec3::Y);
    let point = Light {
        shape: LightShape::Point {
            position: light.center().unwrap(),
        },
        samples: 1,
        ..light.clone()
    };
    // Errors before and after GPU work, then a good frame, then more errors.
    let errors = [
        engine
            .soft_shadows(
                &scene,
                eye,
                &[Some(nan)],
                &light,
                &ShadowSettings::default(),
            )
            .err(),
        engine
            .hard_shadows(&scene, eye, &[Some(good)], &light, 64)
            .err(),
        engine
            .soft_shadows(
                &scene,
                eye,
                &[Some(good)],
                &light,
                &ShadowSettings {
                    lut_resolution: 0,
                    ..Default::default()
                },
            )
            .err(),
        engine
            .hard_shadows(&scene, eye, &[Some(good)], &point, 1 << 20)
            .err(),
    ];
    engine.render(&desc, FrameOptions::default()).unwrap();
    let mut bad = desc.clone();
    bad.camera.width = 0;
    let render_error = engine.render(&bad, FrameOptions::default()).err();
    let huge = engine
        .context()
        .create_buffer(BufferDesc::storage("too_large", u64::MAX / 2));
    for e in errors.iter().chain([&render_error]) {
        let e = e.as_ref().expect("an error");
        eprintln!("error: {e}");
    }
    assert!(huge.is_err());
    engine
        .hard_shadows(&scene, eye, &[Some(good)], &point, 64)
        .unwrap();
    engine.context().check_validation().unwrap();
    let messages = engine.context().validation_messages();
    let device = std::sync::Arc::downgrade(engine.context().device());
    drop(engine);
    assert!(device.upgrade().is_none(), "the device outlived the engine");
    let left = std::mem::take(&mut *messages.lock().unwrap());
    assert!(left.is_empty(), "at shutdown: {left:#?}");
}

/// The frame's statistics (a GPU frame's).
fn gpu_stats(frame: &alias_free_shadows::render::Frame) -> &alias_free_shadows::stats::FrameStats {
    match &frame.stats {
        alias_free_shadows::stats::Stats::Gpu(s) => s,
        other => panic!("not a GPU frame: {other:?}"),
    }
}

/// Resources live across frames: a second frame of the same size creates
/// no buffer or image (the count is the device's own, of every buffer and
/// image made), for a point light, a light with extent in both modes, and
/// the user-sample API; a smaller frame after a larger one reuses the
/// larger buffers (it makes only render targets of its own size) and gives
/// exactly the result of a fresh engine.
#[test]
fn a_second_frame_of_the_same_size_allocates_nothing() {
    let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
    for spec in ["builtin:plane_sphere", "builtin:demo"] {
        for mode in [file::SoftMode::Lut, file::SoftMode::Exact] {
            let mut desc = file::load(spec).unwrap();
            desc.camera.width = 48;
            desc.camera.height = 40;
            desc.shadows.mode = mode;
            let first = engine.render(&desc, FrameOptions::default()).unwrap();
            let second = engine.render(&desc, FrameOptions::default()).unwrap();
            let (a, b) = (gpu_stats(&first), gpu_stats(&second));
            eprintln!(
                "{spec} {mode:?}: first frame {:?}, second {:?}",
                a.allocations, b.allocations
            );
            assert_eq!(
                b.allocations.count(),
                0,
                "{spec}: the second frame allocated"
            );
            assert_eq!(b.lights[0].stats.allocations.count(), 0);
            assert_eq!(first.dump.visibility, second.dump.visibility);
        }
    }
    // The first frame on a fresh engine does allocate (the count counts).
    let mut fresh = Engine::new(&ContextOptions::validated()).unwrap();
    let mut desc = file::load("builtin:demo").unwrap();
    desc.camera.width = 32;
    desc.camera.height = 32;
    let small_fresh = fresh.render(&desc, FrameOptions::default()).unwrap();
    assert!(gpu_stats(&small_fresh).allocations.buffers > 0);
    // Smaller after larger: no new buffer (only the view samples' render
    // targets, which have the image's size), the same visibility as a
    // fresh engine.
    let small = engine.render(&desc, FrameOptions::default()).unwrap();
    let a = gpu_stats(&small).allocations;
    assert_eq!((a.buffers, a.images), (0, 2), "{a:?}");
    assert_eq!(small.dump.visibility, small_fresh.dump.visibility);

    // The user-sample API reuses its uploads and passes too.
    let eye = desc.camera.eye;
    let samples: Vec<Option<ViewSample>> = small_fresh.view.samples.clone();
    let settings = ShadowSettings::default();
    let light = desc.lights[0].clone();
    let r1 = engine
        .soft_shadows(&desc.scene, eye, &samples, &light, &settings)
        .unwrap();
    let r2 = engine
        .soft_shadows(&desc.scene, eye, &samples, &light, &settings)
        .unwrap();
    assert_eq!(
        r2.stats.allocations.count(),
        0,
        "first: {:?}",
        r1.stats.allocations
    );
    assert_eq!(r1.visible, r2.visible);
    engine.context().check_validation().unwrap();
}
