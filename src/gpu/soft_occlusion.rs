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

use crate::gpu::clusters::ClusterPass;
use crate::gpu::dispatch::{groups, groups_2d, storage, RGBA32UI};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::{CasterRound, Recording, UNITS_INDIRECT};
use crate::gpu::shaders;
use crate::gpu::shared::{counter, LightPush};
use crate::gpu::soft_light::{SoftLight, SoftMode, MAX_SOFT_SAMPLES};
use crate::gpu::tile_bin::{LOOKUP_PAIR_CHUNK, SOFT_PAIR_CHUNK};
use crate::gpu::{casters::CasterPass, texel_lists::TexelListPass, tile_bin::TileBinPass};
use crate::vulkan::{
    vk, Barrier, Binding, Buffer, CommandRecorder, ComputePipeline, ComputePipelineDesc,
    DescriptorKind, GpuContext, GrowBuffer,
};
use crate::Result;
use std::collections::HashMap;

/// What soft occlusion reads of the passes before it: the texel lists, the
/// casters, the tile bins and the view-sample clusters' tile boxes (a
/// chunk of a tile's samples drops the pairs its own box rules out).
pub type SoftInputs<'a> = (
    &'a TexelListPass,
    &'a CasterPass,
    &'a TileBinPass,
    &'a ClusterPass,
);

/// The most entries of the unsure list (32 B each, one storage binding):
/// look-up mode runs the work units in ranges whose entries fit it.
fn unsure_list_entries(ctx: &GpuContext) -> u64 {
    (ctx.info().limits.max_storage_buffer_range as u64 / 32).min(1 << 22)
}

/// The most unsure-list entries one work unit lists: one per lane, pair
/// and block (64 · `LOOKUP_PAIR_CHUNK` · `blocks`).
fn unit_entries(blocks: usize) -> u64 {
    64 * LOOKUP_PAIR_CHUNK.1 as u64 * blocks as u64
}

/// The soft occlusion pipelines and the masks they write.
pub struct SoftOcclusionPass {
    /// Every kernel by (kernel, alpha round, per-pixel rotation)
    /// (specialization constants `ALPHA` and `ROTATION`): the plain ones
    /// made up front, the others when a light first needs them.
    pipelines: HashMap<(Kernel, bool, bool), ComputePipeline>,
    /// Look-up mode: (slot, triangle, block) and unsure bits per entry
    /// (32 B), kept across frames.
    unsure_list: GrowBuffer,
    /// The counters before the occlusion, to run it again when the unsure
    /// list overflows.
    counters_before: GrowBuffer,
    /// The last look-up run's work units and its ranges' (start, length,
    /// entries): the next run with as many units plans its ranges by them.
    last_ranges: (u32, Vec<(u32, u32, u64)>),
    /// At most this many unsure-list entries per range (tests: forces
    /// many ranges and the runs again of ranges that overflow).
    pub list_limit: Option<u64>,
    /// Per list slot: blocked light samples, `mask_words` words.
    pub blocked: GrowBuffer,
    /// The camera-relative light samples (uniform buffer).
    pub light_samples: GrowBuffer,
    /// Bound in place of the table in exact mode (a view may not be empty).
    no_table: GrowBuffer,
    /// The light's per-pixel rotation (`pixel_rotation.glsl`; zeros
    /// without one), uniform buffer.
    pub pixel_rotation: GrowBuffer,
    /// Look-up mode, since [`SoftOcclusionPass::prepare`]: unsure-list
    /// entries tested and ranges of work units run (without the runs
    /// again of ranges that overflowed).
    pub unsure_listed: (u64, u32),
}

/// One of the occlusion shaders: look-up mode's (exact masks) or the
/// approximate look-up's per block count, exact mode's, and the unsure
/// tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Kernel {
    Sure(usize),
    Approx(usize),
    Exact,
    Unsure,
}

impl Kernel {
    /// The kernel of `sl`'s mode (the occlusion, not the unsure tests).
    fn of(sl: &SoftLight) -> Kernel {
        match sl.mode {
            SoftMode::Lut => Kernel::Sure(sl.blocks()),
            SoftMode::Approx => Kernel::Approx(sl.blocks()),
            SoftMode::Exact => Kernel::Exact,
        }
    }

