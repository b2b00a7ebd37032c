//! GLSL (`shaders/common.glsl`) and Rust (`src/gpu/shared.rs`) agree on every
//! shared struct: `shaders/layout_probe.comp` writes known values through the
//! GLSL types, which Rust reads field by field, and flattens a uniform and
//! push constants that Rust filled, which Rust compares scalar by scalar.

use alias_free_shadows::gpu::shaders;
use alias_free_shadows::gpu::shared::*;
use alias_free_shadows::vulkan::*;
use bytemuck::Zeroable;

/// `f(base, k)` of the probe.
fn f(base: u32, k: u32) -> f32 {
    (base + k) as f32
}
/// `u(base, k)` of the probe: uint bits in a float slot.
fn u(base: u32, k: u32) -> u32 {
    0x4000_0000 + base + k
}
fn fv(base: u32, k: u32) -> [f32; 4] {
    [f(base, k), f(base, k + 1), f(base, k + 2), f(base, k + 3)]
}
fn uv(base: u32, k: u32) -> [u32; 4] {
    [base + k, base + k + 1, base + k + 2, base + k + 3]
}

fn expected_sample(e: u32) -> GpuViewSample {
    let b = 1000 + 100 * e;
    GpuViewSample {
        position: [f(b, 0), f(b, 1), f(b, 2)],
        triangle: u(b, 3),
        normal: [f(b, 4), f(b, 5), f(b, 6)],
        flags: u(b, 7),
    }
}

fn expected_triangle(e: u32) -> GpuTriangle {
    let b = 2000 + 100 * e;
    GpuTriangle {
        v0: [f(b, 0), f(b, 1), f(b, 2)],
        flags: u(b, 3),
        v1: [f(b, 4), f(b, 5), f(b, 6)],
        mesh: u(b, 7),
        v2: [f(b, 8), f(b, 9), f(b, 10)],
        alpha_record: u(b, 11),
    }
}

fn expected_frame(e: u32) -> FrameConstants {
    let b = 3000 + 100 * e;
    FrameConstants {
        light_view_proj: [fv(b, 0), fv(b, 4), fv(b, 8), fv(b, 12)],
        light_position: [f(b, 16), f(b, 17), f(b, 18)],
        light_kind: u(b, 19),
        light_direction: fv(b, 20),
        light_extent: fv(b, 24),
        light_resolution: uv(b, 28),
        counts: uv(b, 32),
        camera_origin: fv(b, 36),
    }
}

/// Compares named fields and reports the first that differs.
macro_rules! check_fields {
    ($what:expr, $got:expr, $want:expr, [$($field:ident),* $(,)?]) => {{
        let (got, want) = (&$got, &$want);
        $(
            assert_eq!(got.$field, want.$field, "{}: field `{}`", $what, stringify!($field));
        )*
        // Every field was listed: the whole structs agree too.
        assert_eq!(bytemuck::bytes_of(got), bytemuck::bytes_of(want), "{}: bytes", $what);
    }};
}

#[test]
fn sizes() {
    assert_eq!(std::mem::size_of::<ScanPush>(), 16);
    assert_eq!(std::mem::size_of::<GpuViewSample>(), 32);
    assert_eq!(std::mem::size_of::<GpuTriangle>(), 48);
    assert_eq!(std::mem::size_of::<FrameConstants>(), 160);
    assert_eq!(std::mem::align_of::<FrameConstants>(), 4);
}

