//! Hard-shadow occlusion (paper §3.3): every listed view sample of every
//! texel a tile's (caster, face) pairs may touch, against each pair's four
//! planes; a hit sets the sample's shadow flag. Shader `occlusion.comp`,
//! one workgroup per work unit (`tile_bin_units.comp`). CPU twin:
//! [`crate::cpu::occlusion`].

use crate::gpu::dispatch::{groups_2d, require_occlusion_subgroup_ops, storage, RGBA32UI};
use crate::gpu::light_frame::{CasterRound, Recording, UNITS_INDIRECT};
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::{casters::CasterPass, texel_lists::TexelListPass, tile_bin::TileBinPass};
use crate::vulkan::{
    vk, Barrier, Binding, ComputePipeline, ComputePipelineDesc, DescriptorKind, GpuContext,
    GrowBuffer,
};
use crate::Result;

/// The occlusion pipelines and the shadow flags they set.
pub struct OcclusionPass {
    /// Opaque casters, and the alpha-tested casters' round (their alpha
    /// tests: specialization constant `ALPHA`).
    occlusion: [ComputePipeline; 2],
    /// Per list slot: non-zero when some caster blocks the light.
    pub shadowed: GrowBuffer,
}

impl OcclusionPass {
    /// Builds the pipeline.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        require_occlusion_subgroup_ops(ctx, "occlusion")?;
        let sb = DescriptorKind::StorageBuffer;
        let tb = DescriptorKind::UniformTexelBuffer;
        let make = |alpha: bool| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name: if alpha {
                    "occlusion_alpha"
                } else {
                    "occlusion"
                },
                spirv: shaders::OCCLUSION,
                bindings: &[tb, tb, sb, tb, sb, sb, tb, sb, sb, sb, tb, tb, tb, tb],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[(5, alpha as u32)],
            })
        };
        Ok(OcclusionPass {
            occlusion: [make(false)?, make(true)?],
            shadowed: GrowBuffer::storage("shadowed"),
        })
    }

    /// Records the occlusion of every listed sample by its tile's casters
    /// (once the work units are known), ORed into the flags of the rounds
    /// before unless `first`.
    pub fn record(
        &mut self,
        r: &mut Recording,
        (lists, casters, bins): (&TexelListPass, &CasterPass, &TileBinPass),
        counters: &GrowBuffer,
        first: bool,
    ) -> Result<()> {
        self.shadowed.get(r.ctx, 4 * r.frame.n as u64)?;
        if first {
            r.cmd.fill_buffer(self.shadowed.slice(), 0)?;
        }
        r.cmd.barrier(Barrier::TransferToCompute);
        let (shadowed, units) = (&self.shadowed, r.frame.units());
        let pipeline = &self.occlusion[usize::from(r.round == CasterRound::Alpha)];
        let triangles = r.inputs.triangles;
        let [records, textures, alphas] = r.inputs.alpha.bindings();
        r.pass("occlusion", |rec, pc| {
            let bindings = [
                Binding::uniform_texel(&casters.pairs, RGBA32UI),
                Binding::uniform_texel(&casters.planes, RGBA32UI),
                storage(&bins.tile_offsets),
                Binding::uniform_texel(&bins.tile_pairs, vk::Format::R32_UINT),
                storage(&lists.counts),
                storage(&lists.offsets),
                Binding::uniform_texel(&lists.list_samples, RGBA32UI),
                storage(shadowed),
                storage(counters),
                storage(&bins.unit_offsets),
                Binding::uniform_texel(triangles, RGBA32UI),
                records,
                textures,
                alphas,
            ];
            if units == UNITS_INDIRECT {
                rec.dispatch_indirect(pipeline, &bindings, pc, bins.dispatch_args.buffer())?;
            } else {
                rec.dispatch(pipeline, &bindings, pc, groups_2d(units.max(1)))?;
            }
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })
    }
}