    /// Its pipeline, `alpha` the alpha-tested casters' round, `rotated`
    /// with the per-pixel rotation.
    fn make(self, ctx: &GpuContext, alpha: bool, rotated: bool) -> Result<ComputePipeline> {
        let suffix = match (alpha, rotated) {
            (false, false) => "",
            (true, false) => "_alpha",
            (false, true) => "_rotated",
            (true, true) => "_alpha_rotated",
        };
        let flags = (alpha, rotated);
        match self {
            Kernel::Sure(b) => {
                let name = format!("soft_occlusion_sure{b}{suffix}");
                occlusion_pipeline(ctx, &name, SURE_SPIRV[b - 1], LOOKUP_PAIR_CHUNK, flags)
            }
            Kernel::Approx(b) => {
                let name = format!("soft_occlusion_approx{b}{suffix}");
                occlusion_pipeline(ctx, &name, APPROX_SPIRV[b - 1], LOOKUP_PAIR_CHUNK, flags)
            }
            Kernel::Exact => {
                let name = format!("soft_occlusion_exact{suffix}");
                let spirv = shaders::SOFT_OCCLUSION_EXACT;
                occlusion_pipeline(ctx, &name, spirv, SOFT_PAIR_CHUNK, flags)
            }
            Kernel::Unsure => {
                unsure_pipeline(ctx, &format!("soft_occlusion_unsure{suffix}"), flags)
            }
        }
    }
}

