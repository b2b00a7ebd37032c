//! Soft-shadow occlusion (paper §4.2): per listed view sample and each
//! caster whose influence region covers its texel, the light samples the
//! caster hides, the AND of its four planes' bits, ORed into the sample's
//! blocked mask. The bits come from the plane look-up texture (LUT mode,
//! every 128-sample block in one pass) or from testing every light sample
//! (exact mode, one pass per block). In look-up mode (the default) the
//! table bounds each plane's bits from both sides, and the bits it leaves
//! unsure go to a list that `soft_occlusion_unsure.comp` tests exactly:
//! the masks of exact mode. Shader `soft_occlusion.comp`, compiled once per
//! mode and block count (`build.rs`). CPU twin:
//! [`crate::cpu::soft_occlusion`].

use crate::gpu::dispatch::{groups, groups_2d, storage, RGBA32UI};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::Recording;
use crate::gpu::shaders;
use crate::gpu::shared::{counter, LightPush};
use crate::gpu::soft_light::{SoftLight, SoftMode, MAX_SOFT_SAMPLES};
use crate::gpu::tile_bin::{sure_pair_chunk, SOFT_PAIR_CHUNK};
use crate::gpu::{casters::CasterPass, texel_lists::TexelListPass, tile_bin::TileBinPass};
use crate::vulkan::{
    vk, Barrier, Binding, Buffer, ComputePipeline, ComputePipelineDesc, DescriptorKind, GpuContext,
    GrowBuffer,
};
use crate::Result;