#[test]
fn glsl_and_rust_layouts_agree() {
    let ctx = GpuContext::new(&ContextOptions::validated()).expect("Vulkan context");
    {
        let storage = |name: &str, bytes: usize| {
            ctx.create_buffer(BufferDesc::storage(name, bytes as u64))
                .unwrap()
        };
        let samples = storage("samples", 2 * std::mem::size_of::<GpuViewSample>());
        let triangles = storage("triangles", 2 * std::mem::size_of::<GpuTriangle>());
        let frames = storage("frames", 2 * std::mem::size_of::<FrameConstants>());
        let scans = storage("scans", 2 * std::mem::size_of::<ScanPush>());
        let flat_len = 16 + 6 * 4 + 4;
        let flat = storage("flat", 4 * flat_len);

        // Rust-side values for the read direction: distinct, no NaNs.
        let mut frame_in = FrameConstants::zeroed();
        {
            let words: &mut [u32] = bytemuck::cast_slice_mut(std::slice::from_mut(&mut frame_in));
            for (k, w) in words.iter_mut().enumerate() {
                *w = 0x3f80_0000 + 7 * k as u32;
            }
        }
        let push = ScanPush {
            n: 11,
            flags: 22,
            group_count: 33,
            groups_x: 44,
        };
        let uniform = ctx
            .create_buffer(BufferDesc::uniform("frame in", 160))
            .unwrap();
        ctx.upload(&uniform, 0, &[frame_in]).unwrap();

        let pipeline = ctx
            .create_compute_pipeline(&ComputePipelineDesc {
                name: "layout_probe",
                spirv: shaders::LAYOUT_PROBE,
                bindings: &[
                    DescriptorKind::StorageBuffer,
                    DescriptorKind::StorageBuffer,
                    DescriptorKind::StorageBuffer,
                    DescriptorKind::StorageBuffer,
                    DescriptorKind::UniformBuffer,
                    DescriptorKind::StorageBuffer,
                ],
                push_constant_bytes: 16,
                specialization: &[],
            })
            .unwrap();
        let mut rec = ctx.begin().unwrap();
        rec.dispatch(
            &pipeline,
            &[
                Binding::storage(&samples),
                Binding::storage(&triangles),
                Binding::storage(&frames),
                Binding::storage(&scans),
                Binding::uniform(&uniform),
                Binding::storage(&flat),
            ],
            bytemuck::bytes_of(&push),
            [1, 1, 1],
        )
        .unwrap();
        ctx.submit_and_wait(rec).unwrap();

        let got: Vec<GpuViewSample> = ctx.read_buffer(&samples, 0, 2).unwrap();
        for e in 0..2 {
            check_fields!(
                format!("GpuViewSample[{e}]"),
                got[e as usize],
                expected_sample(e),
                [position, triangle, normal, flags]
            );
        }
        let got: Vec<GpuTriangle> = ctx.read_buffer(&triangles, 0, 2).unwrap();
        for e in 0..2 {
            check_fields!(
                format!("GpuTriangle[{e}]"),
                got[e as usize],
                expected_triangle(e),
                [v0, flags, v1, mesh, v2, alpha_record]
            );
        }
        let got: Vec<FrameConstants> = ctx.read_buffer(&frames, 0, 2).unwrap();
        for e in 0..2 {
            check_fields!(
                format!("FrameConstants[{e}] (std140)"),
                got[e as usize],
                expected_frame(e),
                [
                    light_view_proj,
                    light_position,
                    light_kind,
                    light_direction,
                    light_extent,
                    light_resolution,
                    counts,
                    camera_origin
                ]
            );
        }
        let got: Vec<ScanPush> = ctx.read_buffer(&scans, 0, 2).unwrap();
        for e in 0..2u32 {
            let b = 4000 + 100 * e;
            let want = ScanPush {
                n: b,
                flags: b + 1,
                group_count: b + 2,
                groups_x: b + 3,
            };
            check_fields!(
                format!("ScanPush[{e}]"),
                got[e as usize],
                want,
                [n, flags, group_count, groups_x]
            );
        }

        // Read direction: the uniform and push constants, scalar by scalar in
        // declaration order, equal the Rust struct's words in memory order.
        let got: Vec<u32> = ctx.read_buffer(&flat, 0, flat_len).unwrap();
        let mut want: Vec<u32> = bytemuck::cast_slice(std::slice::from_ref(&frame_in)).to_vec();
        want.extend_from_slice(bytemuck::cast_slice(std::slice::from_ref(&push)));
        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!(g, w, "uniform FrameConstants / push ScanPush scalar {k}");
        }
    }
    let messages = ctx.validation_messages();
    drop(ctx);
    let m = messages.lock().unwrap();
    assert!(m.is_empty(), "validation messages:\n{}", m.join("\n"));
}