impl SoftOcclusionPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let plain = (1..=8)
            .flat_map(|b| [Kernel::Sure(b), Kernel::Approx(b)])
            .chain([Kernel::Exact, Kernel::Unsure]);
        let pipelines = plain
            .map(|k| Ok(((k, false, false), k.make(ctx, false, false)?)))
            .collect::<Result<_>>()?;
        Ok(SoftOcclusionPass {
            pipelines,
            unsure_list: GrowBuffer::storage("unsure_list"),
            counters_before: GrowBuffer::storage("counters_before_occlusion"),
            last_ranges: (0, Vec::new()),
            list_limit: None,
            blocked: GrowBuffer::storage("blocked_masks"),
            light_samples: GrowBuffer::storage_uniform("light_samples"),
            no_table: GrowBuffer::storage("plane_lut_unused"),
            pixel_rotation: GrowBuffer::storage_uniform("pixel_rotation"),
            unsure_listed: (0, 0),
        })
    }

    /// Makes the kernels that `sl` needs in the rounds that run (the
    /// alpha round's with `alpha_casters`), with its rotation or without.
    fn make_pipelines(
        &mut self,
        ctx: &GpuContext,
        sl: &SoftLight,
        alpha_casters: bool,
    ) -> Result<()> {
        let rotated = sl.rotation.is_some();
        let mut want = vec![(Kernel::of(sl), false)];
        if alpha_casters {
            want.push((Kernel::of(&sl.for_round(CasterRound::Alpha)), true));
        }
        if sl.mode == SoftMode::Lut {
            want.push((Kernel::Unsure, false));
            want.extend(alpha_casters.then_some((Kernel::Unsure, true)));
        }
        for (kernel, alpha) in want {
            if let std::collections::hash_map::Entry::Vacant(e) =
                self.pipelines.entry((kernel, alpha, rotated))
            {
                e.insert(kernel.make(ctx, alpha, rotated)?);
            }
        }
        Ok(())
    }

    /// The pipeline of `kernel` in the alpha round or not, with the
    /// per-pixel rotation or not.
    fn pipeline(&self, kernel: Kernel, alpha: bool, rotated: bool) -> Result<&ComputePipeline> {
        self.pipelines
            .get(&(kernel, alpha, rotated))
            .ok_or_else(not_made)
    }

    /// Sizes the buffers and uploads the light samples (before the run's
    /// first recording).
    /// Makes the kernels `sl` needs (the alpha round's with `alpha_casters`).
    pub fn prepare(
        &mut self,
        ctx: &GpuContext,
        frame: &LightFrame,
        sl: &SoftLight,
        alpha_casters: bool,
    ) -> Result<()> {
        self.make_pipelines(ctx, sl, alpha_casters)?;
        self.unsure_listed = (0, 0);
        self.blocked
            .get(ctx, 4 * frame.mask_words * frame.n as u64)?;
        self.light_samples.get(ctx, 16 * MAX_SOFT_SAMPLES as u64)?;
        self.pixel_rotation.get(ctx, 16 * (3 + 128))?;
        self.no_table.get(ctx, 16)?;
        self.counters_before.get(ctx, 4 * counter::COUNT as u64)?;
        // The unsure list (the units run in ranges whose entries fit it).
        if sl.mode == SoftMode::Lut {
            self.unsure_list.get(ctx, 32 * unsure_list_entries(ctx))?;
        } else {
            self.unsure_list.get(ctx, 16)?;
        }
        Ok(())
    }

    /// Uploads the light samples and the per-pixel rotation of `sl` (after
    /// [`SoftOcclusionPass::prepare`]), waiting until done.
    pub fn upload(&self, ctx: &GpuContext, sl: &SoftLight) -> Result<()> {
        let (samples, rotation) = light_words(sl);
        ctx.upload_staged(self.light_samples.buffer(), 0, &samples)?;
        ctx.upload_staged(self.pixel_rotation.buffer(), 0, &rotation)
    }

    /// The same uploads recorded into `rec` (a caller's recording, where
    /// several lights share one submission), before the passes that read
    /// them.
    pub fn record_upload(&self, rec: &mut CommandRecorder, sl: &SoftLight) -> Result<()> {
        let (samples, rotation) = light_words(sl);
        rec.update_buffer(
            self.light_samples.buffer(),
            0,
            bytemuck::cast_slice(&samples),
        )?;
        rec.update_buffer(
            self.pixel_rotation.buffer(),
            0,
            bytemuck::cast_slice(&rotation),
        )?;
        rec.barrier(Barrier::TransferToCompute);
        Ok(())
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
        passes: SoftInputs,
        counters: &GrowBuffer,
        first: bool,
    ) -> Result<()> {
        let blocks = sl.blocks();
        if first {
            r.cmd.fill_buffer(self.blocked.slice(), 0)?;
        }
        let alpha = r.round == CasterRound::Alpha;
        let rotated = sl.rotation.is_some();
        match sl.mode {
            SoftMode::Exact => {
                let exact = self.pipeline(Kernel::Exact, alpha, rotated)?;
                for block in 0..blocks as u32 {
                    self.occlusion_block(r, exact, block, None, passes, counters)?;
                }
                Ok(())
            }
            SoftMode::Approx => {
                let pipeline = self.pipeline(Kernel::Approx(blocks), alpha, rotated)?;
                let all = (0, r.frame.units());
                self.occlusion(r, pipeline, all, table, passes, counters)
            }
            SoftMode::Lut => self.record_sure(r, sl, table, passes, counters),
        }
    }

    fn record_sure(
        &mut self,
        r: &mut Recording,
        sl: &SoftLight,
        table: Option<&Buffer>,
        passes: SoftInputs,
        counters: &GrowBuffer,
    ) -> Result<()> {
        let blocks = sl.blocks();
        let (alpha, rotated) = (r.round == CasterRound::Alpha, sl.rotation.is_some());
        let plan = std::mem::take(&mut self.last_ranges);
        let sure = self.pipeline(Kernel::Sure(blocks), alpha, rotated)?;
        let units = r.frame.units();
        let listed_at = 4 * counter::UNSURE_PAIRS as u64;
        // The units in ranges, each followed by the exact tests of its
        // unsure list. A unit lists at most one entry per lane, pair and
        // block, so the first range is as long as that bound allows; later
        // ones follow the entries per unit seen, or the last run's ranges
        // when it had as many units (a frame like the last: no range runs
        // twice). A range whose list overflowed runs again, shorter, from
        // the counters before it: its sure bits ORed twice are the same.
        let per_unit = unit_entries(blocks);
        let capacity = self.capacity(blocks);
        debug_assert!(capacity >= per_unit);
        let safe = (capacity / per_unit).max(1) as u32;
        let plan = if plan.0 == units { plan.1 } else { Vec::new() };
        let mut done = Vec::new();
        let mut len = safe;
        let mut start = 0u32;
        let mut retry = false;
        let mut listed_here = 0u64;
        while start < units {
            if !retry {
                if let Some(l) = planned_len(&plan, start, capacity) {
                    len = len.max(l);
                }
            }
            len = len.min(units - start);
            // The passes before wrote the counters; the copy reads the
            // fill's word too.
            r.cmd.barrier(Barrier::ComputeToTransfer);
            r.cmd
                .fill_buffer(counters.buffer().slice(listed_at, 4)?, 0)?;
            r.cmd.barrier(Barrier::TransferToTransfer);
            r.cmd
                .copy_buffer(counters.slice(), self.counters_before.buffer(), 0)?;
            r.cmd.barrier(Barrier::TransferToCompute);
            self.occlusion(r, sure, (start, len), table, passes, counters)?;
            r.submit()?;
            let c: Vec<u32> = r
                .ctx
                .read_buffer_staged(counters.buffer(), 0, counter::COUNT)?;
            let listed = c[counter::UNSURE_PAIRS] as u64;
            if listed > capacity {
                r.cmd
                    .copy_buffer(self.counters_before.slice(), counters.buffer(), 0)?;
                r.cmd.barrier(Barrier::TransferToCompute);
                len = ((len as u64 * capacity / listed) * 7 / 10)
                    .clamp(1, (len as u64).saturating_sub(1).max(1)) as u32;
                retry = true;
                continue;
            }
            retry = false;
            self.test_unsure(r, listed, passes.0, rotated)?;
            listed_here += listed;
            done.push((start, len, listed));
            start += len;
            // The next range: as many units as this one's density fits
            // with room to spare, at most four times as many.
            let fit = capacity as f64 * len as f64 / (1.5 * listed as f64).max(1.0);
            len = fit.clamp(safe as f64, (4.0 * len as f64).max(safe as f64)) as u32;
        }
        self.unsure_listed.0 += listed_here;
        self.unsure_listed.1 += done.len() as u32;
        self.last_ranges = (units, done);
        Ok(())
    }

    /// Entries the unsure list holds per range for a light of `blocks`
    /// blocks: its size, or the limit, but never below one unit's bound
    /// ([`unit_entries`]), so that a range of one unit always fits.
    fn capacity(&self, blocks: usize) -> u64 {
        let limit = self
            .list_limit
            .unwrap_or(u64::MAX)
            .max(unit_entries(blocks));
        (self.unsure_list.len() / 32).min(limit)
    }

    /// Records the exact tests of the first `listed` entries of the unsure list.
    fn test_unsure(
        &self,
        r: &mut Recording,
        listed: u64,
        lists: &TexelListPass,
        rotated: bool,
    ) -> Result<()> {
        let (list, triangles) = (&self.unsure_list, r.inputs.triangles);
        let samples = &lists.list_samples;
        let mut push = r.frame.push;
        push.more[3] = listed as u32;
        let unsure = self.pipeline(Kernel::Unsure, r.round == CasterRound::Alpha, rotated)?;
        let [records, textures, alphas] = r.inputs.alpha.bindings();
        r.pass("occlusion_unsure", |rec, _| {
            let bindings = [
                Binding::uniform_texel(list, RGBA32UI),
                Binding::uniform_texel(triangles, RGBA32UI),
                Binding::uniform_texel(samples, RGBA32UI),
                storage(&self.blocked),
                Binding::uniform(&self.light_samples),
                records,
                textures,
                alphas,
                Binding::uniform_texel(&lists.list_sample_index, vk::Format::R32_UINT),
                Binding::uniform(&self.pixel_rotation),
            ];
            let groups = groups(listed as u32);
            rec.dispatch(unsure, &bindings, bytemuck::bytes_of(&push), groups)?;
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })
    }

    /// Records `pipeline` over the work units `start..start + len` (all
    /// blocks: the look-up modes), with `table` (or none).
    fn occlusion(
        &self,
        r: &mut Recording,
        pipeline: &ComputePipeline,
        (start, len): (u32, u32),
        table: Option<&Buffer>,
        passes: SoftInputs,
        counters: &GrowBuffer,
    ) -> Result<()> {
        // soft.x: exact mode's block; the look-up modes': the list's capacity
        // (an integer field: as float bits it would be a denormal, which a
        // driver may flush to zero).
        let capacity = self.capacity((r.frame.mask_words / 4).max(1) as usize) as u32;
        self.occlusion_pass(r, pipeline, (capacity, start, len), table, passes, counters)
    }

    /// Records exact mode's pass of 128-sample block `block` over every unit.
    fn occlusion_block(
        &self,
        r: &mut Recording,
        pipeline: &ComputePipeline,
        block: u32,
        table: Option<&Buffer>,
        passes: SoftInputs,
        counters: &GrowBuffer,
    ) -> Result<()> {
        let units = r.frame.units();
        self.occlusion_pass(r, pipeline, (block, 0, units), table, passes, counters)
    }

    /// One occlusion dispatch: block `block` (exact mode), units
    /// `start..start + len`.
    fn occlusion_pass(
        &self,
        r: &mut Recording,
        pipeline: &ComputePipeline,
        (block, start, len): (u32, u32, u32),
        table: Option<&Buffer>,
        (lists, casters, bins, clusters): SoftInputs,
        counters: &GrowBuffer,
    ) -> Result<()> {
        r.cmd.barrier(Barrier::TransferToCompute);
        let table = table.map_or(self.no_table.slice(), |t| t.into());
        let triangles = r.inputs.triangles;
        let [records, textures, alphas] = r.inputs.alpha.bindings();
        r.pass("occlusion", |rec, pc| {
            let mut push: LightPush = bytemuck::pod_read_unaligned(pc);
            push.soft[0] = block;
            push.soft[3] = start;
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
                Binding::uniform_texel(&clusters.boxes, RGBA32UI),
                records,
                textures,
                alphas,
                Binding::uniform_texel(&lists.list_sample_index, vk::Format::R32_UINT),
                Binding::uniform(&self.pixel_rotation),
            ];
            let push = bytemuck::bytes_of(&push);
            if len == UNITS_INDIRECT {
                rec.dispatch_indirect(pipeline, &bindings, push, bins.dispatch_args.buffer())?;
            } else {
                rec.dispatch(pipeline, &bindings, push, groups_2d(len.max(1)))?;
            }
            rec.barrier(Barrier::ComputeToCompute);
            Ok(())
        })
    }
}

