//! The Vulkan backend: device listing, buffers, bindings and their limits,
//! images, the profiler, validation capture, and clean teardown. Every
//! context runs with validation; any message fails the test.

use std::time::Duration;

use alias_free_shadows::gpu::shaders;
use alias_free_shadows::vulkan::*;
use alias_free_shadows::Error;

fn context() -> GpuContext {
    GpuContext::new(&ContextOptions::validated()).expect("Vulkan context with validation")
}

/// Drops the context and fails on any validation message, leaks included.
fn finish(ctx: GpuContext) {
    let messages = ctx.validation_messages();
    drop(ctx);
    let m = messages.lock().unwrap();
    assert!(m.is_empty(), "validation messages:\n{}", m.join("\n"));
}

/// A pipeline with three storage buffers (scan reduce: input as uvec4s,
/// input as uints, sums), for binding checks.
fn reduce_pipeline(ctx: &GpuContext) -> ComputePipeline {
    ctx.create_compute_pipeline(&ComputePipelineDesc {
        name: "scan_reduce",
        spirv: shaders::SCAN_REDUCE,
        bindings: &[DescriptorKind::StorageBuffer; 3],
        push_constant_bytes: 16,
        specialization: &[(0, 64), (1, 1)],
    })
    .unwrap()
}

/// Contexts and resources can be shared between threads; recorders moved.
#[test]
fn thread_safety_traits() {
    fn send_sync<T: Send + Sync>() {}
    fn send<T: Send>() {}
    send_sync::<GpuContext>();
    send_sync::<Buffer>();
    send_sync::<Image>();
    send_sync::<ComputePipeline>();
    send_sync::<Profiler>();
    send_sync::<alias_free_shadows::gpu::scan::ScanPass>();
    send::<CommandRecorder>();
}

#[test]
fn list_devices_finds_llvmpipe() {
    let devices = list_devices().unwrap();
    assert!(!devices.is_empty());
    for d in &devices {
        eprintln!("{d}");
    }
    if let Some(lvp) = devices.iter().find(|d| d.name.contains("llvmpipe")) {
        assert_eq!(lvp.limits.max_storage_buffer_range, 134_217_728);
        assert_eq!(lvp.device_type, DeviceType::Cpu);
        assert!(lvp.usable());
        assert!(lvp.supports_subgroup(vk::SubgroupFeatureFlags::ARITHMETIC));
        let table = lvp.to_string();
        assert!(table.contains("maxStorageBufferRange") && table.contains("134217728"));
    }
}

#[test]
fn device_selection_by_name() {
    let devices = list_devices().unwrap();
    let Some(lvp) = devices.iter().find(|d| d.name.contains("llvmpipe")) else {
        return;
    };
    let ctx = GpuContext::new(&ContextOptions {
        device: Some("LLVMPIPE".into()),
        ..ContextOptions::validated()
    })
    .unwrap();
    assert_eq!(ctx.info().name, lvp.name);
    finish(ctx);
    let e = GpuContext::new(&ContextOptions {
        device: Some("no such device 1234".into()),
        ..ContextOptions::validated()
    })
    .err()
    .expect("unknown device name is an error");
    assert!(e.to_string().contains("no Vulkan device matches"), "{e}");
}

#[test]
fn context_create_and_drop_is_clean() {
    let ctx = context();
    assert_ne!(ctx.validation(), ValidationLevel::Off);
    finish(ctx);
}

#[test]
fn contexts_in_parallel_threads() {
    let handles: Vec<_> = (0..3)
        .map(|i| {
            std::thread::spawn(move || {
                let ctx = context();
                let data: Vec<u32> = (0..1000).map(|x| x * i).collect();
                let buf = ctx
                    .create_buffer_with_data(BufferDesc::storage("t", 4000), &data)
                    .unwrap();
                let back: Vec<u32> = ctx.read_buffer_staged(&buf, 0, 1000).unwrap();
                assert_eq!(back, data);
                drop(buf);
                finish(ctx);
            })
        })
        .collect();
    for h in handles {
        h.join().unwrap();
    }
}

