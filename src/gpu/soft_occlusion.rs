//! Soft-shadow occlusion (paper §4.2): per listed view sample and each
//! caster whose influence region covers its texel, the light samples the
//! caster hides, the AND of its four planes' bits, ORed into the sample's
//! blocked mask. The bits come from the plane look-up texture (LUT mode,
//! every 128-sample block in one pass) or from testing every light sample
//! (exact mode, one pass per block). In look-up mode (the default) the
//! table bounds each plane's bits from both sides, and the bits it leaves
//! unsure are tested exactly: the masks of exact mode. The opaque round
//! tests them in its own loops (one per block, within a budget of loop
//! iterations per subgroup that keeps lavapipe's loop bound); the alpha
//! round, and the
//! pairs past the budget, send them to a list that
//! `soft_occlusion_unsure.comp` tests. Shader `soft_occlusion.comp`,
//! compiled once per mode and block count (`build.rs`). CPU twin:
//! [`crate::cpu::soft_occlusion`].

use crate::gpu::clusters::ClusterPass;
use crate::gpu::dispatch::{groups, groups_2d, require_occlusion_subgroup_ops, storage, RGBA32UI};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::{CasterRound, Recording, UNITS_INDIRECT};
use crate::gpu::pair_groups::PairGroupPass;
use crate::gpu::shaders;
use crate::gpu::shared::{counter, LightPush};
use crate::gpu::soft_light::{
    light_groups, SoftLight, SoftMode, LIGHT_GROUP_SIZE, MAX_SOFT_SAMPLES,
};
use crate::gpu::tile_bin::{LOOKUP_PAIR_CHUNK, SOFT_PAIR_CHUNK};
use crate::gpu::{casters::CasterPass, texel_lists::TexelListPass, tile_bin::TileBinPass};
use crate::vulkan::{
    vk, Barrier, Binding, Buffer, CommandRecorder, ComputePipeline, ComputePipelineDesc,
    DescriptorKind, GpuContext, GrowBuffer,
};
use crate::{Error, Result};
use std::collections::HashMap;

/// What soft occlusion reads of the passes before it: the texel lists, the
/// casters, the tile bins, the view-sample clusters' tile boxes (a chunk
/// of a tile's samples drops the pairs its own box rules out) and the
/// binned pairs' group bits (and first those its groups' boxes rule out).
pub type SoftInputs<'a> = (
    &'a TexelListPass,
    &'a CasterPass,
    &'a TileBinPass,
    &'a ClusterPass,
    &'a PairGroupPass,
);

/// The most entries of the unsure list (32 B each, one storage binding):
/// look-up mode runs the work units in ranges whose entries fit it.
fn unsure_list_entries(ctx: &GpuContext) -> u64 {
    (ctx.info().limits.max_storage_buffer_range as u64 / 32).min(1 << 22)
}

/// The unsure list's segments (`UNSURE_SEGMENTS`, `soft_common.glsl`):
/// work unit `u` of a dispatch lists into segment `u % UNSURE_SEGMENTS`,
/// which has a count of its own. With one count for the whole list, its
/// atomics (one per subgroup and pair with unsure bits) cost 0.36 of 1.3 s
/// of occlusion on two lavapipe threads (`torus_knot:20000`, 128 samples).
pub const UNSURE_SEGMENTS: u64 = 4;

/// The entries per segment that look-up mode plans a range of work units
/// to list (at most 0.9 of a segment): ranges whose lists stay small run
/// faster. Measured on lavapipe, 512², 128 samples, occlusion of a warm
/// frame: `builtin:demo` 530 ms with one range planned to 0.9 of the list,
/// 400–410 ms with ranges of 2^15 to 2^17 entries per segment, 460 ms at
/// 2^18; `torus_knot:20000` 1410 ms (two ranges) against 940–1090 ms.
const RANGE_TARGET: u64 = 1 << 17;

/// The entries per segment a range is planned to list: on a CPU device
/// [`RANGE_TARGET`] (small lists stay in its caches); on a GPU 0.9 of a
/// segment, since there each range costs two host round trips (its
/// submission and its counts' read-back) and caches are not what limits
/// it: on an H200, 6 to 69 ranges per frame came with 10–100 ms of host
/// time that exact mode does not have (f8858d6; these bigger ranges were
/// not measured there).
fn range_target(cpu: bool, whole_segment: u64) -> u64 {
    let most = whole_segment * 9 / 10;
    if cpu {
        RANGE_TARGET.min(most)
    } else {
        most
    }
}

