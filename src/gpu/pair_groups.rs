//! Per binned pair of a tile, the groups of the tile's listed samples it may
//! shadow (`pair_groups.comp`): the chunk rules of soft occlusion
//! (`clusters_common.glsl`, `chunk_rule`) for the boxes of the groups of
//! [`CLUSTER_GROUP_SAMPLES`] samples the tile's samples fall in
//! ([`ClusterPass`]'s group boxes), one bit per group. A tile of thousands
//! of samples (a car over a ground, seen from the light) has dozens of
//! chunks of 64, and each chunk judged each of the tile's pairs by those
//! rules on its own box: now a chunk first skips the pairs that both of
//! its groups dropped (`soft_occlusion.comp`, `keep_pairs`), and judges
//! only the rest. Soft shadows only. CPU twin:
//! [`crate::cpu::pair_groups`].

use crate::cpu::clusters::CLUSTER_GROUP_SAMPLES;
use crate::gpu::casters::CasterPass;
use crate::gpu::clusters::ClusterPass;
use crate::gpu::dispatch::{groups, storage, R32UI, RGBA32UI};
use crate::gpu::light_frame::Recording;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::texel_lists::TexelListPass;
use crate::gpu::tile_bin::TileBinPass;
use crate::vulkan::{
    Barrier, Binding, ComputePipeline, ComputePipelineDesc, DescriptorKind, GpuContext, GrowBuffer,
};
use crate::Result;

/// Slots of the tile lists per invocation (`SLOTS_PER_LANE` in
/// `pair_groups.comp`).
const SLOTS_PER_LANE: u64 = 16;

// A chunk of 64 samples lies in at most two groups (keep_pairs tests two
// bits).
const _: () = assert!(CLUSTER_GROUP_SAMPLES >= 64 && CLUSTER_GROUP_SAMPLES.is_multiple_of(64));

/// The pipeline and the bits it writes.
pub struct PairGroupPass {
    pipeline: ComputePipeline,
    /// Per slot of the tile lists ([`TileBinPass::tile_pairs`]) of a tile
    /// whose samples span at least `CLUSTER_GROUP_MIN` groups: bit `j` set
    /// where the pair may shadow a sample of its tile's `j`-th group
    /// (nothing written for the other tiles' slots).
    pub groups: GrowBuffer,
}

impl PairGroupPass {
    /// Builds the pipeline.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let tb = DescriptorKind::UniformTexelBuffer;
        let sb = DescriptorKind::StorageBuffer;
        let pipeline = ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
            name: "pair_groups",
            spirv: shaders::PAIR_GROUPS,
            bindings: &[tb, sb, tb, sb, tb, sb],
            push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
            specialization: &[],
        })?;
        Ok(PairGroupPass {
            pipeline,
            groups: GrowBuffer::storage("pair_groups"),
        })
    }

    /// Sizes the bits for every slot of `bins`' list of binned pairs (as
    /// sized now: by the count, or by a caller's capacity).
    pub fn prepare(&mut self, ctx: &GpuContext, bins: &TileBinPass) -> Result<()> {
        self.groups.get(ctx, bins.tile_pairs.len().max(4))?;
        Ok(())
    }

    /// Records the bits of the binned pairs (after tile binning's
    /// scatter): `SLOTS_PER_LANE` (16) slots of the tile lists per invocation,
    /// over the `binned` pairs the host read back, or over the list's
    /// capacity in a caller's recording (`None`: the slots past the binned
    /// pairs do nothing).
    pub fn record(
        &mut self,
        r: &mut Recording,
        (lists, casters, bins, clusters): (&TexelListPass, &CasterPass, &TileBinPass, &ClusterPass),
        binned: Option<u32>,
    ) -> Result<()> {
        self.prepare(r.ctx, bins)?;
        let slots = binned.map_or(bins.tile_pairs.len() / 4, u64::from);
        let invocations = slots.div_ceil(SLOTS_PER_LANE);
        let groups_buf = &self.groups;
        let pipeline = &self.pipeline;
        r.pass("pair_groups", |rec, pc| {
            rec.barrier(Barrier::ComputeToCompute);
            let bindings = [
                Binding::uniform_texel(&casters.pairs, RGBA32UI),
                storage(&bins.tile_offsets),
                Binding::uniform_texel(&bins.tile_pairs, R32UI),
                storage(&lists.offsets),
                Binding::uniform_texel(&clusters.boxes, RGBA32UI),
                storage(groups_buf),
            ];
            rec.dispatch(pipeline, &bindings, pc, groups(invocations.max(1) as u32))?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })
    }

    /// Bytes this run binds.
    pub fn bytes(&self) -> u64 {
        self.groups.len()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn slots_per_lane_match_the_shader() {
        let glsl = include_str!("../../shaders/pair_groups.comp");
        let define = crate::gpu::shared::tests::glsl_define(glsl, "SLOTS_PER_LANE");
        assert_eq!(define, Some(super::SLOTS_PER_LANE));
    }
}