#[test]
fn buffer_round_trips() {
    let ctx = context();
    {
        let data: Vec<u32> = (0..100_000u32)
            .map(|i| i.wrapping_mul(2_654_435_761))
            .collect();
        for location in [
            MemoryLocation::GpuOnly,
            MemoryLocation::CpuToGpu,
            MemoryLocation::GpuToCpu,
        ] {
            let buf = ctx
                .create_buffer(BufferDesc::storage("round trip", 400_000).with_location(location))
                .unwrap();
            // Direct (mapped) when possible, and always-staged.
            ctx.upload(&buf, 0, &data).unwrap();
            assert_eq!(ctx.read_buffer::<u32>(&buf, 0, data.len()).unwrap(), data);
            assert_eq!(
                ctx.read_buffer_staged::<u32>(&buf, 0, data.len()).unwrap(),
                data
            );
            let other: Vec<u32> = data.iter().map(|x| !x).collect();
            ctx.upload_staged(&buf, 0, &other).unwrap();
            assert_eq!(ctx.read_buffer::<u32>(&buf, 0, data.len()).unwrap(), other);
            // A typed sub-range.
            ctx.upload_staged(&buf, 40, &[7u64, 8u64]).unwrap();
            assert_eq!(ctx.read_buffer_staged::<u64>(&buf, 40, 2).unwrap(), [7, 8]);
            // In place: the same values, at an aligned offset and at one
            // that is not aligned for u64 (then copied).
            let sum = |v: &[u32]| v.iter().map(|&x| x as u64).sum::<u64>();
            let mut want = other.clone();
            want[10..14].copy_from_slice(bytemuck::cast_slice(&[7u64, 8u64]));
            assert_eq!(
                ctx.read_buffer_with(&buf, 0, data.len(), sum).unwrap(),
                sum(&want)
            );
            assert_eq!(
                ctx.read_buffer_with(&buf, 40, 2, |v: &[u64]| v.to_vec())
                    .unwrap(),
                [7, 8]
            );
            let odd: Vec<u64> =
                bytemuck::pod_collect_to_vec(bytemuck::cast_slice::<u32, u8>(&want[11..15]));
            assert_eq!(
                ctx.read_buffer_with(&buf, 44, 2, |v: &[u64]| v.to_vec())
                    .unwrap(),
                odd
            );
            assert_eq!(
                ctx.read_buffer_with(&buf, 0, 0, |v: &[u32]| v.len())
                    .unwrap(),
                0
            );
        }
        // Out of bounds is an error.
        let buf = ctx.create_buffer(BufferDesc::storage("small", 16)).unwrap();
        assert!(ctx.upload(&buf, 8, &[1u32, 2, 3]).is_err());
        assert!(ctx.read_buffer::<u32>(&buf, 0, 5).is_err());
        assert!(ctx
            .read_buffer_with(&buf, 4, 4, |v: &[u32]| v.len())
            .is_err());
        // Copy and fill through a recorder.
        let dst = ctx.create_buffer(BufferDesc::storage("dst", 16)).unwrap();
        ctx.upload(&buf, 0, &[1u32, 2, 3, 4]).unwrap();
        let mut rec = ctx.begin().unwrap();
        rec.fill_buffer(dst.whole(), 9).unwrap();
        rec.barrier(Barrier::TransferToTransfer);
        rec.copy_buffer(buf.slice(4, 8).unwrap(), &dst, 0).unwrap();
        ctx.submit_and_wait(rec).unwrap();
        assert_eq!(ctx.read_buffer::<u32>(&dst, 0, 4).unwrap(), [2, 3, 9, 9]);
    }
    finish(ctx);
}

