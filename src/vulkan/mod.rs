//! The small Vulkan backend every compute pass is built on: one concept per
//! file, after the layout of EmbarkStudios/kajiya.
//!
//! - [`instance`]: loader, instance and the validation-message sink;
//! - [`device`]: physical-device choice, [`DeviceInfo`] and [`list_devices`];
//! - [`context`]: [`GpuContext`], the handle passes hold (device, queue,
//!   allocator) with [`GpuContext::submit_and_wait`];
//! - [`commands`]: [`CommandRecorder`], one command buffer being recorded,
//!   with dispatch and binding helpers;
//! - [`buffer`] and [`image`]: resources through `gpu-allocator`; a
//!   [`GrowBuffer`] lives across frames and grows only when a frame needs more;
//! - [`shader`] and [`pipeline`]: compute pipelines with specialization and
//!   push constants;
//! - [`barrier`]: the memory barriers between passes;
//! - [`profiler`]: timestamp queries per named pass.
//!
//! Every Vulkan object is owned by a Rust value that destroys it on `Drop`,
//! and every such value holds an `Arc` of the device, so objects are always
//! destroyed before the device and the device before the instance, also on
//! error paths.
//!
//! A later pass (count per light texel, scan, scatter) typically does:
//! ```no_run
//! use alias_free_shadows::gpu::scan::ScanPass;
//! use alias_free_shadows::gpu::shaders;
//! use alias_free_shadows::vulkan::*;
//! # fn main() -> alias_free_shadows::Result<()> {
//! let ctx = GpuContext::new(&ContextOptions::default())?; // AFS_VALIDATION, AFS_DEVICE
//! let texels = 512 * 512u64;
//! // Buffers the pass owns (GPU-only; `upload`/`read_buffer` pick mapped
//! // copies or staging as the memory allows).
//! let counts = ctx.create_buffer(BufferDesc::storage("counts", 4 * texels))?;
//! let offsets = ctx.create_buffer(BufferDesc::storage("offsets", 4 * (texels + 1)))?;
//! // Pipelines are made once: bindings 0, 1, ... of set 0 by kind, push
//! // constants, specialization constants (id, value).
//! let count_pass = ctx.create_compute_pipeline(&ComputePipelineDesc {
//!     name: "count",
//!     spirv: shaders::BINDING_PROBE, // your shaders::COUNT_SAMPLES
//!     bindings: &[DescriptorKind::StorageBuffer, DescriptorKind::UniformBuffer],
//!     push_constant_bytes: 4,
//!     specialization: &[(0, 64)],
//! })?;
//! let frame = ctx.create_buffer(BufferDesc::uniform("frame", 160))?;
//! let mut scan = ScanPass::new(&ctx)?;
//! let mut profiler = Profiler::new(&ctx, 8)?;
//!
//! let mut rec = ctx.begin()?;
//! rec.fill_buffer(counts.whole(), 0)?;
//! rec.barrier(Barrier::TransferToCompute);
//! let p = profiler.begin(&mut rec, "count")?;
//! rec.dispatch(
//!     &count_pass,
//!     &[Binding::storage(&counts), Binding::uniform(&frame)],
//!     &1024u32.to_ne_bytes(),
//!     [1024 / 64, 1, 1],
//! )?;
//! profiler.end(&mut rec, p);
//! let p = profiler.begin(&mut rec, "scan")?;
//! scan.record(&mut rec, counts.whole(), offsets.whole(), texels as u32)?; // offsets[texels] = total
//! profiler.end(&mut rec, p);
//! rec.barrier(Barrier::ComputeToCompute); // before the scatter reads `offsets`
//! // ... scatter dispatch ...
//! ctx.submit_and_wait(rec)?; // fence with timeout; validation errors become Err
//! let total: Vec<u32> = ctx.read_buffer(&offsets, 4 * texels, 1)?;
//! for t in profiler.results()? {
//!     println!("{}: {:?} ms", t.name, t.ms);
//! }
//! # Ok(()) }
//! ```

pub mod barrier;
pub mod buffer;
pub mod commands;
pub mod context;
pub mod device;
pub mod graphics;
pub mod image;
pub mod instance;
pub mod pipeline;
pub mod profiler;
pub mod shader;

pub use ash::vk;
pub use barrier::Barrier;
pub use buffer::{
    storage_binding_ranges, Buffer, BufferDesc, BufferSlice, GrowBuffer, MemoryLocation,
};
pub use commands::CommandRecorder;
pub use context::{ContextOptions, GpuContext};
pub use device::{
    list_devices, Allocations, Device, DeviceFeatures, DeviceInfo, DeviceLimits,
    DeviceRequirements, DeviceType, ExternalDevice, MemoryHeapInfo,
};
pub use graphics::{
    vertex_input_barrier, Attachment, Draw, Framebuffer, GraphicsPipeline, GraphicsPipelineDesc,
    VertexAttribute,
};
pub use image::{Image, ImageDesc};
pub use instance::{Instance, ValidationLevel, ValidationMessages};
pub use pipeline::{
    Binding, ComputePipeline, ComputePipelineDesc, DescriptorKind, SPREAD_THREADS_ID,
};
pub use profiler::{PassTiming, Profiler};
pub use shader::ShaderModule;