/// The soft occlusion pipelines and the masks they write.
pub struct SoftOcclusionPass {
    /// Look-up mode (exact masks), one pipeline per number of 128-sample
    /// blocks (1 to 8).
    sure: Vec<ComputePipeline>,
    /// Approximate (nearest-texel) look-up mode, per block count.
    approx: Vec<ComputePipeline>,
    exact: ComputePipeline,
    /// Exact mode with the look-up mode's work units, per block count: the
    /// fallback when the unsure list would pass the binding limit.
    exact_sure: Vec<ComputePipeline>,
    /// Look-up mode: the unsure list's exact tests.
    unsure: ComputePipeline,
    /// Look-up mode: (slot, triangle, block) and unsure bits per entry
    /// (32 B), kept across frames.
    unsure_list: GrowBuffer,
    /// The counters before the occlusion, to run it again when the unsure
    /// list overflows.
    counters_before: GrowBuffer,
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
        let make = |name: &str, spirv, chunk: (u32, u32)| {
            ctx.create_compute_pipeline(&ComputePipelineDesc {
                name,
                spirv,
                bindings: &[tb, tb, sb, tb, sb, sb, tb, sb, sb, sb, ub, tb, sb],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[chunk],
            })
        };
        Ok(SoftOcclusionPass {
            sure: [
                shaders::SOFT_OCCLUSION_SURE1,
                shaders::SOFT_OCCLUSION_SURE2,
                shaders::SOFT_OCCLUSION_SURE3,
                shaders::SOFT_OCCLUSION_SURE4,
                shaders::SOFT_OCCLUSION_SURE5,
                shaders::SOFT_OCCLUSION_SURE6,
                shaders::SOFT_OCCLUSION_SURE7,
                shaders::SOFT_OCCLUSION_SURE8,
            ]
            .iter()
            .enumerate()
            .map(|(b, spirv)| {
                let name = format!("soft_occlusion_sure{}", b + 1);
                make(&name, spirv, sure_pair_chunk(b as u32 + 1))
            })
            .collect::<Result<_>>()?,
            approx: [
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
            .map(|(b, spirv)| {
                let name = format!("soft_occlusion_approx{}", b + 1);
                make(&name, spirv, SOFT_PAIR_CHUNK)
            })
            .collect::<Result<_>>()?,
            exact: make(
                "soft_occlusion_exact",
                shaders::SOFT_OCCLUSION_EXACT,
                SOFT_PAIR_CHUNK,
            )?,
            exact_sure: (1..=8)
                .map(|b| {
                    make(
                        "soft_occlusion_exact",
                        shaders::SOFT_OCCLUSION_EXACT,
                        sure_pair_chunk(b),
                    )
                })
                .collect::<Result<_>>()?,
            unsure: ctx.create_compute_pipeline(&ComputePipelineDesc {
                name: "soft_occlusion_unsure",
                spirv: shaders::SOFT_OCCLUSION_UNSURE,
                bindings: &[tb, tb, tb, sb, ub],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[],
            })?,
            unsure_list: GrowBuffer::storage("unsure_list"),
            counters_before: GrowBuffer::storage("counters_before_occlusion"),
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
        self.counters_before.get(ctx, 4 * counter::COUNT as u64)?;
        // The unsure list: kept from earlier frames, else room for a few
        // entries per listed sample and block (it grows when a frame needs
        // more, up to one binding).
        let entries = (2 * frame.n as u64 * sl.blocks() as u64).max(1 << 16);
        let max = self.max_entries(ctx);
        if self.unsure_list.capacity() < 32 * entries.min(max) {
            self.unsure_list.get(ctx, 32 * entries.min(max))?;
        } else {
            let keep = self.unsure_list.capacity();
            self.unsure_list.get(ctx, keep)?;
        }
        Ok(())
    }

    /// The most entries the unsure list can hold (one storage binding).
    fn max_entries(&self, ctx: &GpuContext) -> u64 {
        ctx.info().limits.max_storage_buffer_range as u64 / 32
    }

    /// Records the occlusion passes (once the work units are known; `table`:
    /// the plane look-up texture in the modes that use one). Look-up mode:
    /// the pass bounds every pair's bits with the table and lists the
    /// pairs with unsure bits, whose count is read back; a list that
    /// overflowed is grown and the pass runs again (past one binding, the
    /// exact pass runs instead); then the list's exact tests.
    pub fn record(
        &mut self,
        r: &mut Recording,
        sl: &SoftLight,
        table: Option<&Buffer>,
        passes: (&TexelListPass, &CasterPass, &TileBinPass),
        counters: &GrowBuffer,
    ) -> Result<()> {
        let blocks = sl.blocks();
        match sl.mode {
            SoftMode::Exact => {
                self.occlusion(r, &self.exact, blocks as u32, None, passes, counters)
            }
            SoftMode::Approx => {
                let pipeline = &self.approx[blocks - 1];
                self.occlusion(r, pipeline, 1, table, passes, counters)
            }
            SoftMode::Lut => self.record_sure(r, sl, table, passes, counters),
        }
    }

    fn record_sure(
        &mut self,
        r: &mut Recording,
        sl: &SoftLight,
        table: Option<&Buffer>,
        passes: (&TexelListPass, &CasterPass, &TileBinPass),
        counters: &GrowBuffer,
    ) -> Result<()> {
        let blocks = sl.blocks();
        r.cmd.barrier(Barrier::ComputeToTransfer);
        r.cmd
            .copy_buffer(counters.slice(), self.counters_before.buffer(), 0)?;
        let sure = &self.sure[blocks - 1];
        self.occlusion(r, sure, 1, table, passes, counters)?;
        r.submit()?;
        let c: Vec<u32> = r
            .ctx
            .read_buffer_staged(counters.buffer(), 0, counter::COUNT)?;
        let listed = c[counter::UNSURE_PAIRS] as u64;
        if listed > self.unsure_list.len() / 32 {
            // Again, from the counters before, with a list that holds them
            // all, or exactly when one binding cannot.
            let before = self.counters_before.slice();
            r.cmd.copy_buffer(before, counters.buffer(), 0)?;
            r.cmd.barrier(Barrier::TransferToCompute);
            if listed > self.max_entries(r.ctx) {
                let exact = &self.exact_sure[blocks - 1];
                return self.occlusion(r, exact, blocks as u32, None, passes, counters);
            }
            self.unsure_list.get(
                r.ctx,
                32 * (listed + listed / 4).min(self.max_entries(r.ctx)),
            )?;
            self.occlusion(r, sure, 1, table, passes, counters)?;
        }
        let (list, triangles) = (&self.unsure_list, r.inputs.triangles);
        let samples = &passes.0.list_samples;
        let mut push = r.frame.push;
        push.more[3] = listed as u32;
        r.pass("occlusion_unsure", |rec, _| {
            let bindings = [
                Binding::uniform_texel(list, RGBA32UI),
                Binding::uniform_texel(triangles, RGBA32UI),
                Binding::uniform_texel(samples, RGBA32UI),
                storage(&self.blocked),
                Binding::uniform(&self.light_samples),
            ];
            let groups = groups(listed as u32);
            rec.dispatch(&self.unsure, &bindings, bytemuck::bytes_of(&push), groups)?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })
    }

    /// Clears the masks and records `pipeline` in `passes` passes (one per
    /// block in exact mode), with `table` (or none).
    fn occlusion(
        &self,
        r: &mut Recording,
        pipeline: &ComputePipeline,
        passes: u32,
        table: Option<&Buffer>,
        (lists, casters, bins): (&TexelListPass, &CasterPass, &TileBinPass),
        counters: &GrowBuffer,
    ) -> Result<()> {
        r.cmd.fill_buffer(self.blocked.slice(), 0)?;
        r.cmd.barrier(Barrier::TransferToCompute);
        let table = table.map_or(self.no_table.slice(), |t| t.into());
        let (triangles, units) = (r.inputs.triangles, r.frame.units());
        let capacity = (self.unsure_list.len() / 32) as u32;
        for block in 0..passes {
            r.pass("occlusion", |rec, pc| {
                let mut push: LightPush = bytemuck::pod_read_unaligned(pc);
                push.soft[0] = block;
                push.dir_right[3] = f32::from_bits(capacity);
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
                    storage(&self.unsure_list),
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