#[test]
fn storage_binding_over_the_limit_is_an_error() {
    let ctx = context();
    {
        let max = ctx.info().limits.max_storage_buffer_range as u64;
        // Whole 4-byte elements past the limit (NVIDIA's limit is 2^32 - 1).
        let big = ctx
            .create_buffer(BufferDesc::storage("big", (max / 4 + 64) * 4))
            .unwrap();
        let small = ctx.create_buffer(BufferDesc::storage("sums", 256)).unwrap();
        let pipeline = reduce_pipeline(&ctx);
        let push = [0u8; 16];
        let mut rec = ctx.begin().unwrap();
        let e = rec
            .dispatch(
                &pipeline,
                &[
                    Binding::storage(&big),
                    Binding::storage(&small),
                    Binding::storage(&small),
                ],
                &push,
                [1, 1, 1],
            )
            .unwrap_err();
        assert!(matches!(e, Error::Vulkan(_)));
        assert!(e.to_string().contains("maxStorageBufferRange"), "{e}");
        assert!(big
            .whole()
            .check_storage_binding(&ctx.info().limits)
            .is_err());

        // Split into ranges instead: each one binds.
        let ranges = ctx.device().storage_binding_ranges(big.size(), 4).unwrap();
        assert_eq!(ranges.len(), 2);
        assert!(ranges.iter().all(|&(_, s)| s <= max));
        assert_eq!(ranges.iter().map(|&(_, s)| s).sum::<u64>(), big.size());
        for (offset, size) in ranges {
            let slice = big.slice(offset, size).unwrap();
            rec.dispatch(
                &pipeline,
                &[
                    Binding::Storage(slice),
                    Binding::Storage(slice),
                    Binding::storage(&small),
                ],
                &push,
                [1, 1, 1],
            )
            .unwrap();
        }
        ctx.submit_and_wait(rec).unwrap();

        // The pure helper.
        assert_eq!(
            storage_binding_ranges(100, 4, 48, 16).unwrap(),
            vec![(0, 48), (48, 48), (96, 4)]
        );
        assert_eq!(storage_binding_ranges(0, 4, 48, 16).unwrap(), vec![]);
        assert!(storage_binding_ranges(10, 4, 48, 16).is_err());
        assert_eq!(
            storage_binding_ranges(120, 12, 50, 16).unwrap(),
            vec![(0, 48), (48, 48), (96, 24)]
        );
    }
    finish(ctx);
}

#[test]
fn bad_bindings_are_errors() {
    let ctx = context();
    {
        let pipeline = reduce_pipeline(&ctx);
        let buf = ctx.create_buffer(BufferDesc::storage("b", 64)).unwrap();
        let uniform = ctx.create_buffer(BufferDesc::uniform("u", 64)).unwrap();
        let mut rec = ctx.begin().unwrap();
        // Wrong count, wrong kind, wrong push size, buffer without storage usage.
        assert!(rec
            .dispatch(
                &pipeline,
                &[Binding::storage(&buf), Binding::storage(&buf)],
                &[0; 16],
                [1, 1, 1]
            )
            .is_err());
        assert!(rec
            .dispatch(
                &pipeline,
                &[
                    Binding::storage(&buf),
                    Binding::storage(&buf),
                    Binding::uniform(&buf)
                ],
                &[0; 16],
                [1, 1, 1]
            )
            .is_err());
        assert!(rec
            .dispatch(
                &pipeline,
                &[
                    Binding::storage(&buf),
                    Binding::storage(&buf),
                    Binding::storage(&buf)
                ],
                &[0; 8],
                [1, 1, 1]
            )
            .is_err());
        assert!(rec
            .dispatch(
                &pipeline,
                &[
                    Binding::storage(&uniform),
                    Binding::storage(&buf),
                    Binding::storage(&buf)
                ],
                &[0; 16],
                [1, 1, 1]
            )
            .is_err());
        drop(rec);
    }
    finish(ctx);
}

