//! Soft-shadow occlusion (paper §4.2): per listed view sample and each
//! caster whose influence region covers its texel, the light samples the
//! caster hides, the AND of its four planes' bits, ORed into the sample's
//! blocked mask. The bits come from the plane look-up texture (LUT mode,
//! every 128-sample block in one pass) or from testing every light sample
//! (exact mode, one pass per block). Shader `soft_occlusion.comp`, compiled
//! once per mode and block count (`build.rs`). CPU twin:
//! [`crate::cpu::soft_occlusion`].

use crate::gpu::dispatch::{groups_2d, storage, RGBA32UI};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::Recording;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::soft_light::{SoftLight, MAX_SOFT_SAMPLES};
use crate::gpu::tile_bin::SOFT_PAIR_CHUNK;
use crate::gpu::{casters::CasterPass, texel_lists::TexelListPass, tile_bin::TileBinPass};
use crate::vulkan::{
    vk, Barrier, Binding, Buffer, ComputePipeline, ComputePipelineDesc, DescriptorKind, GpuContext,
    GrowBuffer,
};
use crate::Result;

/// The soft occlusion pipelines and the masks they write.
pub struct SoftOcclusionPass {
    /// LUT mode, one pipeline per number of 128-sample blocks (1 to 8).
    lut: Vec<ComputePipeline>,
    exact: ComputePipeline,
    /// Per list slot: blocked light samples, `mask_words` words.
    pub blocked: GrowBuffer,
    /// The camera-relative light samples (uniform buffer).
    pub light_samples: GrowBuffer,
    /// Bound in place of the table in exact mode (a view may not be empty).
    no_table: GrowBuffer,
}

impl SoftOcclusionPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let sb = DescriptorKind::StorageBuffer;
        let tb = DescriptorKind::UniformTexelBuffer;
        let ub = DescriptorKind::UniformBuffer;
        let make = |name: &str, spirv| {
            ctx.create_compute_pipeline(&ComputePipelineDesc {
                name,
                spirv,
                bindings: &[tb, tb, sb, tb, sb, sb, tb, sb, sb, sb, ub, tb],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[SOFT_PAIR_CHUNK],
            })
        };
        Ok(SoftOcclusionPass {
            lut: [
                shaders::SOFT_OCCLUSION_LUT1,
                shaders::SOFT_OCCLUSION_LUT2,
                shaders::SOFT_OCCLUSION_LUT3,
                shaders::SOFT_OCCLUSION_LUT4,
                shaders::SOFT_OCCLUSION_LUT5,
                shaders::SOFT_OCCLUSION_LUT6,
                shaders::SOFT_OCCLUSION_LUT7,
                shaders::SOFT_OCCLUSION_LUT8,
            ]
            .iter()
            .enumerate()
            .map(|(b, spirv)| make(&format!("soft_occlusion_lut{}", b + 1), spirv))
            .collect::<Result<_>>()?,
            exact: make("soft_occlusion_exact", shaders::SOFT_OCCLUSION_EXACT)?,
            blocked: GrowBuffer::storage("blocked_masks"),
            light_samples: GrowBuffer::storage_uniform("light_samples"),
            no_table: GrowBuffer::storage("plane_lut_unused"),
        })
    }

    /// Sizes the buffers and uploads the light samples (before the run's
    /// first recording).
    pub fn prepare(&mut self, ctx: &GpuContext, frame: &LightFrame, sl: &SoftLight) -> Result<()> {
        self.blocked
            .get(ctx, 4 * frame.mask_words * frame.n as u64)?;
        let ubo = self.light_samples.get(ctx, 16 * MAX_SOFT_SAMPLES as u64)?;
        let v: Vec<[f32; 4]> = sl.samples.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect();
        ctx.upload_staged(ubo, 0, &v)?;
        self.no_table.get(ctx, 16)?;
        Ok(())
    }

    /// Records the occlusion passes (once the work units are known; `table`:
    /// the plane look-up texture in LUT mode).
    pub fn record(
        &self,
        r: &mut Recording,
        sl: &SoftLight,
        table: Option<&Buffer>,
        (lists, casters, bins): (&TexelListPass, &CasterPass, &TileBinPass),
        counters: &GrowBuffer,
    ) -> Result<()> {
        r.cmd.fill_buffer(self.blocked.slice(), 0)?;
        r.cmd.barrier(Barrier::TransferToCompute);
        let blocks = sl.blocks() as u32;
        let pipeline = if sl.exact {
            &self.exact
        } else {
            &self.lut[blocks as usize - 1]
        };
        let table = match table {
            Some(t) if !sl.exact => t.into(),
            _ => self.no_table.slice(),
        };
        let (triangles, units) = (r.inputs.triangles, r.frame.units());
        // LUT mode: one pass for every block (one look-up index serves
        // all); exact mode: one pass per 128-sample block.
        let passes = if sl.exact { blocks } else { 1 };
        for block in 0..passes {
            r.pass("occlusion", |rec, pc| {
                let mut push: LightPush = bytemuck::pod_read_unaligned(pc);
                push.soft[0] = block;
                let bindings = [
                    Binding::uniform_texel(&casters.pairs, RGBA32UI),
                    Binding::uniform_texel(triangles, RGBA32UI),
                    storage(&bins.tile_offsets),
                    Binding::uniform_texel(&bins.tile_pairs, vk::Format::R32_UINT),
                    storage(&lists.counts),
                    storage(&lists.offsets),
                    Binding::uniform_texel(&lists.list_samples, RGBA32UI),
                    storage(&self.blocked),
                    storage(counters),
                    storage(&bins.unit_offsets),
                    Binding::uniform(&self.light_samples),
                    Binding::uniform_texel(table, RGBA32UI),
                ];
                let groups = groups_2d(units.max(1));
                rec.dispatch(pipeline, &bindings, bytemuck::bytes_of(&push), groups)?;
                rec.barrier(Barrier::ComputeToCompute);
                Ok(())
            })?;
        }
        Ok(())
    }
}
