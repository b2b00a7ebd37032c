//! The light's frusta fitted to the view samples (paper §4.3): which light
//! face each view sample falls in, and per face the window around the
//! projected samples with the far plane at the farthest one.
//!
//! Shaders `light_view_fit.comp` (per view sample: atomic min/max of its
//! projection as order-preserving keys) and `light_view_finalize.comp` (one
//! invocation: keys to windows). CPU twin: [`crate::cpu::light_view`].

use crate::gpu::dispatch::{groups, storage};
use crate::gpu::light_frame::Recording;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::vulkan::{
    Barrier, ComputePipeline, ComputePipelineDesc, DescriptorKind, GpuContext, GrowBuffer,
};
use crate::Result;

/// View samples per invocation of the fit (`FIT_PER_LANE`,
/// `light_view_fit.comp`).
const FIT_PER_LANE: u32 = 16;

/// The fit's pipelines and what they write.
pub struct LightViewPass {
    fit: ComputePipeline,
    finalize: ComputePipeline,
    /// Per face: 8 words of fit keys (`FIT_EMPTY` before the fit).
    fit_keys: GrowBuffer,
    /// Per face: its basis and fitted window (`LightFace`), read alike by
    /// every invocation of later passes: bound as a uniform buffer there.
    pub faces: GrowBuffer,
}

impl LightViewPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let sb = DescriptorKind::StorageBuffer;
        let make = |name, spirv| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name,
                spirv,
                bindings: &[sb; 2],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[],
            })
        };
        Ok(LightViewPass {
            fit: make("light_view_fit", shaders::LIGHT_VIEW_FIT)?,
            finalize: make("light_view_finalize", shaders::LIGHT_VIEW_FINALIZE)?,
            fit_keys: GrowBuffer::storage("light_fit_keys"),
            faces: GrowBuffer::storage_uniform("light_faces"),
        })
    }

    /// Sizes the buffers.
    pub fn prepare(&mut self, ctx: &GpuContext) -> Result<()> {
        self.fit_keys.get(ctx, 4 * 8 * 6)?;
        self.faces.get(ctx, 128 * 6)?;
        Ok(())
    }

    /// Records the fit of every face's window to the run's view samples.
    pub fn record(&self, r: &mut Recording) -> Result<()> {
        // The fit keys start empty: recorded, not uploaded, so that lights
        // recorded into one command buffer each start afresh.
        let mut fit_init = [0u32; 48];
        for f in 0..6 {
            fit_init[f * 8] = u32::MAX;
            fit_init[f * 8 + 1] = u32::MAX;
        }
        r.cmd.barrier(Barrier::ComputeToTransfer);
        r.cmd
            .update_buffer(self.fit_keys.buffer(), 0, bytemuck::cast_slice(&fit_init))?;
        r.cmd.barrier(Barrier::TransferToCompute);
        let (samples, n) = (r.inputs.samples, r.frame.n);
        r.pass("light_fit", |rec, pc| {
            let keys = storage(&self.fit_keys);
            rec.dispatch(
                &self.fit,
                &[storage(samples), keys],
                pc,
                groups(n.div_ceil(FIT_PER_LANE)),
            )?;
            rec.barrier(Barrier::ComputeToCompute);
            rec.dispatch(&self.finalize, &[keys, storage(&self.faces)], pc, [1, 1, 1])?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })
    }

    /// Bytes this run binds.
    pub fn bytes(&self) -> u64 {
        self.fit_keys.len() + self.faces.len()
    }
}
