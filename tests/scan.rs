//! The GPU exclusive scan against its CPU twin, with validation on: any
//! validation message fails the test.

use std::time::Instant;

use alias_free_shadows::cpu::scan::exclusive_scan;
use alias_free_shadows::gpu::scan::{scan_u32, ScanConfig, ScanPass};
use alias_free_shadows::vulkan::*;

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

/// Deterministic values below `max` (xorshift).
fn values(n: usize, seed: u64, max: u32) -> Vec<u32> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 32) as u32) % max
        })
        .collect()
}

fn check(got: &(Vec<u32>, u32), input: &[u32], what: &str) {
    let (want, want_total) = exclusive_scan(input);
    assert_eq!(got.0.len(), want.len(), "{what}: length");
    if let Some(i) = (0..want.len()).find(|&i| got.0[i] != want[i]) {
        panic!(
            "{what}: first difference at {i} of {}: gpu {} cpu {}",
            want.len(),
            got.0[i],
            want[i]
        );
    }
    assert_eq!(got.1, want_total, "{what}: total");
}

#[test]
fn scan_1m_random_matches_cpu() {
    let ctx = context();
    let input = values(1 << 20, 1, 256);
    {
        let mut pass = ScanPass::new(&ctx).unwrap();
        // The first run includes lavapipe's shader JIT; time the second.
        check(
            &pass.scan(&ctx, &input, None).unwrap(),
            &input,
            "1M (first)",
        );
        let mut profiler = Profiler::new(&ctx, 4).unwrap();
        let t = Instant::now();
        let got = pass.scan(&ctx, &input, Some(&mut profiler)).unwrap();
        let wall = t.elapsed();
        check(&got, &input, "1M");
        let ms = profiler.pass_ms("scan").unwrap();
        eprintln!(
            "scan of 1,048,576 u32 on {} with {:?}: GPU {} ms (upload+scan+read-back wall {:.1} ms)",
            ctx.info().name,
            pass.config(),
            ms.map_or("n/a".into(), |m| format!("{m:.2}")),
            wall.as_secs_f64() * 1e3
        );
    }
    finish(ctx);
}

#[test]
fn scan_edge_sizes() {
    let ctx = context();
    {
        let default = ScanConfig::for_device(ctx.info());
        // Small blocks too, so level boundaries and three levels are hit.
        let small = ScanConfig {
            workgroup_size: 64,
            vecs_per_thread: 1,
            ..default
        };
        for config in [default, small] {
            let mut pass = ScanPass::with_config(&ctx, config).unwrap();
            let b = config.block_elements() as usize;
            let mut sizes = vec![
                0,
                1,
                2,
                3,
                4,
                5,
                255,
                256,
                257,
                65_536 + 1,
                3_000_017,
                b - 1,
                b,
                b + 1,
                b * b - 1,
                b * b,
                b * b + 1,
            ];
            sizes.retain(|&n| n <= 4_000_000);
            for (k, &n) in sizes.iter().enumerate() {
                let input = values(n, 10 + k as u64, 1000);
                let got = pass.scan(&ctx, &input, None).unwrap();
                check(&got, &input, &format!("n = {n}, {config:?}"));
            }
        }
    }
    finish(ctx);
}

#[test]
fn scan_u32_convenience_and_wrapping() {
    let ctx = context();
    // Sums past 2^32 wrap exactly like the CPU twin.
    let input = values(100_003, 3, u32::MAX);
    check(&scan_u32(&ctx, &input).unwrap(), &input, "wrapping");
    check(&scan_u32(&ctx, &[]).unwrap(), &[], "empty");
    finish(ctx);
}

#[test]
fn scan_16m() {
    let ctx = context();
    let n = (16 << 20) + 3;
    let input = values(n, 4, 16);
    {
        let mut pass = ScanPass::new(&ctx).unwrap();
        let mut profiler = Profiler::new(&ctx, 1).unwrap();
        let got = pass.scan(&ctx, &input, Some(&mut profiler)).unwrap();
        check(&got, &input, "16M + 3");
        eprintln!(
            "scan of {n} u32: GPU {:?} ms",
            profiler.pass_ms("scan").unwrap()
        );
    }
    finish(ctx);
}

#[test]
fn scan_in_place_at_offsets_and_thrice_in_one_recording() {
    let ctx = context();
    {
        let align = ctx
            .info()
            .limits
            .min_storage_buffer_offset_alignment
            .max(16);
        let mut pass = ScanPass::new(&ctx).unwrap();
        let small = values(1000, 5, 100);
        let large = values(700_001, 6, 100);
        // One buffer: [pad | small (in place, n + 1 slots) | pad | large in | large out].
        let off_small = align;
        let off_large_in = (off_small + 4 * 1001).next_multiple_of(align);
        let off_large_out = (off_large_in + 4 * 700_001).next_multiple_of(align);
        let size = off_large_out + 4 * 700_002;
        let buf = ctx
            .create_buffer(BufferDesc::storage("shared", size))
            .unwrap();
        ctx.upload(&buf, off_small, &small).unwrap();
        ctx.upload(&buf, off_large_in, &large).unwrap();
        let mut rec = ctx.begin().unwrap();
        // Small first, then large: the pass grows its scratch buffers while
        // the recording still uses the old ones.
        let s = buf.slice(off_small, 4 * 1001).unwrap();
        pass.record(&mut rec, s, s, 1000).unwrap();
        pass.record(
            &mut rec,
            buf.slice(off_large_in, 4 * 700_001).unwrap(),
            buf.slice(off_large_out, 4 * 700_002).unwrap(),
            700_001,
        )
        .unwrap();
        // A third scan reuses the second's scratch buffers (in place, on the
        // large input): the recorded barriers must order them.
        let large_in = buf.slice(off_large_in, 4 * 700_001).unwrap();
        pass.record(&mut rec, large_in, large_in, 700_000).unwrap();
        ctx.submit_and_wait(rec).unwrap();
        let got_third: Vec<u32> = ctx.read_buffer(&buf, off_large_in, 700_001).unwrap();
        let (want_third, total_third) = exclusive_scan(&large[..700_000]);
        assert_eq!(got_third[..700_000], want_third[..], "third scan");
        assert_eq!(got_third[700_000], total_third, "third scan total");
        let mut got_small: Vec<u32> = ctx.read_buffer(&buf, off_small, 1001).unwrap();
        let t = got_small.pop().unwrap();
        check(&(got_small, t), &small, "in place");
        let mut got_large: Vec<u32> = ctx.read_buffer(&buf, off_large_out, 700_002).unwrap();
        let t = got_large.pop().unwrap();
        check(&(got_large, t), &large, "second scan");
    }
    finish(ctx);
}