#[test]
fn texel_buffers_uniforms_and_images_bind() {
    let ctx = context();
    {
        let n = 64u32;
        let src: Vec<u32> = (0..n).map(|i| i * 10).collect();
        let texel: Vec<u32> = (0..n).map(|i| i * 1000).collect();
        let src_buf = ctx
            .create_buffer_with_data(BufferDesc::storage("src", 4 * n as u64), &src)
            .unwrap();
        let texel_buf = ctx
            .create_buffer_with_data(BufferDesc::storage("texel src", 4 * n as u64), &texel)
            .unwrap();
        let dst = ctx
            .create_buffer(BufferDesc::storage("texel dst", 4 * n as u64))
            .unwrap();
        let add = ctx
            .create_buffer_with_data(BufferDesc::uniform("add", 16), &[5u32, 0, 0, 0])
            .unwrap();
        let image = ctx
            .create_image(&ImageDesc::d3(
                "probe image",
                [4, 4, 4],
                vk::Format::R32G32B32A32_UINT,
            ))
            .unwrap();
        let pipeline = ctx
            .create_compute_pipeline(&ComputePipelineDesc {
                name: "binding_probe",
                spirv: shaders::BINDING_PROBE,
                bindings: &[
                    DescriptorKind::StorageBuffer,
                    DescriptorKind::UniformBuffer,
                    DescriptorKind::UniformTexelBuffer,
                    DescriptorKind::StorageTexelBuffer,
                    DescriptorKind::StorageImage,
                ],
                push_constant_bytes: 4,
                specialization: &[(0, 32)],
            })
            .unwrap();
        let mut rec = ctx.begin().unwrap();
        rec.barrier(Barrier::TransferToCompute);
        rec.dispatch(
            &pipeline,
            &[
                Binding::storage(&src_buf),
                Binding::uniform(&add),
                Binding::uniform_texel(&texel_buf, vk::Format::R32_UINT),
                Binding::storage_texel(&dst, vk::Format::R32_UINT),
                Binding::StorageImage(&image),
            ],
            &n.to_ne_bytes(),
            [n / 32, 1, 1],
        )
        .unwrap();
        ctx.submit_and_wait(rec).unwrap();
        let want: Vec<u32> = (0..n).map(|i| i * 1000 + i * 10 + 5).collect();
        assert_eq!(ctx.read_buffer::<u32>(&dst, 0, n as usize).unwrap(), want);
        let texels: Vec<[u32; 4]> =
            bytemuck::cast_slice(&ctx.read_image(&image, 16).unwrap()).to_vec();
        for i in 0..n as usize {
            assert_eq!(texels[i], [i as u32, want[i], 0, 1], "texel {i}");
        }

        // Image upload and read-back, 2D and 3D.
        let img2 = ctx
            .create_image(&ImageDesc::d2("2d", 5, 3, vk::Format::R32_UINT))
            .unwrap();
        let bytes: Vec<u8> = (0..60u8).collect();
        ctx.upload_image(&img2, &bytes).unwrap();
        assert_eq!(ctx.read_image(&img2, 4).unwrap(), bytes);
        let bytes3: Vec<u8> = (0..1024u32).map(|i| (i * 7) as u8).collect();
        ctx.upload_image(&image, &bytes3).unwrap();
        assert_eq!(ctx.read_image(&image, 16).unwrap(), bytes3);
        assert!(ctx.upload_image(&img2, &bytes[..59]).is_err());
        // Too large a side is an error, not a driver failure.
        let max3 = ctx.info().limits.max_image_dimension_3d;
        assert!(ctx
            .create_image(&ImageDesc::d3(
                "huge",
                [max3 + 1, 1, 1],
                vk::Format::R32_UINT
            ))
            .is_err());
    }
    finish(ctx);
}

