//! One light's passes over one batch of view samples and triangles, in the
//! order of the paper: `record_passes` is the page to read against §3
//! (hard shadows) and §4 (soft shadows); [`LightPasses::run`] records it
//! and reads the results back, [`LightPasses::record_for_caller`] records
//! it into a renderer's command buffer. Each pass lives in its own
//! module with its shader family and its CPU twin of the same name in
//! [`crate::cpu`]; the buffers each writes belong to it and live across
//! frames ([`GrowBuffer`]), grown only when a frame needs more.

use crate::cpu::light_view::LightView;
use crate::gpu::casters::CasterPass;
use crate::gpu::clusters::ClusterPass;
use crate::gpu::light_frame::{CasterRound, Recording, UNITS_INDIRECT};
use crate::gpu::light_frame::{LightFrame, LightInputs};
use crate::gpu::light_view::LightViewPass;
use crate::gpu::occlusion::OcclusionPass;
use crate::gpu::pair_groups::PairGroupPass;
use crate::gpu::pass_clock::PassClock;
use crate::gpu::plane_lut::PlaneLutPass;
use crate::gpu::resolve::ResolvePass;
use crate::gpu::shared::counter;
use crate::gpu::soft_light::SoftLight;
use crate::gpu::soft_light::SoftMode;
use crate::gpu::soft_occlusion::SoftOcclusionPass;
use crate::gpu::texel_lists::TexelListPass;
use crate::gpu::tile_bin::TileBinPass;
use crate::vulkan::{
    vk, Allocations, Barrier, BufferSlice, CommandRecorder, GpuContext, GrowBuffer, PassTiming,
};
use crate::{Error, Result};

/// What one run of a light's passes returns.
#[derive(Clone, Debug)]
pub struct ShadowOutput {
    /// Per view sample: `None` when not evaluated (invalid, or facing away
    /// from the light), else whether it is lit (hard shadows; for soft
    /// shadows, whether no light sample was blocked is not tracked here).
    pub lit: Vec<Option<bool>>,
    /// The pass counters (indices in [`counter`]).
    pub counters: [u32; counter::COUNT],
    /// Per light texel, tile-major (`texel_index` in shadow_common.glsl):
    /// list length. Split runs keep the batch with the longest list.
    pub list_lengths: Vec<u32>,
    /// Milliseconds per pass.
    pub timings: Vec<PassTiming>,
    /// Bytes of GPU buffers the run used.
    pub buffer_bytes: u64,
    /// Buffers and images the run created (none once its resources are
    /// warm: a second frame of the same size reuses every one).
    pub allocations: Allocations,
    /// Soft shadows only.
    pub soft: Option<SoftOutput>,
}

/// What a soft-shadow run returns besides the common output.
#[derive(Clone, Debug)]
pub struct SoftOutput {
    /// Per view sample: visible fraction of the light samples, `None`
    /// where not evaluated (invalid, or facing away from the whole light).
    pub visibility: Vec<Option<f32>>,
    /// Visible light samples per view sample, `mask_words` words each (bit
    /// `j % 32` of word `j / 32` for light sample `j`); empty when the run
    /// did not read them back ([`LightPasses::read_masks`]).
    pub visible: Vec<u32>,
    /// Words per view sample in `visible` (4 per 128-sample block).
    pub mask_words: usize,
    /// Whether this run built the plane look-up texture (`lut_build` in the
    /// timings); false in exact mode and when the last one was reused.
    pub lut_built: bool,
    /// Look-up mode: entries of the unsure list (a pair's unsure bits in
    /// one 128-sample block), and the ranges of work units
    /// that listed them (each followed by its exact tests).
    pub unsure_entries: u64,
    /// See `unsure_entries`.
    pub unsure_ranges: u32,
}