/// Look-up mode's occlusion shaders, per block count.
const SURE_SPIRV: [&[u32]; 8] = [
    shaders::SOFT_OCCLUSION_SURE1,
    shaders::SOFT_OCCLUSION_SURE2,
    shaders::SOFT_OCCLUSION_SURE3,
    shaders::SOFT_OCCLUSION_SURE4,
    shaders::SOFT_OCCLUSION_SURE5,
    shaders::SOFT_OCCLUSION_SURE6,
    shaders::SOFT_OCCLUSION_SURE7,
    shaders::SOFT_OCCLUSION_SURE8,
];

/// The approximate look-up's occlusion shaders, per block count.
const APPROX_SPIRV: [&[u32]; 8] = [
    shaders::SOFT_OCCLUSION_LUT1,
    shaders::SOFT_OCCLUSION_LUT2,
    shaders::SOFT_OCCLUSION_LUT3,
    shaders::SOFT_OCCLUSION_LUT4,
    shaders::SOFT_OCCLUSION_LUT5,
    shaders::SOFT_OCCLUSION_LUT6,
    shaders::SOFT_OCCLUSION_LUT7,
    shaders::SOFT_OCCLUSION_LUT8,
];

/// The `PixelRotation` uniform block of `pixel_rotation.glsl` for `sl`:
/// centre, axis, hashed seed and first pixel, then the angle table two per row (zeros
/// without a rotation: the unrotated kernels do not read it).
fn pixel_rotation_block(sl: &SoftLight) -> Vec<[u32; 4]> {
    let f = |v: [f32; 4]| v.map(f32::to_bits);
    let mut rows = vec![[0u32; 4]; 3 + 128];
    if let Some(rot) = &sl.rotation {
        rows[0] = f(rot.centre.extend(0.0).to_array());
        rows[1] = f(rot.axis.extend(0.0).to_array());
        rows[2] = [crate::light::hash32(rot.seed), rot.first_pixel, 0, 0];
        for (k, pair) in crate::light::pixel_rotation_table().chunks(2).enumerate() {
            rows[3 + k] = f([pair[0][0], pair[0][1], pair[1][0], pair[1][1]]);
        }
    }
    rows
}