#[test]
fn profiler_times_a_pass() {
    let ctx = context();
    {
        let mut profiler = Profiler::new(&ctx, 4).unwrap();
        let mut pass = alias_free_shadows::gpu::scan::ScanPass::new(&ctx).unwrap();
        let n = 1 << 18;
        let input = ctx
            .create_buffer_with_data(BufferDesc::storage("in", 4 * n), &vec![1u32; n as usize])
            .unwrap();
        let output = ctx
            .create_buffer(BufferDesc::storage("out", 4 * (n + 1)))
            .unwrap();
        let mut rec = ctx.begin().unwrap();
        let scope = profiler.begin(&mut rec, "scan").unwrap();
        pass.record(&mut rec, input.whole(), output.whole(), n as u32)
            .unwrap();
        profiler.end(&mut rec, scope);
        let empty = profiler.begin(&mut rec, "nothing").unwrap();
        profiler.end(&mut rec, empty);
        let open = profiler.begin(&mut rec, "never ended").unwrap();
        drop(open);
        ctx.submit_and_wait(rec).unwrap();
        let results = profiler.results().unwrap();
        assert_eq!(results.len(), 2, "{results:?}");
        assert_eq!(results[0].name, "scan");
        if profiler.supported() {
            let ms = results[0].ms.unwrap();
            assert!(ms >= 0.0 && ms.is_finite(), "{ms}");
            assert!(results[1].ms.unwrap() >= 0.0);
            eprintln!("scan of {n}: {ms:.3} ms");
        } else {
            assert!(results[0].ms.is_none());
        }
        let total: Vec<u32> = ctx.read_buffer(&output, 4 * n, 1).unwrap();
        assert_eq!(total[0], n as u32);
        // More passes than a pool holds (4) take more pools, each reset in
        // the recorder of its first pass: ten passes over two recorders, then
        // a second round in the same pools.
        for round in 0..2 {
            profiler.clear();
            for part in 0..2 {
                let mut rec = ctx.begin().unwrap();
                for i in 0..5 {
                    let s = profiler
                        .begin(&mut rec, &format!("r{round} p{part}.{i}"))
                        .unwrap();
                    pass.record(&mut rec, input.whole(), output.whole(), 1024)
                        .unwrap();
                    profiler.end(&mut rec, s);
                }
                ctx.submit_and_wait(rec).unwrap();
            }
            let results = profiler.results().unwrap();
            assert_eq!(results.len(), 10, "{results:?}");
            assert_eq!(results[9].name, format!("r{round} p1.4"));
            for r in &results {
                assert_eq!(r.ms.is_some(), profiler.supported(), "{r:?}");
                assert!(r.ms.is_none_or(|ms| ms >= 0.0 && ms.is_finite()), "{r:?}");
            }
            ctx.check_validation().unwrap();
        }
    }
    finish(ctx);
}

#[test]
fn validation_errors_are_reported() {
    let ctx = context();
    // A buffer without usage flags is invalid: the layer must report it
    // (and the driver still makes a harmless buffer).
    let info = vk::BufferCreateInfo::default()
        .size(16)
        .usage(vk::BufferUsageFlags::empty());
    let raw = unsafe { ctx.raw().create_buffer(&info, None) };
    if let Ok(b) = raw {
        unsafe { ctx.raw().destroy_buffer(b, None) };
    }
    let e = ctx.check_validation().unwrap_err();
    assert!(matches!(e, Error::Validation(_)), "{e}");
    assert!(e.to_string().contains("usage"), "{e}");
    // Taken: nothing left.
    assert!(ctx.take_validation_messages().is_empty());
    finish(ctx);
}

#[test]
fn timeout_setting_and_empty_submission() {
    let mut ctx = context();
    ctx.set_timeout(Duration::from_secs(60));
    assert_eq!(ctx.timeout(), Duration::from_secs(60));
    // An empty submission finishes well within the timeout.
    let rec = ctx.begin().unwrap();
    ctx.submit_and_wait(rec).unwrap();
    finish(ctx);
}