/// How a run ended.
pub enum Ran {
    /// Every pass ran: the light's results, counters and timings.
    Done(Box<ShadowOutput>),
    /// The binned pairs (4 B each) pass the device's binding limit: the
    /// triangles must run in smaller batches.
    TooManyPairs {
        /// Bytes the binned (pair, tile) list would need (4 per entry),
        /// more than `maxStorageBufferRange`.
        binned_bytes: u64,
    },
}

/// Every pass of a light, made once; their buffers live across frames.
pub struct LightPasses {
    /// §4.3: the light's frusta fitted to the view samples (faces and
    /// windows).
    pub light_view: LightViewPass,
    /// §3.1: the per-light-texel lists of view samples.
    pub texel_lists: TexelListPass,
    /// The boxes of each tile's listed view samples (soft shadows).
    pub clusters: ClusterPass,
    /// §3.3, §4.1: caster planes and (caster, face) pairs.
    pub casters: CasterPass,
    /// §3.2: conservative rasterization of the pairs, binned per tile, and
    /// the occlusion work units.
    pub tile_bin: TileBinPass,
    /// Soft shadows: per binned pair, the groups of its tile's samples it
    /// may shadow (Sintorn et al. 2014's clusters, one level above the
    /// occlusion units' own).
    pub pair_groups: PairGroupPass,
    /// §3.3: hard-shadow occlusion (one shadow flag per view sample).
    pub occlusion: OcclusionPass,
    /// §4.2: the plane look-up texture, kept across runs of the same light
    /// shape.
    pub plane_lut: PlaneLutPass,
    /// §4.2: soft-shadow occlusion (a blocked light-sample mask per view
    /// sample).
    pub soft_occlusion: SoftOcclusionPass,
    /// Per view sample: evaluated or not, lit or visibility.
    pub resolve: ResolvePass,
    /// The passes' counters (`COUNTER_*`).
    pub counters: GrowBuffer,
    /// Times each pass of a run (GPU timestamps or host wall clock).
    pub clock: PassClock,
    /// Whether a soft run reads the visible light-sample masks back (on by
    /// default): 16 B per 128-sample block and view sample, 32 MiB at 512²
    /// and 1024 samples, which only textured lights, the library's masks
    /// and triangle batches (their AND) use.
    pub read_masks: bool,
}