/// A soft occlusion pipeline: `chunk` pairs per work unit (specialization
/// constant 2); `alpha`: the alpha-tested casters' round (constant 5);
/// `rotated`: the per-pixel rotation (constant 6).
fn occlusion_pipeline(
    ctx: &GpuContext,
    name: &str,
    spirv: &[u32],
    chunk: (u32, u32),
    (alpha, rotated): (bool, bool),
) -> Result<ComputePipeline> {
    let sb = DescriptorKind::StorageBuffer;
    let tb = DescriptorKind::UniformTexelBuffer;
    let ub = DescriptorKind::UniformBuffer;
    ctx.create_compute_pipeline(&ComputePipelineDesc {
        name,
        spirv,
        bindings: &[
            tb, tb, sb, tb, sb, sb, tb, sb, sb, sb, ub, tb, sb, tb, tb, tb, tb, tb, ub,
        ],
        push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
        specialization: &[chunk, (5, alpha as u32), (6, rotated as u32)],
    })
}

/// The unsure tests' pipeline (`alpha`: the alpha-tested casters' round;
/// `rotated`: the per-pixel rotation).
fn unsure_pipeline(
    ctx: &GpuContext,
    name: &str,
    (alpha, rotated): (bool, bool),
) -> Result<ComputePipeline> {
    let sb = DescriptorKind::StorageBuffer;
    let tb = DescriptorKind::UniformTexelBuffer;
    let ub = DescriptorKind::UniformBuffer;
    ctx.create_compute_pipeline(&ComputePipelineDesc {
        name,
        spirv: shaders::SOFT_OCCLUSION_UNSURE,
        bindings: &[tb, tb, tb, sb, ub, tb, tb, tb, tb, ub],
        push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
        specialization: &[(5, alpha as u32), (6, rotated as u32)],
    })
}