#[test]
fn scan_shapes_agree() {
    let ctx = context();
    let input = values(300_007, 7, 50);
    for (workgroup_size, vecs_per_thread, texel_loads) in [
        (64, 1, false),
        (128, 4, false),
        (256, 2, false),
        (32, 8, false),
        (64, 1, true),
        (128, 4, true),
        (256, 2, true),
        (32, 8, true),
        (64, 16, false),
        (128, 16, true),
    ] {
        let config = ScanConfig {
            workgroup_size,
            vecs_per_thread,
            texel_loads,
        };
        let mut pass = ScanPass::with_config(&ctx, config).unwrap();
        check(
            &pass.scan(&ctx, &input, None).unwrap(),
            &input,
            &format!("{config:?}"),
        );
    }
    finish(ctx);
}

#[test]
fn scan_errors_instead_of_truncating() {
    let ctx = context();
    {
        let mut pass = ScanPass::new(&ctx).unwrap();
        let buf = ctx.create_buffer(BufferDesc::storage("small", 64)).unwrap();
        let mut rec = ctx.begin().unwrap();
        // Longer than the device can bind.
        let too_long = pass.max_len() + 1;
        let e = pass
            .record(&mut rec, buf.whole(), buf.whole(), too_long)
            .unwrap_err();
        assert!(e.to_string().contains("maxStorageBufferRange"), "{e}");
        // Longer than the buffers.
        let e = pass
            .record(&mut rec, buf.whole(), buf.whole(), 16)
            .unwrap_err();
        assert!(e.to_string().contains("output bytes"), "{e}");
        drop(rec);
    }
    finish(ctx);
}

#[test]
fn timeout_is_an_error_not_a_hang() {
    let mut ctx = context();
    let input = values(3_000_000, 8, 10);
    {
        let mut pass = ScanPass::new(&ctx).unwrap();
        pass.reserve(input.len() as u32).unwrap();
        ctx.set_timeout(std::time::Duration::from_nanos(1));
        let t = Instant::now();
        match pass.scan(&ctx, &input, None) {
            Err(e) => assert!(e.to_string().contains("did not finish"), "{e}"),
            // A driver that runs work inside vkQueueSubmit finishes first;
            // lavapipe (Mesa 22.3) runs it on a queue thread and times out.
            Ok(got) => {
                eprintln!("the driver finished within the timeout; nothing to check");
                check(&got, &input, "no timeout");
            }
        }
        assert!(t.elapsed().as_secs() < 30);
        // The context stays usable once the work is done.
        ctx.set_timeout(std::time::Duration::from_secs(300));
        let small = values(10, 9, 10);
        check(
            &pass.scan(&ctx, &small, None).unwrap(),
            &small,
            "after timeout",
        );
    }
    finish(ctx);
}

/// Sweeps scan shapes and prints the GPU time of a 1M scan for each (median
/// of 9, configurations interleaved so machine load drifts hit all alike);
/// run with `cargo test --test scan -- --ignored --nocapture tune`.
#[test]
#[ignore]
fn tune_scan_shapes() {
    let ctx = GpuContext::new(&ContextOptions::default()).unwrap();
    let input = values(1 << 20, 11, 256);
    let mut passes: Vec<ScanPass> = [32, 64, 128, 256, 512]
        .into_iter()
        .flat_map(|w| [1, 2, 4, 8, 16].map(|v| (w, v)))
        .flat_map(|(w, v)| [false, true].map(|t| (w, v, t)))
        .map(|(workgroup_size, vecs_per_thread, texel_loads)| {
            let config = ScanConfig {
                workgroup_size,
                vecs_per_thread,
                texel_loads,
            };
            let mut pass = ScanPass::with_config(&ctx, config).unwrap();
            pass.scan(&ctx, &input, None).unwrap();
            pass
        })
        .collect();
    let mut times = vec![Vec::new(); passes.len()];
    for _ in 0..9 {
        for (pass, t) in passes.iter_mut().zip(&mut times) {
            let mut profiler = Profiler::new(&ctx, 1).unwrap();
            let got = pass.scan(&ctx, &input, Some(&mut profiler)).unwrap();
            check(&got, &input, "tune");
            t.push(profiler.pass_ms("scan").unwrap().unwrap_or(f64::NAN));
        }
    }
    for (pass, mut t) in passes.iter().zip(times) {
        t.sort_by(f64::total_cmp);
        eprintln!("{:?}: {:.2} ms", pass.config(), t[4]);
    }
}