impl LightPasses {
    /// Sets up every pass: pipelines are made at their first dispatch
    /// (soft occlusion's kernels with the first light that needs each), no
    /// buffer before the first run.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(LightPasses {
            light_view: LightViewPass::new(ctx)?,
            texel_lists: TexelListPass::new(ctx)?,
            clusters: ClusterPass::new(ctx)?,
            casters: CasterPass::new(ctx)?,
            tile_bin: TileBinPass::new(ctx)?,
            pair_groups: PairGroupPass::new(ctx)?,
            occlusion: OcclusionPass::new(ctx)?,
            plane_lut: PlaneLutPass::new(ctx)?,
            soft_occlusion: SoftOcclusionPass::new(ctx)?,
            resolve: ResolvePass::new(ctx)?,
            counters: GrowBuffer::storage("counters"),
            clock: PassClock::new(ctx)?,
            read_masks: true,
        })
    }

    /// The passes of `light` over `inputs`, in order; with `soft`, the same
    /// passes compute soft shadows of that light seen from its samples'
    /// centre: influence regions instead of projections, light-sample
    /// bitmasks instead of one bit.
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        inputs: &LightInputs,
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Result<Ran> {
        let before = ctx.allocations();
        let frame = LightFrame::new(inputs, light, resolution, soft);
        self.clock.restart(ctx);
        // §4.2: the plane look-up texture, built once per light shape.
        let lut_built = match soft.filter(|sl| sl.uses_table()) {
            Some(sl) => self.plane_lut.ensure(ctx, &mut self.clock, sl)?,
            None => false,
        };
        self.prepare(ctx, &frame, soft, inputs.alpha_casters)?;
        if let Some(sl) = soft {
            self.soft_occlusion.upload(ctx, sl)?;
        }
        let (stages, clock) = self.stages();
        let r = &mut Recording::new(ctx, clock, *inputs, frame)?;
        let carried = match record_passes(stages, r, soft)? {
            Ok(carried) => carried,
            Err(ran) => return Ok(ran),
        };
        r.submit()?;
        ctx.check_validation()?;
        let mut out = self.read_output(ctx, &frame, inputs, soft, lut_built)?;
        counter::add(&mut out.counters, &carried);
        out.allocations = ctx.allocations() - before;
        Ok(Ran::Done(Box::new(out)))
    }

    /// Sizes every buffer a caller's recording of `light` over `inputs`
    /// binds ([`LightPasses::record_for_caller`]), with a binned-pair list
    /// of `pair_capacity` entries. Call it for every light of a
    /// submission before recording any: a recording never allocates.
    pub fn prepare_for_caller(
        &mut self,
        ctx: &GpuContext,
        inputs: &LightInputs,
        (light, resolution, soft): (&LightView, u32, Option<&SoftLight>),
        pair_capacity: u32,
    ) -> Result<()> {
        let frame = LightFrame::new(inputs, light, resolution, soft);
        self.prepare(ctx, &frame, soft, inputs.alpha_casters)?;
        self.tile_bin
            .prepare_for_caller(ctx, &frame, pair_capacity)?;
        if soft.is_some() {
            self.pair_groups.prepare(ctx, &self.tile_bin)?;
        }
        self.texel_lists.reserve_scan(&frame)?;
        self.occlusion.shadowed.get(ctx, 4 * frame.n as u64)?;
        Ok(())
    }

    /// Records the passes of `light` over `inputs` into a caller's
    /// command buffer (`cmd`) without submitting or reading anything back:
    /// the list of binned pairs has the capacity
    /// [`LightPasses::prepare_for_caller`] gave it, the occlusion passes
    /// dispatch the units the GPU counted, and the light's status words go
    /// to `status` (`record_args.comp`). Soft shadows in exact mode only.
    /// The result stays in the resolve pass's `result` buffer.
    pub fn record_for_caller(
        &mut self,
        ctx: &GpuContext,
        (cmd, status): (CommandRecorder, BufferSlice),
        inputs: &LightInputs,
        (light, resolution, soft): (&LightView, u32, Option<&SoftLight>),
    ) -> Result<CommandRecorder> {
        if let Some(sl) = soft.filter(|sl| sl.mode != SoftMode::Exact) {
            return Err(Error::InvalidInput(format!(
                "a recording into a caller's command buffer computes soft shadows in exact \
                 mode only (this light asks for {:?} mode, which sizes its work on the host)",
                sl.mode
            )));
        }
        let frame = LightFrame::new(inputs, light, resolution, soft);
        let before = ctx.allocations();
        self.prepare(ctx, &frame, soft, inputs.alpha_casters)?;
        let grew = |now: Allocations| {
            Error::InvalidInput(format!(
                "{:?}: a buffer had to grow while recording for a caller: prepare every light \
                 of the submission first",
                now - before
            ))
        };
        if ctx.allocations() != before {
            return Err(grew(ctx.allocations()));
        }
        let (stages, clock) = self.stages();
        let r = &mut Recording::for_caller(ctx, clock, *inputs, frame, (cmd, status));
        // What the last light's passes read, this one's clears rewrite.
        r.cmd.barrier(Barrier::ComputeToTransfer);
        if let Some(sl) = soft {
            stages.soft_occlusion.record_upload(&mut r.cmd, sl)?;
        }
        if let Err(Ran::TooManyPairs { .. }) = record_passes(stages, r, soft)? {
            return Err(Error::Vulkan(
                "internal: a caller's recording asked for smaller batches".into(),
            ));
        }
        if ctx.allocations() != before {
            return Err(grew(ctx.allocations()));
        }
        let none = CommandRecorder::for_caller(ctx.device(), vk::CommandBuffer::null());
        Ok(std::mem::replace(&mut r.cmd, none))
    }

    /// The passes as [`record_passes`] takes them, and the clock apart.
    fn stages(&mut self) -> (Stages<'_>, &mut PassClock) {
        let LightPasses {
            light_view,
            texel_lists,
            clusters,
            casters,
            tile_bin,
            pair_groups,
            occlusion,
            plane_lut,
            soft_occlusion,
            resolve,
            counters,
            clock,
            read_masks: _,
        } = self;
        let stages = Stages {
            light_view,
            texel_lists,
            clusters,
            casters,
            tile_bin,
            pair_groups,
            occlusion,
            plane_lut,
            soft_occlusion,
            resolve,
            counters,
        };
        (stages, clock)
    }

    /// Sizes every pass's buffers for `frame` (uploads the fit keys and the
    /// light samples).
    fn prepare(
        &mut self,
        ctx: &GpuContext,
        frame: &LightFrame,
        soft: Option<&SoftLight>,
        alpha_casters: bool,
    ) -> Result<()> {
        self.counters.get(ctx, 4 * counter::COUNT as u64)?;
        self.light_view.prepare(ctx)?;
        self.texel_lists.prepare(ctx, frame)?;
        self.clusters.prepare(ctx, frame)?;
        self.casters.prepare(ctx, frame)?;
        self.tile_bin.prepare(ctx, frame)?;
        let rotated = soft.is_some_and(|sl| sl.rotation.is_some());
        self.resolve.prepare(ctx, frame, rotated)?;
        if let Some(sl) = soft {
            self.soft_occlusion.prepare(ctx, frame, sl, alpha_casters)?;
        }
        Ok(())
    }

    /// Reads the results, counters and list lengths back.
    fn read_output(
        &self,
        ctx: &GpuContext,
        frame: &LightFrame,
        inputs: &LightInputs,
        soft: Option<&SoftLight>,
        lut_built: bool,
    ) -> Result<ShadowOutput> {
        let n = frame.n as usize;
        let result: Vec<u32> = ctx.read_buffer_staged(self.resolve.result.buffer(), 0, n)?;
        let soft_out = match soft {
            Some(_) => {
                let words = frame.mask_words as usize;
                let visible = if words > 0 && n > 0 && self.read_masks {
                    ctx.read_buffer_staged(self.resolve.visible.buffer(), 0, words * n)?
                } else {
                    Vec::new()
                };
                let visibility = result
                    .iter()
                    .map(|&r| {
                        let v = f32::from_bits(r);
                        (v >= 0.0).then_some(v)
                    })
                    .collect();
                let (unsure_entries, unsure_ranges) = self.soft_occlusion.unsure_listed;
                Some(SoftOutput {
                    visibility,
                    visible,
                    mask_words: words,
                    lut_built,
                    unsure_entries,
                    unsure_ranges,
                })
            }
            None => None,
        };
        let c: Vec<u32> = ctx.read_buffer_staged(self.counters.buffer(), 0, counter::COUNT)?;
        let list_lengths: Vec<u32> =
            ctx.read_buffer_staged(self.texel_lists.counts.buffer(), 0, frame.texels as usize)?;
        let mut counters = [0u32; counter::COUNT];
        counters.copy_from_slice(&c);
        let mut buffer_bytes = inputs.samples.size
            + inputs.triangles.size
            + self.counters.len()
            + self.light_view.bytes()
            + self.texel_lists.bytes()
            + self.clusters.bytes()
            + self.casters.bytes()
            + self.tile_bin.bytes()
            + self.resolve.result.len();
        if let Some(sl) = soft {
            buffer_bytes += self.soft_occlusion.blocked.len()
                + self.resolve.visible.len()
                + self.pair_groups.bytes();
            if sl.uses_table() {
                buffer_bytes += self.plane_lut.table().map_or(0, |t| t.size());
            }
        } else {
            buffer_bytes += self.occlusion.shadowed.len();
        }
        Ok(ShadowOutput {
            lit: result
                .iter()
                .map(|&r| (r & 2 != 0).then_some(r & 1 != 0))
                .collect(),
            counters,
            list_lengths,
            timings: self.clock.results()?,
            buffer_bytes,
            allocations: Allocations::default(),
            soft: soft_out,
        })
    }
}