/// Words from one segment's count to the next (`UNSURE_COUNT_STRIDE`): a
/// cache line apart.
const UNSURE_COUNT_STRIDE: usize = 16;

/// The most unsure-list entries one work unit lists: one per lane, pair
/// and block (64 · `LOOKUP_PAIR_CHUNK` · `blocks`).
fn unit_entries(blocks: usize) -> u64 {
    64 * LOOKUP_PAIR_CHUNK.1 as u64 * blocks as u64
}

/// Shared memory of the soft occlusion kernels (soft_occlusion.comp):
/// `keep_pairs`' two arrays of `MAX_KEPT` (= `LOOKUP_PAIR_CHUNK`) pair
/// indices and their two counts, and 64 subgroup boxes of two `vec4`s.
/// 18,440 bytes, past Vulkan's least `maxComputeSharedMemorySize` (16 KiB;
/// lavapipe has 32, desktop GPUs 32 to 64): one array compacted in place
/// instead took a barrier per 64 pairs and made ToyCar's occlusion 5%
/// slower on lavapipe.
pub const SHARED_BYTES: u32 = 2 * 4 * LOOKUP_PAIR_CHUNK.1 + 2 * 4 + 2 * 64 * 16;

/// A range of one unit of eight blocks fits in every segment of the
/// smallest list a device allows (Vulkan's least `maxStorageBufferRange`,
/// 2^27 bytes, of 32-byte entries).
const _: () = assert!(64 * LOOKUP_PAIR_CHUNK.1 as u64 * 8 * UNSURE_SEGMENTS <= (1 << 27) / 32);

/// The soft occlusion pipelines and the masks they write.
pub struct SoftOcclusionPass {
    /// Every kernel by (kernel, alpha round, per-pixel rotation, wedge
    /// rule) (specialization constants `ALPHA`, `ROTATION` and
    /// `WEDGE_RULE`; the wedge rule keys only the exact kernel, the others
    /// compile it out), each made when a light first needs it
    /// ([`SoftOcclusionPass::prepare`]): the 18 plain kernels made up
    /// front cost every engine's start 0.5 s on lavapipe, most of them
    /// never used (a hard-shadow run uses none). Kept for the pass's life,
    /// so that a command buffer recorded before the wedge rule was turned
    /// off or on still holds live pipelines.
    pipelines: HashMap<(Kernel, bool, bool, bool), ComputePipeline>,
    /// Look-up mode: (slot, triangle, block) and unsure bits per entry
    /// (32 B), in [`UNSURE_SEGMENTS`] segments, kept across frames.
    unsure_list: GrowBuffer,
    /// Each segment's count of entries, [`UNSURE_COUNT_STRIDE`] words
    /// apart, then each work unit's entries.
    unsure_counts: GrowBuffer,
    /// The counters before the occlusion, to run it again when the unsure
    /// list overflows.
    counters_before: GrowBuffer,
    /// The last look-up run's unsure-list entries per work unit: the next
    /// run with as many units plans its ranges by them.
    last_unit_entries: Vec<u32>,
    /// At most this many unsure-list entries per range (tests: forces
    /// many ranges, and since ranges are planned without it, the runs
    /// again of ranges that overflow).
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
    /// Whether the pipelines apply the wedge rule (specialization constant
    /// 7, `WEDGE_RULE`).
    wedge_rule: bool,
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
    fn make(
        self,
        ctx: &GpuContext,
        alpha: bool,
        rotated: bool,
        wedge_rule: bool,
    ) -> Result<ComputePipeline> {
        let suffix = match (alpha, rotated) {
            (false, false) => "",
            (true, false) => "_alpha",
            (false, true) => "_rotated",
            (true, true) => "_alpha_rotated",
        };
        let flags = (alpha, rotated, wedge_rule);
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
            Kernel::Unsure => unsure_pipeline(
                ctx,
                &format!("soft_occlusion_unsure{suffix}"),
                (alpha, rotated),
            ),
        }
    }
}