/// The units from `start` whose entries, by the last run's ranges `plan`
/// (spread evenly over each range), fill three quarters of `capacity`;
/// `None` without a plan.
fn planned_len(plan: &[(u32, u32, u64)], start: u32, capacity: u64) -> Option<u32> {
    let budget = 0.75 * capacity as f64;
    let (mut used, mut end) = (0.0f64, start);
    for &(s, l, entries) in plan.iter().filter(|r| r.0 + r.1 > start) {
        let from = s.max(start);
        let density = entries as f64 / l.max(1) as f64;
        let room = ((budget - used) / density.max(1e-12)).floor();
        let take = (s + l - from) as f64;
        if room < take {
            end = from + room as u32;
            return Some((end - start).max(1));
        }
        used += take * density;
        end = s + l;
    }
    (!plan.is_empty()).then_some((end - start).max(1))
}

/// A pipeline that `prepare` did not make.
fn not_made() -> crate::Error {
    crate::Error::InvalidInput("an occlusion pipeline was not prepared".into())
}

/// The light samples (`vec4` each) and the per-pixel rotation block of `sl`,
/// as the occlusion passes' uniform buffers hold them.
fn light_words(sl: &SoftLight) -> (Vec<[f32; 4]>, Vec<[u32; 4]>) {
    let samples = sl.samples.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect();
    (samples, pixel_rotation_block(sl))
}