/// Every pass of a light, borrowed apart from the clock that the
/// recording holds.
struct Stages<'p> {
    light_view: &'p mut LightViewPass,
    texel_lists: &'p mut TexelListPass,
    clusters: &'p mut ClusterPass,
    casters: &'p mut CasterPass,
    tile_bin: &'p mut TileBinPass,
    pair_groups: &'p mut PairGroupPass,
    occlusion: &'p mut OcclusionPass,
    plane_lut: &'p mut PlaneLutPass,
    soft_occlusion: &'p mut SoftOcclusionPass,
    resolve: &'p mut ResolvePass,
    counters: &'p mut GrowBuffer,
}

/// The passes of one light in the paper's order, recorded into `r`: the
/// page to read against §3 and §4. Returns the counters of the rounds
/// before the last (to add to the last's), or the batching a run needs.
fn record_passes(
    stages: Stages,
    r: &mut Recording,
    soft: Option<&SoftLight>,
) -> Result<std::result::Result<[u32; counter::COUNT], Ran>> {
    let Stages {
        light_view,
        texel_lists,
        clusters,
        casters,
        tile_bin,
        pair_groups,
        occlusion,
        plane_lut,
        soft_occlusion,
        resolve,
        counters,
    } = stages;
    let inputs = r.inputs;
    r.cmd.fill_buffer(counters.slice(), 0)?;
    texel_lists.record_clears(&mut r.cmd)?;
    r.cmd.barrier(Barrier::TransferToCompute);

    // §4.3: the light's frusta fitted to the view samples; §3.1: the
    // per-light-texel lists of view samples (count, scan, scatter).
    light_view.record(r)?;
    texel_lists.record(r, &light_view.faces)?;
    // Sintorn et al. 2014: each tile's view samples as one box (soft).
    clusters.record(r, texel_lists, soft.is_some())?;
    // §3.2-§4.2: the casters against the samples, in one round; or
    // two when some are alpha-tested: the opaque ones, then those with
    // their alpha tests, ORed into what the first blocked.
    let mut carried = [0u32; counter::COUNT];
    for (k, &round) in CasterRound::of(&inputs).iter().enumerate() {
        if k > 0 {
            carry_counters(r, counters, &mut carried)?;
        }
        r.set_round(round);
        let round_light = soft.map(|sl| sl.for_round(round));
        let samples = (&*light_view, &*texel_lists, &*clusters, &*plane_lut);
        let tests = (
            &mut *casters,
            &mut *tile_bin,
            &mut *pair_groups,
            &mut *occlusion,
            &mut *soft_occlusion,
        );
        let first = k == 0;
        if let Some(ran) = cast(r, samples, tests, counters, round_light.as_deref(), first)? {
            return Ok(Err(ran));
        }
    }
    // Visibility = visible light samples / light samples (no round's:
    // its timing has no round prefix).
    r.set_round(CasterRound::All);
    match soft {
        None => resolve.record_hard(r, texel_lists, &occlusion.shadowed)?,
        Some(sl) => {
            let rotated = sl.rotation.is_some();
            resolve.record_soft(r, texel_lists, soft_occlusion, rotated)?
        }
    }
    Ok(Ok(carried))
}