impl SoftOcclusionPass {
    /// Checks the device and makes the buffers' holders; the pipelines
    /// come with the first light that needs each.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        require_occlusion_subgroup_ops(ctx, "soft occlusion")?;
        let info = ctx.info();
        if info.limits.max_compute_shared_memory_size < SHARED_BYTES {
            return Err(Error::Vulkan(format!(
                "soft occlusion needs {SHARED_BYTES} bytes of shared memory per workgroup, \"{}\" has {}",
                info.name, info.limits.max_compute_shared_memory_size
            )));
        }
        let pipelines = HashMap::new();
        Ok(SoftOcclusionPass {
            pipelines,
            unsure_list: GrowBuffer::storage("unsure_list"),
            unsure_counts: GrowBuffer::storage("unsure_counts"),
            counters_before: GrowBuffer::storage("counters_before_occlusion"),
            last_unit_entries: Vec::new(),
            list_limit: None,
            blocked: GrowBuffer::storage("blocked_masks"),
            light_samples: GrowBuffer::storage_uniform("light_samples"),
            no_table: GrowBuffer::storage("plane_lut_unused"),
            pixel_rotation: GrowBuffer::storage_uniform("pixel_rotation"),
            unsure_listed: (0, 0),
            wedge_rule: true,
        })
    }

    /// Turns the wedge rule on or off for the next runs (their pipelines
    /// are made with the other specialization when first needed).
    pub fn set_wedge_rule(&mut self, on: bool) {
        self.wedge_rule = on;
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
            self.make_kernel(ctx, kernel, alpha, rotated, self.wedge_rule)?;
        }
        Ok(())
    }

    /// Makes `kernel`'s pipeline (alpha round, rotation, wedge rule as
    /// given) unless the pass holds it already.
    fn make_kernel(
        &mut self,
        ctx: &GpuContext,
        kernel: Kernel,
        alpha: bool,
        rotated: bool,
        wedge_rule: bool,
    ) -> Result<()> {
        let wedge = wedge_key(kernel, wedge_rule);
        if let std::collections::hash_map::Entry::Vacant(e) =
            self.pipelines.entry((kernel, alpha, rotated, wedge))
        {
            e.insert(kernel.make(ctx, alpha, rotated, wedge)?);
        }
        Ok(())
    }

    /// Makes every kernel a light could need (each mode at each block
    /// count, the unsure tests; in the alpha round or not, rotated or not;
    /// exact mode's with the wedge rule and without), as
    /// [`SoftOcclusionPass::prepare`] would: since none is made up front,
    /// a test calls this (on a context with
    /// [`crate::vulkan::ContextOptions::eager_pipelines`]) to see every
    /// pipeline compile and pass validation. Returns how many of the
    /// pass's kernels are made (on other contexts, those dispatched).
    #[doc(hidden)]
    pub fn make_every_kernel(&mut self, ctx: &GpuContext) -> Result<usize> {
        let kernels = (1..=MAX_SOFT_SAMPLES / 128)
            .flat_map(|b| [Kernel::Sure(b), Kernel::Approx(b)])
            .chain([Kernel::Exact, Kernel::Unsure]);
        for kernel in kernels {
            for k in 0..8 {
                self.make_kernel(ctx, kernel, k & 1 != 0, k & 2 != 0, k & 4 != 0)?;
            }
        }
        Ok(self.pipelines.values().filter(|p| p.is_made()).count())
    }

    /// The pipeline of `kernel` in the alpha round or not, with the
    /// per-pixel rotation or not (and the wedge rule as set).
    fn pipeline(&self, kernel: Kernel, alpha: bool, rotated: bool) -> Result<&ComputePipeline> {
        let wedge = wedge_key(kernel, self.wedge_rule);
        self.pipelines
            .get(&(kernel, alpha, rotated, wedge))
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
        let groups = MAX_SOFT_SAMPLES / LIGHT_GROUP_SIZE;
        self.light_samples
            .get(ctx, 16 * (MAX_SOFT_SAMPLES + groups) as u64)?;
        self.pixel_rotation.get(ctx, 16 * (3 + 128))?;
        self.no_table.get(ctx, 16)?;
        self.counters_before.get(ctx, 4 * counter::COUNT as u64)?;
        let count_words = UNSURE_SEGMENTS as usize * UNSURE_COUNT_STRIDE;
        self.unsure_counts.get(ctx, 4 * count_words as u64)?;
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
        let plan = std::mem::take(&mut self.last_unit_entries);
        let units = r.frame.units();
        // The units' entry counts follow the segments' counts.
        let count_words = UNSURE_SEGMENTS as usize * UNSURE_COUNT_STRIDE;
        let counts_bytes = 4 * (count_words as u64 + units as u64);
        if self.unsure_counts.buffer().size() < counts_bytes {
            // No recorded pass may bind the buffer that growing frees.
            r.submit()?;
        }
        self.unsure_counts.get(r.ctx, counts_bytes)?;
        let sure = self.pipeline(Kernel::Sure(blocks), alpha, rotated)?;
        // The units in ranges, each followed by the exact tests of its
        // unsure list. A unit lists at most one entry per lane, pair and
        // block into its segment, so without a plan the first range is as
        // long as that bound allows and later ones follow the entries per
        // unit seen, to list about RANGE_TARGET entries per segment. Each
        // run counts every unit's entries: the next run with as many units
        // (a frame like this one) plans its ranges by them to that target,
        // and a range whose list overflowed (in any segment) runs
        // again as long as its own counts fit, from the counters before
        // it (its sure bits ORed twice are the same).
        let per_unit = unit_entries(blocks);
        let capacity = self.capacity(blocks);
        let segment = capacity / UNSURE_SEGMENTS;
        debug_assert!(segment >= per_unit);
        let safe = (UNSURE_SEGMENTS * (segment / per_unit).max(1)) as u32;
        // Planned without the limit, so that a limit makes ranges overflow.
        let whole_segment = self.unsure_list.len() / 32 / UNSURE_SEGMENTS;
        let target = range_target(r.ctx.info().is_cpu(), whole_segment);
        let plan = if plan.len() == units as usize {
            plan
        } else {
            Vec::new()
        };
        let mut seen = vec![0u32; units as usize];
        let mut ranges = 0u32;
        let mut len = safe;
        let mut start = 0u32;
        let mut retry = false;
        let mut listed_here = 0u64;
        while start < units {
            if !retry && !plan.is_empty() {
                // The entries of a like frame, with room for their spread
                // from run to run.
                len = fitting_prefix(&plan[start as usize..], target);
            }
            len = len.min(units - start);
            r.cmd.barrier(Barrier::ComputeToTransfer);
            r.cmd.fill_buffer(self.unsure_counts.slice(), 0)?;
            r.cmd
                .copy_buffer(counters.slice(), self.counters_before.buffer(), 0)?;
            r.cmd.barrier(Barrier::TransferToCompute);
            self.occlusion(r, sure, (start, len), table, passes, counters)?;
            r.submit()?;
            let end = (start + len) as usize;
            let c: Vec<u32> =
                r.ctx
                    .read_buffer_staged(self.unsure_counts.buffer(), 0, count_words + end)?;
            let fullest = c[..count_words]
                .iter()
                .step_by(UNSURE_COUNT_STRIDE)
                .map(|&n| n as u64)
                .max()
                .unwrap_or(0);
            let run = &c[count_words + start as usize..];
            if fullest > segment {
                r.cmd
                    .copy_buffer(self.counters_before.slice(), counters.buffer(), 0)?;
                r.cmd.barrier(Barrier::TransferToCompute);
                len = fitting_prefix(run, segment * 9 / 10).min(len - 1).max(1);
                retry = true;
                continue;
            }
            retry = false;
            self.test_unsure(r, (fullest, segment), passes.0, rotated)?;
            listed_here += run.iter().map(|&n| n as u64).sum::<u64>();
            seen[start as usize..end].copy_from_slice(run);
            ranges += 1;
            start += len;
            // Without a plan, the next range: as many units as this one's
            // density fits with room to spare, at most four times as many.
            let listed = fullest * UNSURE_SEGMENTS;
            let fit =
                (target * UNSURE_SEGMENTS) as f64 * len as f64 / (1.2 * listed as f64).max(1.0);
            len = fit.clamp(safe as f64, (4.0 * len as f64).max(safe as f64)) as u32;
        }
        self.unsure_listed.0 += listed_here;
        self.unsure_listed.1 += ranges;
        self.last_unit_entries = seen;
        Ok(())
    }

    /// Entries the unsure list holds per range for a light of `blocks`
    /// blocks: its size, or the limit, but never below one unit's bound
    /// (`unit_entries`) per segment, so that a range of one unit always
    /// fits.
    pub fn capacity(&self, blocks: usize) -> u64 {
        let limit = self
            .list_limit
            .unwrap_or(u64::MAX)
            .max(UNSURE_SEGMENTS * unit_entries(blocks));
        (self.unsure_list.len() / 32).min(limit)
    }

    /// Records the exact tests of the unsure list: at most `fullest`
    /// entries in each segment of `segment` entries.
    fn test_unsure(
        &self,
        r: &mut Recording,
        (fullest, segment): (u64, u64),
        lists: &TexelListPass,
        rotated: bool,
    ) -> Result<()> {
        let (list, triangles) = (&self.unsure_list, r.inputs.triangles);
        let samples = &lists.list_samples;
        let mut push = r.frame.push;
        push.more[3] = segment as u32;
        let unsure = self.pipeline(Kernel::Unsure, r.round == CasterRound::Alpha, rotated)?;
        let [records, textures, alphas] = r.inputs.alpha.bindings();
        r.pass("occlusion_unsure", |rec, _| {
            let bindings = [
                Binding::uniform_texel(list, RGBA32UI),
                Binding::uniform_texel(triangles, RGBA32UI),
                Binding::uniform_texel(samples, RGBA32UI),
                storage(&self.blocked),
                Binding::uniform_texel(&self.light_samples, vk::Format::R32G32B32A32_SFLOAT),
                records,
                textures,
                alphas,
                Binding::uniform_texel(&lists.list_sample_index, vk::Format::R32_UINT),
                Binding::uniform(&self.pixel_rotation),
                storage(&self.unsure_counts),
            ];
            let mut groups = groups(fullest as u32);
            groups[2] = UNSURE_SEGMENTS as u32;
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
        // soft.x: exact mode's block; the look-up modes': a list segment's
        // capacity (an integer field: as float bits it would be a denormal,
        // which a driver may flush to zero).
        let blocks = (r.frame.mask_words / 4).max(1) as usize;
        let capacity = (self.capacity(blocks) / UNSURE_SEGMENTS) as u32;
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
        (lists, casters, bins, clusters, pair_groups): SoftInputs,
        counters: &GrowBuffer,
    ) -> Result<()> {
        r.cmd.barrier(Barrier::TransferToCompute);
        let table = table.map_or(self.no_table.slice(), |t| t.into());
        let [records, textures, alphas] = r.inputs.alpha.bindings();
        r.pass("occlusion", |rec, pc| {
            let mut push: LightPush = bytemuck::pod_read_unaligned(pc);
            push.soft[0] = block;
            push.soft[3] = start;
            let bindings = [
                Binding::uniform_texel(&casters.pairs, RGBA32UI),
                Binding::uniform_texel(&self.light_samples, vk::Format::R32G32B32A32_SFLOAT),
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
                storage(&self.unsure_counts),
                Binding::uniform_texel(&pair_groups.groups, vk::Format::R32_UINT),
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

/// The wedge-rule flag a kernel's pipeline is made and kept with: the rule
/// as set for the exact kernel, off for the others (their shaders compile
/// it out, `WEDGE_COMPILED`), so that switching it builds no duplicate of
/// theirs.
fn wedge_key(kernel: Kernel, on: bool) -> bool {
    on && kernel == Kernel::Exact
}

/// A soft occlusion pipeline: `chunk` pairs per work unit (specialization
/// constant 2); `alpha`: the alpha-tested casters' round (constant 5);
/// `rotated`: the per-pixel rotation (constant 6); `wedge_rule`: the wedge
/// rule (constant 7).
fn occlusion_pipeline(
    ctx: &GpuContext,
    name: &str,
    spirv: &[u32],
    chunk: (u32, u32),
    (alpha, rotated, wedge_rule): (bool, bool, bool),
) -> Result<ComputePipeline> {
    let sb = DescriptorKind::StorageBuffer;
    let tb = DescriptorKind::UniformTexelBuffer;
    let ub = DescriptorKind::UniformBuffer;
    ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
        name,
        spirv,
        bindings: &[
            tb, tb, sb, tb, sb, sb, tb, sb, sb, sb, ub, tb, sb, tb, tb, tb, tb, tb, ub, sb, tb,
        ],
        push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
        specialization: &[
            chunk,
            (5, alpha as u32),
            (6, rotated as u32),
            (7, wedge_rule as u32),
        ],
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
    ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
        name,
        spirv: shaders::SOFT_OCCLUSION_UNSURE,
        bindings: &[tb, tb, tb, sb, tb, tb, tb, tb, tb, ub, sb],
        push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
        specialization: &[(5, alpha as u32), (6, rotated as u32)],
    })
}

/// The most units from the first of `entries` (unsure-list entries per
/// work unit, unit `i` in segment `i % UNSURE_SEGMENTS`) whose entries fit
/// `budget` in every segment; at least one.
fn fitting_prefix(entries: &[u32], budget: u64) -> u32 {
    let mut used = [0u64; UNSURE_SEGMENTS as usize];
    for (i, &n) in entries.iter().enumerate() {
        let k = i % UNSURE_SEGMENTS as usize;
        used[k] += n as u64;
        if used[k] > budget {
            return (i as u32).max(1);
        }
    }
    (entries.len() as u32).max(1)
}

/// A pipeline that `prepare` did not make.
fn not_made() -> crate::Error {
    crate::Error::InvalidInput("an occlusion pipeline was not prepared".into())
}

/// The `LightSamples` uniform block of the occlusion pass for `sl` (the
/// samples, then from sample [`MAX_SOFT_SAMPLES`] on their groups'
/// spheres, [`light_groups`]) and its per-pixel rotation block.
fn light_words(sl: &SoftLight) -> (Vec<[f32; 4]>, Vec<[u32; 4]>) {
    let mut samples: Vec<[f32; 4]> = sl.samples.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect();
    samples.resize(MAX_SOFT_SAMPLES, [0.0; 4]);
    samples.extend(light_groups(&sl.samples));
    (samples, pixel_rotation_block(sl))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fitting_prefix_stops_where_a_segment_overflows() {
        let s = UNSURE_SEGMENTS as usize;
        // Every unit lists 10: each segment takes budget / 10 units.
        let even = vec![10u32; 10 * s];
        assert_eq!(fitting_prefix(&even, 30), 3 * s as u32);
        assert_eq!(fitting_prefix(&even, 1000), 10 * s as u32);
        // One heavy unit in segment 1 stops the prefix at itself.
        let mut heavy = vec![0u32; 4 * s];
        heavy[s + 1] = 50;
        assert_eq!(fitting_prefix(&heavy, 49), s as u32 + 1);
        assert_eq!(fitting_prefix(&heavy, 50), 4 * s as u32);
        // A first unit over the budget still makes a range of one.
        assert_eq!(fitting_prefix(&[100, 0, 0], 10), 1);
        assert_eq!(fitting_prefix(&[], 10), 1);
    }

    /// The kernel's shared arrays are as SHARED_BYTES counts them: a unit's
    /// chunk of pairs fits `MAX_KEPT`, and the subgroup boxes are 64.
    #[test]
    fn shared_arrays_match_the_kernel() {
        let glsl = include_str!("../../shaders/soft_occlusion.comp");
        assert_eq!(
            crate::gpu::shared::tests::glsl_define(glsl, "MAX_KEPT"),
            Some(LOOKUP_PAIR_CHUNK.1 as u64)
        );
        for decl in [
            "shared uint kept_pairs[MAX_KEPT];",
            "shared uint meeting_pairs[MAX_KEPT];",
            "shared uint kept_count;",
            "shared uint meeting_count;",
            "shared vec4 chunk_lo[64], chunk_hi[64];",
        ] {
            assert!(glsl.contains(decl), "{decl}");
        }
        assert_eq!(
            glsl.matches("\nshared ").count(),
            5,
            "every shared array counted"
        );
        assert_eq!(SHARED_BYTES, 18_440);
    }
}
