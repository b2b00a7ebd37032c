//! The small Vulkan backend every compute pass is built on: one concept per
//! file, after the layout of EmbarkStudios/kajiya.
//!
//! - [`instance`]: loader, instance and the validation-message sink;
//! - [`device`]: physical-device choice, [`DeviceInfo`] and [`list_devices`];
//! - [`context`]: [`GpuContext`], the handle passes hold (device, queue,
//!   allocator) with [`GpuContext::submit_and_wait`];
//! - [`commands`]: [`CommandRecorder`], one command buffer being recorded,
//!   with dispatch and binding helpers;
//! - [`buffer`] and [`image`]: resources through `gpu-allocator`;
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
//! A later pass typically does:
//! ```no_run
//! use alias_free_shadows::vulkan::*;
//! # fn main() -> alias_free_shadows::Result<()> {
//! let ctx = GpuContext::new(&ContextOptions::default())?;
//! let data = ctx.create_buffer_with_data(BufferDesc::storage("counts", 1024 * 4), &[1u32; 1024])?;
//! let pipeline = ctx.create_compute_pipeline(&ComputePipelineDesc {
//!     name: "my_pass",
//!     spirv: alias_free_shadows::gpu::shaders::SCAN_REDUCE, // your shader's words
//!     bindings: &[DescriptorKind::StorageBuffer, DescriptorKind::StorageBuffer],
//!     push_constant_bytes: 16,
//!     specialization: &[(0, 256)],
//! })?;
//! let mut rec = ctx.begin()?;
//! rec.barrier(Barrier::TransferToCompute);
//! rec.dispatch(&pipeline, &[Binding::storage(&data), Binding::storage(&data)], &[0u8; 16], [1, 1, 1])?;
//! ctx.submit_and_wait(rec)?;
//! let back: Vec<u32> = ctx.read_buffer(&data, 0, 1024)?;
//! # Ok(()) }
//! ```

pub mod barrier;
pub mod buffer;
pub mod commands;
pub mod context;
pub mod device;
pub mod image;
pub mod instance;
pub mod pipeline;
pub mod profiler;
pub mod shader;

pub use ash::vk;
pub use barrier::Barrier;
pub use buffer::{storage_binding_ranges, Buffer, BufferDesc, BufferSlice, MemoryLocation};
pub use commands::CommandRecorder;
pub use context::{ContextOptions, GpuContext};
pub use device::{list_devices, Device, DeviceInfo, DeviceLimits, DeviceType, MemoryHeapInfo};
pub use image::{Image, ImageDesc};
pub use instance::{Instance, ValidationLevel, ValidationMessages};
pub use pipeline::{Binding, ComputePipeline, ComputePipelineDesc, DescriptorKind};
pub use profiler::{PassTiming, Profiler};
pub use shader::ShaderModule;