/// One round of casters: each caster's planes and its projection or
/// influence region (§3.3, §4.1), conservatively rasterized and binned per
/// tile, less the tiles whose box it cannot shadow (§3.2), and (soft) the
/// groups of each tile's samples it cannot shadow; then every
/// listed view sample against its tile's casters (§3.3, §4.2): one bit, or
/// a light-sample bitmask ORed over the casters (and over the rounds
/// before, unless `first`). `Some` when the binned pairs pass the binding
/// limit: the triangles must run in smaller batches.
fn cast(
    r: &mut Recording,
    (light_view, texel_lists, clusters, plane_lut): (
        &LightViewPass,
        &TexelListPass,
        &ClusterPass,
        &PlaneLutPass,
    ),
    (casters, tile_bin, pair_groups, occlusion, soft_occlusion): (
        &mut CasterPass,
        &mut TileBinPass,
        &mut PairGroupPass,
        &mut OcclusionPass,
        &mut SoftOcclusionPass,
    ),
    counters: &GrowBuffer,
    soft: Option<&SoftLight>,
    first: bool,
) -> Result<Option<Ran>> {
    tile_bin.record_clears(&mut r.cmd)?;
    r.cmd.barrier(Barrier::TransferToCompute);
    casters.record(r, &light_view.faces, counters)?;
    let bins = (&*casters, texel_lists, clusters);
    tile_bin.record_count(r, bins, counters, soft)?;
    // The binned pairs, where the host knows them.
    let binned = if r.for_caller.is_some() {
        // A caller's recording cannot read the count back: the list has a
        // fixed capacity and the GPU sizes the occlusion dispatches.
        tile_bin.record_scatter(r, None, bins, counters)?;
        tile_bin.record_args(r)?;
        r.frame.set_units(UNITS_INDIRECT);
        None
    } else {
        r.submit()?;
        // Only now is the number of binned pairs known: past the binding
        // limit, the triangles run again in smaller batches.
        let totals = tile_bin.totals(r.ctx, &r.frame)?;
        let binned_bytes = 4 * totals.pairs as u64;
        let max_range = r.ctx.info().limits.max_storage_buffer_range as u64;
        if binned_bytes > max_range && r.frame.nt > 1 {
            return Ok(Some(Ran::TooManyPairs { binned_bytes }));
        }
        tile_bin.record_scatter(r, Some(totals), bins, counters)?;
        r.frame.set_units(totals.units);
        Some(totals.pairs)
    };
    match soft {
        None => occlusion.record(r, (texel_lists, casters, tile_bin), counters, first)?,
        Some(sl) => {
            // Sintorn et al. 2014, one level up: each pair against the
            // boxes of its tile's groups of samples, before the units.
            let inputs = (texel_lists, &*casters, &*tile_bin, clusters);
            pair_groups.record(r, inputs, binned)?;
            let inputs = (texel_lists, &*casters, &*tile_bin, clusters, &*pair_groups);
            soft_occlusion.record(r, sl, plane_lut.table(), inputs, counters, first)?;
        }
    }
    Ok(None)
}

/// Between rounds: adds the counters so far to `carried` and zeroes them
/// (the next round's casters count their pairs from 0).
fn carry_counters(
    r: &mut Recording,
    counters: &GrowBuffer,
    carried: &mut [u32; counter::COUNT],
) -> Result<()> {
    if r.for_caller.is_some() {
        // Nothing is read back from a caller's recording: the first
        // round's counts are dropped.
        r.cmd.barrier(Barrier::ComputeToTransfer);
        r.cmd.fill_buffer(counters.slice(), 0)?;
        r.cmd.barrier(Barrier::TransferToCompute);
        return Ok(());
    }
    r.submit()?;
    let c: Vec<u32> = r
        .ctx
        .read_buffer_staged(counters.buffer(), 0, counter::COUNT)?;
    let mut round = [0u32; counter::COUNT];
    round.copy_from_slice(&c);
    counter::add(carried, &round);
    r.cmd.fill_buffer(counters.slice(), 0)?;
    r.cmd.barrier(Barrier::TransferToCompute);
    Ok(())
}
