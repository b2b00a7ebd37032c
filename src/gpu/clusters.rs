//! View-sample clusters (Sintorn, Kämpe, Olsson, Assarsson 2014): per tile
//! of light texels, the box of its listed view samples
//! (`clusters_bounds.comp`), and per block of tiles the union of its tiles'
//! boxes. Tile binning tests each caster against the boxes of the tiles it
//! covers (a caster of many tiles against their blocks' boxes first) and
//! drops it where it cannot block any of their samples (`clusters_common.glsl`, `bin_rule`: every sample on the
//! light's side of its plane, or behind a closed caster; for soft shadows
//! also the caster beyond the reach of every sample, or outside the hull of
//! the box's ball and the light), so that occlusion never visits the pair.
//! Soft occlusion applies those rules and the penumbra rule to the box of each
//! workgroup's 64 samples (and their texels to each pair's rectangle) and
//! compacts the unit's pairs before its loop (`soft_occlusion.comp`,
//! `keep_pairs`): on lavapipe every lane runs every iteration, so only a
//! shorter loop saves time. The rules are occlusion's own per-sample early
//! outs taken for a whole box with a margin far above their rounding: the
//! masks stay bit-identical. Where a tile holds thousands of samples, the
//! chunk rules would judge each of its pairs once per chunk: the boxes of
//! groups of [`CLUSTER_GROUP_SAMPLES`] listed samples (after the blocks')
//! let [`crate::gpu::pair_groups`] judge them once per group first. CPU
//! twin: [`crate::cpu::clusters`].

use crate::cpu::clusters::{CLUSTER_BLOCK, CLUSTER_GROUP_SAMPLES};
use crate::gpu::dispatch::{groups, storage, RGBA32UI};
use crate::gpu::light_frame::{LightFrame, Recording};
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::texel_lists::TexelListPass;
use crate::vulkan::{
    Barrier, Binding, ComputePipeline, ComputePipelineDesc, DescriptorKind, GpuContext, GrowBuffer,
};
use crate::Result;

/// The bounds pipelines and the boxes they write.
pub struct ClusterPass {
    bounds: ComputePipeline,
    block_bounds: ComputePipeline,
    group_bounds: ComputePipeline,
    /// Per tile, then per block of [`CLUSTER_BLOCK`]² tiles (face by face,
    /// row by row; tile binning tests the pairs of many tiles against
    /// them first), then per group of [`CLUSTER_GROUP_SAMPLES`] listed
    /// samples: two `vec4`, lo (w: 1 when valid) and hi.
    pub boxes: GrowBuffer,
    /// When false the boxes are all invalid (zeros): nothing is culled.
    pub enabled: bool,
}

impl ClusterPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let make = |name, specialization: &[(u32, u32)]| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name,
                spirv: shaders::CLUSTERS_BOUNDS,
                bindings: &[
                    DescriptorKind::StorageBuffer,
                    DescriptorKind::UniformTexelBuffer,
                    DescriptorKind::StorageBuffer,
                ],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization,
            })
        };
        Ok(ClusterPass {
            bounds: make("clusters_bounds", &[])?,
            block_bounds: make("clusters_block_bounds", &[(1, 1)])?,
            group_bounds: make("clusters_group_bounds", &[(1, 2)])?,
            boxes: GrowBuffer::storage("cluster_boxes"),
            enabled: true,
        })
    }

    /// Blocks of the frame's tiles.
    pub fn blocks(frame: &LightFrame) -> u32 {
        frame.faces * frame.tiles_per_row.div_ceil(CLUSTER_BLOCK).pow(2)
    }

    /// Groups of listed samples the frame can have (every view sample
    /// listed).
    pub fn groups(frame: &LightFrame) -> u32 {
        frame.n.div_ceil(CLUSTER_GROUP_SAMPLES)
    }

    /// Sizes the boxes for the frame's tiles, blocks and groups.
    pub fn prepare(&mut self, ctx: &GpuContext, frame: &LightFrame) -> Result<()> {
        let boxes = frame.tiles as u64 + Self::blocks(frame) as u64 + Self::groups(frame) as u64;
        self.boxes.get(ctx, 32 * boxes)?;
        Ok(())
    }

    /// Records the boxes of the tiles' listed samples (after the lists'
    /// scatter), or their clear when culling is off. Hard shadows get no
    /// boxes: there the rules removed 1-3% of the tests and cost more than
    /// that in binning (warm frames of torus_knot:100000, ToyCar, hairball).
    pub fn record(&self, r: &mut Recording, lists: &TexelListPass, soft: bool) -> Result<()> {
        let tiles = r.frame.tiles;
        let blocks = Self::blocks(&r.frame);
        let sample_groups = Self::groups(&r.frame);
        r.pass("cluster_bounds", |rec, pc| {
            if !self.enabled || !soft {
                rec.fill_buffer(self.boxes.slice(), 0)?;
                rec.barrier(Barrier::TransferToCompute);
                return Ok(());
            }
            rec.barrier(Barrier::ComputeToCompute);
            let bindings = [
                storage(&lists.offsets),
                Binding::uniform_texel(&lists.list_samples, RGBA32UI),
                storage(&self.boxes),
            ];
            rec.dispatch(&self.bounds, &bindings, pc, groups(tiles))?;
            rec.barrier(Barrier::ComputeToCompute);
            rec.dispatch(&self.block_bounds, &bindings, pc, groups(blocks))?;
            rec.dispatch(&self.group_bounds, &bindings, pc, groups(sample_groups))?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })
    }

    /// Bytes this run binds.
    pub fn bytes(&self) -> u64 {
        self.boxes.len()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn block_constants_match_the_shaders() {
        let glsl = include_str!("../../shaders/clusters_common.glsl");
        let define = |name: &str| crate::gpu::shared::tests::glsl_define(glsl, name);
        use crate::cpu::clusters::*;
        assert_eq!(define("CLUSTER_BLOCK"), Some(CLUSTER_BLOCK as u64));
        assert_eq!(
            define("CLUSTER_GROUP_SAMPLES"),
            Some(CLUSTER_GROUP_SAMPLES as u64)
        );
        assert_eq!(
            define("CLUSTER_GROUP_BITS"),
            Some(CLUSTER_GROUP_BITS as u64)
        );
        assert_eq!(define("CLUSTER_GROUP_MIN"), Some(CLUSTER_GROUP_MIN as u64));
        assert_eq!(
            define("CLUSTER_BLOCK_MIN_TILES"),
            Some(CLUSTER_BLOCK_MIN_TILES as u64)
        );
        // In shadow_common.glsl: caster setup lists the large pairs too.
        let shadow_common = include_str!("../../shaders/shadow_common.glsl");
        assert_eq!(
            crate::gpu::shared::tests::glsl_define(shadow_common, "CLUSTER_BLOCK_PAIR_TILES"),
            Some(CLUSTER_BLOCK_PAIR_TILES as u64)
        );
    }
}
