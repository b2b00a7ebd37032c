//! Per-light-texel lists of view samples (paper §3.1): every view sample
//! that faces the light is projected to a light texel, an atomic counter
//! per texel counts them and hands each its slot in the texel's list
//! (`texel_lists_count.comp`, which also keeps each tile's longest list), an
//! exclusive scan of the counts gives each list's offset, and
//! `texel_lists_scatter.comp` writes every sample into one compact array.
//! CPU twin: [`crate::cpu::texel_lists`].

use crate::gpu::dispatch::{groups, storage};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::Recording;
use crate::gpu::scan::ScanPass;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::vulkan::{
    Barrier, Binding, CommandRecorder, ComputePipeline, ComputePipelineDesc, DescriptorKind,
    GpuContext, GrowBuffer,
};
use crate::{Error, Result};

/// The list passes' pipelines and the lists they build.
pub struct TexelListPass {
    count: ComputePipeline,
    scatter: ComputePipeline,
    scan: ScanPass,
    /// Per light texel (tile-major): list length.
    pub counts: GrowBuffer,
    /// Per light texel: list offset; `offsets[texels]` = listed samples.
    pub offsets: GrowBuffer,
    /// Per view sample: its texel, or `NOT_LISTED`.
    pub sample_texel: GrowBuffer,
    /// Per view sample: its slot in its texel's list.
    pub sample_slot: GrowBuffer,
    /// Per list slot: the sample's position (xyz float bits) and triangle id.
    pub list_samples: GrowBuffer,
    /// Per list slot: the sample's index among the view samples (its
    /// pixel: the per-pixel rotation's angle).
    pub list_sample_index: GrowBuffer,
    /// Per tile: its longest list (occlusion work units); then which tiles
    /// hold view samples, one bit each (binning visits only those).
    pub tile_max_len: GrowBuffer,
}

impl TexelListPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let sb = DescriptorKind::StorageBuffer;
        let ub = DescriptorKind::UniformBuffer;
        let make = |name, spirv, bindings: &[DescriptorKind]| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name,
                spirv,
                bindings,
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[],
            })
        };
        Ok(TexelListPass {
            count: make(
                "texel_lists_count",
                shaders::TEXEL_LISTS_COUNT,
                &[sb, ub, sb, sb, sb, sb],
            )?,
            scatter: make(
                "texel_lists_scatter",
                shaders::TEXEL_LISTS_SCATTER,
                &[sb; 6],
            )?,
            scan: ScanPass::new(ctx)?,
            counts: GrowBuffer::storage("texel_counts"),
            offsets: GrowBuffer::storage("texel_offsets"),
            sample_texel: GrowBuffer::storage("sample_texel"),
            sample_slot: GrowBuffer::storage("sample_slot"),
            list_samples: GrowBuffer::storage("light_texel_lists"),
            list_sample_index: GrowBuffer::storage("list_sample_index"),
            tile_max_len: GrowBuffer::storage("tile_max_len"),
        })
    }

    /// The most light texels one run can list (the scan's limit).
    fn max_texels(&self) -> u64 {
        self.scan.max_len() as u64 - 1
    }

    /// Makes the scan's scratch buffers for `frame` now (a caller's
    /// recording allocates nothing).
    pub fn reserve_scan(&mut self, frame: &LightFrame) -> Result<()> {
        self.scan.reserve(frame.texels.min(u32::MAX as u64) as u32)
    }

    /// Checks the frame's texels against the scan's limit.
    pub fn check(&self, frame: &LightFrame) -> Result<()> {
        if frame.texels > self.max_texels() {
            return Err(Error::InvalidInput(format!(
                "{} light face(s) of {}² texels need {} list counters; this device scans at most {} (lower light_texels)",
                frame.faces,
                frame.resolution,
                frame.texels,
                self.scan.max_len()
            )));
        }
        Ok(())
    }

    /// Checks the frame and sizes the buffers.
    pub fn prepare(&mut self, ctx: &GpuContext, frame: &LightFrame) -> Result<()> {
        self.check(frame)?;
        let n = frame.n as u64;
        self.counts.get(ctx, 4 * frame.texels)?;
        self.offsets.get(ctx, 4 * (frame.texels + 1))?;
        self.sample_texel.get(ctx, 4 * n)?;
        self.sample_slot.get(ctx, 4 * n)?;
        self.list_samples.get(ctx, 16 * n)?;
        self.list_sample_index.get(ctx, 4 * n)?;
        self.tile_max_len.get(ctx, 4 * frame.tile_words())?;
        Ok(())
    }

    /// Records the clears this pass needs before the run's first pass.
    pub fn record_clears(&self, rec: &mut CommandRecorder) -> Result<()> {
        rec.fill_buffer(self.counts.slice(), 0)?;
        rec.fill_buffer(self.tile_max_len.slice(), 0)
    }

    /// Records count, scan and scatter (after the light fit wrote `faces`).
    pub fn record(&mut self, r: &mut Recording, faces: &GrowBuffer) -> Result<()> {
        let (samples, n, texels) = (r.inputs.samples, r.frame.n, r.frame.texels as u32);
        r.pass("texel_count", |rec, pc| {
            let bindings = [
                storage(samples),
                Binding::uniform(faces),
                storage(&self.counts),
                storage(&self.sample_texel),
                storage(&self.sample_slot),
                storage(&self.tile_max_len),
            ];
            rec.dispatch(&self.count, &bindings, pc, groups(n))
        })?;
        let scan = &mut self.scan;
        let (counts, offsets) = (&self.counts, &self.offsets);
        r.pass("texel_scan", |rec, _| {
            scan.record(rec, counts.slice(), offsets.slice(), texels)?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })?;
        r.pass("texel_scatter", |rec, pc| {
            let bindings = [
                storage(samples),
                storage(&self.offsets),
                storage(&self.sample_texel),
                storage(&self.sample_slot),
                storage(&self.list_samples),
                storage(&self.list_sample_index),
            ];
            rec.dispatch(&self.scatter, &bindings, pc, groups(n))
        })
    }

    /// Bytes this run binds.
    pub fn bytes(&self) -> u64 {
        [
            &self.counts,
            &self.offsets,
            &self.sample_texel,
            &self.sample_slot,
            &self.list_samples,
            &self.list_sample_index,
            &self.tile_max_len,
        ]
        .iter()
        .map(|b| b.len())
        .sum()
    }
}