/// `div_rn` (shaders/exact_div.glsl), the division whose results twins
/// compare bit for bit: equal to the CPU's IEEE `a / b` on every ratio of
/// light-sample counts up to 1024 (the soft visibility) and on random
/// floats of both signs and every magnitude whose quotient is normal.
#[test]
fn shader_division_rounds_like_ieee() {
    let ctx = context();
    {
        let mut pairs: Vec<[f32; 2]> = Vec::new();
        for n in 1..=1024u32 {
            for t in 0..=n {
                pairs.push([t as f32, n as f32]);
            }
        }
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        while pairs.len() < 800_000 {
            let r = next();
            // Any sign and mantissa; exponents within ±40 so the quotient is normal.
            let bits = |w: u32| (w & 0x807f_ffff) | ((127 + (w >> 23) % 81 - 40) << 23);
            let (a, b) = (
                f32::from_bits(bits(r as u32)),
                f32::from_bits(bits((r >> 32) as u32)),
            );
            pairs.push([a, b]);
        }
        let n = pairs.len();
        let input = ctx
            .create_buffer_with_data(BufferDesc::storage("pairs", 8 * n as u64), &pairs)
            .unwrap();
        let output = ctx
            .create_buffer(BufferDesc::storage("quotients", 4 * n as u64))
            .unwrap();
        let pipeline = ctx
            .create_compute_pipeline(&ComputePipelineDesc {
                name: "div_probe",
                spirv: shaders::DIV_PROBE,
                bindings: &[DescriptorKind::StorageBuffer; 2],
                push_constant_bytes: 4,
                specialization: &[],
            })
            .unwrap();
        let mut rec = ctx.begin().unwrap();
        rec.dispatch(
            &pipeline,
            &[Binding::storage(&input), Binding::storage(&output)],
            &(n as u32).to_le_bytes(),
            [n.div_ceil(64) as u32, 1, 1],
        )
        .unwrap();
        ctx.submit_and_wait(rec).unwrap();
        let got: Vec<f32> = ctx.read_buffer(&output, 0, n).unwrap();
        let wrong: Vec<_> = pairs
            .iter()
            .zip(&got)
            .filter(|([a, b], q)| (a / b).to_bits() != q.to_bits())
            .take(5)
            .collect();
        assert!(
            wrong.is_empty(),
            "div_rn differs from IEEE a / b: {wrong:?}"
        );
    }
    finish(ctx);
}

/// `spread_workgroup` (shaders/shadow_common.glsl), the workgroup order of
/// the passes whose work is uneven, against its twin
/// `gpu::dispatch::spread_index`: the same index for every workgroup and a
/// bijection, for the device's dispatch runs and forced ones, in 1D and
/// 2D dispatches.
#[test]
fn spread_workgroups_match_their_twin() {
    use alias_free_shadows::gpu::dispatch::{groups_2d, spread_index};
    let ctx = context();
    let device_runs = ctx.device().info().dispatch_runs();
    if ctx.device().info().driver_name == "llvmpipe" {
        assert!(device_runs >= 1);
    } else {
        assert_eq!(device_runs, 1);
    }
    for runs in [device_runs, 1, 2, 3, 7, 64] {
        let pipeline = ctx
            .create_compute_pipeline(&ComputePipelineDesc {
                name: "spread_probe",
                spirv: shaders::SPREAD_PROBE,
                bindings: &[DescriptorKind::StorageBuffer],
                push_constant_bytes: std::mem::size_of::<alias_free_shadows::gpu::shared::LightPush>()
                    as u32,
                specialization: &[(SPREAD_THREADS_ID, runs)],
            })
            .unwrap();
        for n in [1u32, 2, 5, 63, 64, 65, 1000, 4097, 70_001] {
            let grid = groups_2d(n);
            let dispatched = grid[0] * grid[1];
            let out = ctx
                .create_buffer(BufferDesc::storage("spread", 4 * dispatched as u64))
                .unwrap();
            let mut rec = ctx.begin().unwrap();
            let push = [0u8; std::mem::size_of::<alias_free_shadows::gpu::shared::LightPush>()];
            rec.dispatch(&pipeline, &[Binding::storage(&out)], &push, grid)
                .unwrap();
            ctx.submit_and_wait(rec).unwrap();
            let got: Vec<u32> = ctx.read_buffer(&out, 0, dispatched as usize).unwrap();
            let mut seen = vec![false; dispatched as usize];
            for (w, &b) in got.iter().enumerate() {
                assert_eq!(
                    b,
                    spread_index(w as u32, dispatched, runs),
                    "runs {runs}, {dispatched} workgroups, workgroup {w}"
                );
                assert!(!seen[b as usize], "runs {runs}, n {dispatched}: {b} twice");
                seen[b as usize] = true;
            }
        }
    }
    finish(ctx);
}

