//! A light's visibility into a caller's target ([`crate::render::Engine::record_frame`]):
//! one `f32` per view sample, from the resolve pass's result
//! (`shaders/visibility_out.glsl`), into a storage buffer
//! (`visibility_out_buffer.comp`) or an `R32_SFLOAT` storage image
//! (`visibility_out_image.comp`). The value is what [`crate::render::Frame`]'s dump
//! holds: the visible fraction, 0 where no sample was evaluated. CPU twin:
//! [`crate::cpu::visibility_out`].

use crate::gpu::dispatch::{groups, storage};
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::vulkan::{
    vk, Barrier, Binding, BufferSlice, CommandRecorder, ComputePipeline, ComputePipelineDesc,
    DescriptorKind, GpuContext,
};
use crate::Result;

/// Where a recorded light's visibility goes.
#[derive(Clone, Copy)]
pub enum OutTarget<'a> {
    /// One `f32` per view sample.
    Buffer(BufferSlice<'a>),
    /// An `R32_SFLOAT` storage image in `GENERAL` layout, view sample
    /// `y · width + x` at texel `(x, y)`.
    Image(vk::ImageView),
}

/// The two shaders, each hard or soft (specialization constant 0).
pub struct VisibilityOutPass {
    /// `[to buffer, to image][soft]`.
    pipelines: [[ComputePipeline; 2]; 2],
}

impl VisibilityOutPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let sb = DescriptorKind::StorageBuffer;
        let make = |name, spirv, target: DescriptorKind, soft: bool| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name,
                spirv,
                bindings: &[sb, target],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[(0, soft as u32)],
            })
        };
        let buffer = shaders::VISIBILITY_OUT_BUFFER;
        let image = shaders::VISIBILITY_OUT_IMAGE;
        let si = DescriptorKind::StorageImage;
        Ok(VisibilityOutPass {
            pipelines: [
                [
                    make("visibility_out_buffer", buffer, sb, false)?,
                    make("visibility_out_buffer_soft", buffer, sb, true)?,
                ],
                [
                    make("visibility_out_image", image, si, false)?,
                    make("visibility_out_image_soft", image, si, true)?,
                ],
            ],
        })
    }

    /// Records the conversion of `result` (the resolve pass's, `n` view
    /// samples, soft or hard) into `target`, with `push` the light's push
    /// constants (`sizes.x` = n).
    pub fn record(
        &self,
        rec: &mut CommandRecorder,
        result: BufferSlice,
        soft: bool,
        target: OutTarget,
        push: &LightPush,
    ) -> Result<()> {
        let n = push.sizes[0];
        let (pipeline, binding) = match target {
            OutTarget::Buffer(b) => (&self.pipelines[0][usize::from(soft)], storage(b)),
            OutTarget::Image(v) => (
                &self.pipelines[1][usize::from(soft)],
                Binding::StorageImageView(v),
            ),
        };
        let bindings = [storage(result), binding];
        // The resolve pass ends with a barrier to the host only.
        rec.barrier(Barrier::ComputeToCompute);
        rec.dispatch(pipeline, &bindings, bytemuck::bytes_of(push), groups(n))
    }
}
