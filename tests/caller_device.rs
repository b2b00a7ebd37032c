//! Issue 18: the engine on a renderer's own Vulkan device. The test makes
//! its device as a renderer would (raw ash, `DeviceRequirements` merged
//! in), hands it over with `Engine::from_external`, with the engine's own
//! allocator and with a shared `gpu_allocator` one, and checks that frames
//! (hard and soft shadows) equal the own-device engine's bit for bit, that
//! the validation layer (on the test's instance) reports nothing, and that
//! the caller's device is still alive and usable after the engine is gone.

use std::sync::{Arc, Mutex};

use alias_free_shadows::bench::{bench_light, load_scene};
use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::render::{Engine, Frame, FrameOptions};
use alias_free_shadows::scene::file::SceneDescription;
use alias_free_shadows::vulkan::{
    vk, ContextOptions, DeviceRequirements, ExternalDevice, Instance, ValidationLevel,
};
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

/// `builtin:demo` at 48² under a point light and the bench's sphere light.
fn scene() -> SceneDescription {
    let mut desc = load_scene("builtin:demo", 48).unwrap();
    let sphere = bench_light(&desc, 128).unwrap();
    let point = Light {
        shape: LightShape::Point {
            position: sphere.center().unwrap(),
        },
        ..sphere.clone()
    };
    desc.lights = vec![point, sphere];
    desc
}

/// What must be equal: every light's visibility, and the picture.
fn assert_same(a: &Frame, b: &Frame, what: &str) {
    assert_eq!(a.dump.visibility.len(), 2, "{what}: two lights");
    for (k, (va, vb)) in a.dump.visibility.iter().zip(&b.dump.visibility).enumerate() {
        let differ = va
            .iter()
            .zip(vb)
            .filter(|(x, y)| x.map(f32::to_bits) != y.map(f32::to_bits))
            .count();
        assert_eq!(differ, 0, "{what}: light {k}: {differ} pixels differ");
    }
    assert!(
        a.dump.visibility[1]
            .iter()
            .any(|v| v[0] > 0.0 && v[0] < 1.0),
        "{what}: the sphere light casts penumbrae (the test can see soft shadows)"
    );
    assert_eq!(a.image.as_raw(), b.image.as_raw(), "{what}: the picture");
}

/// The renderer's side: a device made with raw ash on the first usable
/// physical device, with the engine's requirements merged in. Destroyed
/// when dropped (also when a failed assertion unwinds), before the
/// instance.
struct CallerDevice {
    physical: vk::PhysicalDevice,
    device: ash::Device,
    family: u32,
    requirements: DeviceRequirements,
}

impl Drop for CallerDevice {
    fn drop(&mut self) {
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_device(None);
        }
    }
}

fn caller_device(instance: &Instance) -> CallerDevice {
    let raw = instance.raw();
    let physicals = unsafe { raw.enumerate_physical_devices() }.unwrap();
    let (physical, requirements) = physicals
        .iter()
        .find_map(|&p| {
            DeviceRequirements::for_physical_device(raw, p)
                .ok()
                .map(|r| (p, r))
        })
        .expect("a usable device");
    let families = unsafe { raw.get_physical_device_queue_family_properties(physical) };
    let wanted = requirements.queue_flags | vk::QueueFlags::GRAPHICS;
    let family = families
        .iter()
        .position(|f| f.queue_flags.contains(wanted))
        .expect("a graphics and compute queue") as u32;
    // The renderer's own features (none here), then the engine's.
    let mut features = vk::PhysicalDeviceFeatures::default();
    let mut features12 = vk::PhysicalDeviceVulkan12Features::default();
    requirements.enable(&mut features, &mut features12);
    let priorities = [1.0f32];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(family)
        .queue_priorities(&priorities)];
    let extensions: Vec<_> = requirements.extensions.iter().map(|e| e.as_ptr()).collect();
    let info = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queues)
        .enabled_extension_names(&extensions)
        .enabled_features(&features)
        .push_next(&mut features12);
    let device = unsafe { raw.create_device(physical, &info, None) }.unwrap();
    CallerDevice {
        physical,
        device,
        family,
        requirements,
    }
}

#[test]
fn an_engine_on_the_callers_device_renders_what_its_own_device_renders() {
    let desc = scene();
    let own = {
        let mut engine = Engine::new(&ContextOptions::validated()).unwrap();
        let frame = engine.render(&desc, FrameOptions::default()).unwrap();
        engine.context().check_validation().unwrap();
        frame
    };

    // The caller's instance, with the validation layer and its messenger.
    let instance = Instance::new(ValidationLevel::Standard).unwrap();
    let caller = caller_device(&instance);
    let queue = unsafe { caller.device.get_device_queue(caller.family, 0) };
    let external = |allocator| ExternalDevice {
        entry: instance.entry().clone(),
        instance: instance.raw().clone(),
        physical_device: caller.physical,
        device: caller.device.clone(),
        queue_family: caller.family,
        queue,
        enabled: caller.requirements.features,
        allocator,
    };

    // The engine's own allocator on the caller's device; two frames (the
    // second reuses every resource).
    {
        let mut engine = Engine::from_external(external(None), &ContextOptions::default()).unwrap();
        for round in 0..2 {
            let frame = engine.render(&desc, FrameOptions::default()).unwrap();
            assert_same(&frame, &own, &format!("own allocator, frame {round}"));
        }
    }
    assert_eq!(instance.take_messages(), Vec::<String>::new());

    // The caller's allocator, shared: the engine's memory comes from it and
    // goes back to it.
    let allocator = Arc::new(Mutex::new(
        Allocator::new(&AllocatorCreateDesc {
            instance: instance.raw().clone(),
            device: caller.device.clone(),
            physical_device: caller.physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .unwrap(),
    ));
    {
        let mut engine = Engine::from_external(
            external(Some(Arc::clone(&allocator))),
            &ContextOptions::default(),
        )
        .unwrap();
        let frame = engine.render(&desc, FrameOptions::default()).unwrap();
        assert_same(&frame, &own, "shared allocator");
        let report = allocator.lock().unwrap().generate_report();
        assert!(
            !report.allocations.is_empty(),
            "the engine's buffers come from the caller's allocator"
        );
    }
    let report = allocator.lock().unwrap().generate_report();
    assert!(
        report.allocations.is_empty(),
        "the engine returned its memory: {} allocations left",
        report.allocations.len()
    );
    drop(allocator);

    // The device is the caller's: still alive, destroyed by the caller, and
    // the layer saw no error (leaks of the engine's objects included).
    drop(caller);
    assert_eq!(instance.take_messages(), Vec::<String>::new());
}

#[test]
fn a_wrong_queue_family_is_an_error() {
    let instance = Instance::new(ValidationLevel::Standard).unwrap();
    let caller = caller_device(&instance);
    let queue = unsafe { caller.device.get_device_queue(caller.family, 0) };
    let external = ExternalDevice {
        entry: instance.entry().clone(),
        instance: instance.raw().clone(),
        physical_device: caller.physical,
        device: caller.device.clone(),
        queue_family: 999,
        queue,
        enabled: caller.requirements.features,
        allocator: None,
    };
    let e = Engine::from_external(external, &ContextOptions::default())
        .err()
        .expect("queue family 999 is refused");
    assert!(e.to_string().contains("queue family 999"), "{e}");
    drop(caller);
    assert_eq!(instance.take_messages(), Vec::<String>::new());
}
