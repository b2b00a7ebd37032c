//! The last pass of a light (paper §3, §4): per view sample, whether the
//! shadow passes evaluated it and its visibility. Hard shadows
//! (`resolve_hard.comp`): lit = not shadowed. Soft shadows
//! (`resolve_soft.comp`): the visible light samples are those in front of
//! the sample's surface (the oracle's normal rule) and not blocked;
//! visibility = their count / light samples. CPU twin: [`crate::cpu::resolve`].

use crate::gpu::dispatch::{groups, storage};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::Recording;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::soft_occlusion::SoftOcclusionPass;
use crate::gpu::texel_lists::TexelListPass;
use crate::vulkan::{
    Barrier, Binding, ComputePipeline, ComputePipelineDesc, DescriptorKind, GpuContext, GrowBuffer,
};
use crate::Result;

/// The resolve pipelines and what they write.
pub struct ResolvePass {
    hard: ComputePipeline,
    soft: ComputePipeline,
    /// The soft resolve with the per-pixel rotation, made when first needed.
    soft_rotated: Option<ComputePipeline>,
    /// Per view sample. Hard: bit 0 lit, bit 1 evaluated. Soft: visibility
    /// as `f32` bits, −1 where not evaluated.
    pub result: GrowBuffer,
    /// Soft: per view sample, its visible light samples, `mask_words` words.
    pub visible: GrowBuffer,
}

impl ResolvePass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let sb = DescriptorKind::StorageBuffer;
        let make = |name, spirv, bindings: &[DescriptorKind]| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name,
                spirv,
                bindings,
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[],
            })
        };
        Ok(ResolvePass {
            hard: make("resolve_hard", shaders::RESOLVE_HARD, &[sb; 4])?,
            soft: soft_pipeline(ctx, false)?,
            soft_rotated: None,
            result: GrowBuffer::storage("result"),
            visible: GrowBuffer::storage("visible_masks"),
        })
    }

    /// Sizes the buffers; with `rotated`, makes the soft resolve with the
    /// per-pixel rotation (when first needed).
    pub fn prepare(&mut self, ctx: &GpuContext, frame: &LightFrame, rotated: bool) -> Result<()> {
        if rotated && self.soft_rotated.is_none() {
            self.soft_rotated = Some(soft_pipeline(ctx, true)?);
        }
        let n = frame.n as u64;
        self.result.get(ctx, 4 * n)?;
        if frame.mask_words > 0 {
            self.visible.get(ctx, 4 * frame.mask_words * n)?;
        }
        Ok(())
    }

    /// Records the hard resolve of the shadow flags; ends with a barrier to
    /// the host.
    pub fn record_hard(
        &self,
        r: &mut Recording,
        lists: &TexelListPass,
        shadowed: &GrowBuffer,
    ) -> Result<()> {
        let n = r.frame.n;
        r.pass("resolve", |rec, pc| {
            let bindings = [
                storage(&lists.sample_texel),
                storage(&lists.sample_slot),
                storage(shadowed),
                storage(&self.result),
            ];
            rec.dispatch(&self.hard, &bindings, pc, groups(n))?;
            rec.barrier(Barrier::ComputeToHost);
            Ok(())
        })
    }

    /// Records the soft resolve of the blocked masks (`rotated`: with the
    /// light's per-pixel rotation); ends with a barrier to the host.
    pub fn record_soft(
        &self,
        r: &mut Recording,
        lists: &TexelListPass,
        occlusion: &SoftOcclusionPass,
        rotated: bool,
    ) -> Result<()> {
        let (samples, n) = (r.inputs.samples, r.frame.n);
        let pipeline = match rotated {
            true => self.soft_rotated.as_ref().ok_or_else(|| {
                crate::Error::InvalidInput("the rotated resolve was not prepared".into())
            })?,
            false => &self.soft,
        };
        r.pass("soft_resolve", |rec, pc| {
            let bindings = [
                storage(samples),
                storage(&lists.sample_texel),
                storage(&lists.sample_slot),
                storage(&occlusion.blocked),
                storage(&self.visible),
                storage(&self.result),
                Binding::uniform(&occlusion.light_samples),
                Binding::uniform(&occlusion.pixel_rotation),
            ];
            rec.dispatch(pipeline, &bindings, pc, groups(n))?;
            rec.barrier(Barrier::ComputeToHost);
            Ok(())
        })
    }
}

/// The soft resolve; `rotated`: with the per-pixel rotation
/// (specialization constant 6).
fn soft_pipeline(ctx: &GpuContext, rotated: bool) -> Result<ComputePipeline> {
    let (sb, ub) = (DescriptorKind::StorageBuffer, DescriptorKind::UniformBuffer);
    ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
        name: if rotated {
            "resolve_soft_rotated"
        } else {
            "resolve_soft"
        },
        spirv: shaders::RESOLVE_SOFT,
        bindings: &[sb, sb, sb, sb, sb, sb, ub, ub],
        push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
        specialization: &[(6, rotated as u32)],
    })
}