/// Pipelines are made at their first dispatch, and soft occlusion's kernels
/// only when a light first needs one (made up front, its 18 cost every
/// engine's start 0.5 s on lavapipe), so no run compiles them all. With
/// `eager_pipelines` an engine makes every pipeline of its passes when it
/// is built, and the soft occlusion pass every kernel (each mode at each
/// block count, the unsure tests, in both rounds, rotated or not, exact
/// mode's with the wedge rule and without): any creation error or
/// validation message fails. On a context without it, none is made.
#[test]
fn every_pipeline_is_made_cleanly() {
    use alias_free_shadows::gpu::soft_occlusion::SoftOcclusionPass;
    use alias_free_shadows::render::Engine;
    let lazy = context();
    let mut pass = SoftOcclusionPass::new(&lazy).unwrap();
    assert_eq!(pass.make_every_kernel(&lazy).unwrap(), 0, "deferred");
    drop(pass);
    finish(lazy);

    let eager = ContextOptions {
        eager_pipelines: true,
        ..ContextOptions::validated()
    };
    let engine = Engine::new(&eager).unwrap();
    let ctx = engine.context();
    let mut pass = SoftOcclusionPass::new(ctx).unwrap();
    // 16 look-up kernels (two modes, eight block counts) and the unsure
    // tests in four variants each, exact mode's in eight.
    assert_eq!(pass.make_every_kernel(ctx).unwrap(), 18 * 4 + 4);
    drop(pass);
    ctx.check_validation().unwrap();
}

/// A deferred pipeline is compiled at its first dispatch: one whose shader
/// is not SPIR-V is made without complaint, and its first dispatch returns
/// an error that names it (no panic), while the eager creation of the same
/// description fails at once; a good deferred pipeline is made by its
/// first dispatch and then runs.
#[test]
fn deferred_pipelines_are_made_at_their_first_dispatch() {
    let ctx = context();
    {
        let not_spirv = [0u32; 16];
        let desc = |spirv| ComputePipelineDesc {
            name: "not_spirv",
            spirv,
            bindings: &[DescriptorKind::StorageBuffer; 3],
            push_constant_bytes: 16,
            specialization: &[(0, 64), (1, 1)],
        };
        let eager = ctx.create_compute_pipeline(&desc(&not_spirv));
        assert!(eager.is_err(), "eager creation checks the shader");
        let bad = ComputePipeline::deferred(ctx.device(), &desc(&not_spirv)).unwrap();
        assert!(!bad.is_made());
        let buf = ctx.create_buffer(BufferDesc::storage("b", 64)).unwrap();
        let three = [
            Binding::storage(&buf),
            Binding::storage(&buf),
            Binding::storage(&buf),
        ];
        let mut rec = ctx.begin().unwrap();
        let e = rec
            .dispatch(&bad, &three, &[0; 16], [1, 1, 1])
            .expect_err("a shader that is not SPIR-V cannot be dispatched");
        assert!(e.to_string().contains("not_spirv"), "{e}");
        assert!(!bad.is_made());
        drop(rec);

        let good = ComputePipeline::deferred(ctx.device(), &desc(shaders::SCAN_REDUCE)).unwrap();
        assert!(!good.is_made());
        let mut rec = ctx.begin().unwrap();
        rec.dispatch(&good, &three, &[0; 16], [1, 1, 1]).unwrap();
        assert!(good.is_made());
        ctx.submit_and_wait(rec).unwrap();
    }
    finish(ctx);
}
