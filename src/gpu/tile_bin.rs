//! Conservative rasterization of the casters over the light texels (paper
//! §3.2), binned per tile of [`TILE`]² texels: `tile_bin.comp` counts the
//! tiles each (caster, face) pair's rectangle and edges may touch (less
//! those whose view-sample box it cannot shadow, [`crate::gpu::clusters`]), a scan
//! gives each tile's offset, and the same shader scatters the pairs into
//! per-tile lists. `tile_bin_units.comp` sizes each tile's occlusion work
//! units (chunks of its pairs times chunks of its listed samples, so that no
//! invocation loops past lavapipe's 65,535 iterations), scanned too.
//! CPU twin: [`crate::cpu::tile_bin`].
//!
//! [`TILE`]: crate::gpu::light_frame::TILE

use crate::gpu::clusters::ClusterPass;
use crate::gpu::dispatch::{groups, storage, R32UI, RGBA32UI};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::Recording;
use crate::gpu::scan::ScanPass;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::soft_light::{SoftLight, SoftMode};
use crate::gpu::{casters::CasterPass, texel_lists::TexelListPass};
use crate::vulkan::{
    vk, Barrier, Binding, BufferDesc, CommandRecorder, ComputePipeline, ComputePipelineDesc,
    DescriptorKind, GpuContext, GrowBuffer,
};
use crate::Result;

/// Pairs per soft occlusion work unit in exact mode (specialization
/// constant 2, `OCC_PAIR_CHUNK`): each lane has one sample, and each test
/// loops over at most 144 iterations (8 light-sample groups, up to 8 of
/// them tested, 16 samples each), so 256 · 146 (with the loops over each
/// window of pairs) stays below lavapipe's 65535 loop iterations per
/// invocation.
pub const SOFT_PAIR_CHUNK: (u32, u32) = (2, 256);

/// Pairs per soft occlusion work unit in look-up and approximate modes (any
/// block count). Fewer, longer units pay off on lavapipe, which runs a
/// kernel's code outside loops for every SIMD vector of every unit even
/// when no lane is active: 2048 instead of 512 made warm 512² frames
/// (128 samples, sphere light) 0.86× as long on ToyCar on a ground, 0.93×
/// on `torus_knot:20000`, 0.92× on `builtin:hairball`, and 0.83× on ToyCar
/// at 1024 samples (1024 pairs helped less and made hairball slower; 4096
/// did no better than 2048). Earlier, 512 instead of 256 made approximate mode
/// 1.4–1.5× faster on ToyCar.
/// Its loops run at most 6 + 2 · blocks times per kept pair, and once per
/// unsure bit tested in place (and per block of them), which the kernel's
/// `in_place_budget` holds per subgroup to what the others leave of
/// lavapipe's 65535 loop iterations per subgroup (one SIMD vector, whose
/// loops run as long as their busiest lane). The bound is the shared
/// memory that holds a unit's pairs (`MAX_KEPT`). The
/// unsure list holds at most one entry per lane, pair and block of a unit
/// (`SoftOcclusionPass::capacity`).
pub const LOOKUP_PAIR_CHUNK: (u32, u32) = (2, 2048);

/// Soft occlusion compacts a unit's pairs into `MAX_KEPT` (2048) slots of
/// shared memory (soft_occlusion.comp): no chunk may be longer.
const _: () = assert!(SOFT_PAIR_CHUNK.1 <= 2048 && LOOKUP_PAIR_CHUNK.1 <= 2048);

/// The binning passes' pipelines and the per-tile lists they build.
pub struct TileBinPass {
    /// Count and scatter: hard; soft (specialization constant 4,
    /// `CLUSTERS`: the view-sample clusters' code compiled in) for the pairs
    /// binned row by row; soft for the pairs of many tiles, binned by blocks
    /// of tiles (constant 5, `BY_BLOCKS`).
    count: [ComputePipeline; 3],
    scatter: [ComputePipeline; 3],
    /// Hard shadows' work units: chunks of the tile's longest texel list.
    units_hard: ComputePipeline,
    /// Soft shadows' work units: one lane per listed sample of the tile.
    units_soft: ComputePipeline,
    /// The same with the look-up and approximate modes' chunks
    /// (`LOOKUP_PAIR_CHUNK`).
    units_lookup: ComputePipeline,
    scan: ScanPass,
    /// A caller's recording: the occlusion passes' indirect workgroup counts
    /// from the scans' totals (`record_args.comp`).
    args: ComputePipeline,
    /// Those workgroup counts.
    pub dispatch_args: GrowBuffer,
    /// Per tile: binned pairs (count, then scatter cursor).
    tile_counts: GrowBuffer,
    /// Per tile: offset of its pairs in `tile_pairs`; `[tiles]` = total.
    pub tile_offsets: GrowBuffer,
    /// Per tile: occlusion work units.
    tile_units: GrowBuffer,
    /// Per tile: its first work unit; `[tiles]` = total.
    pub unit_offsets: GrowBuffer,
    /// The binned pair indices, tile by tile.
    pub tile_pairs: GrowBuffer,
    /// Per pair whose rectangle spans at most 32 tiles: the tiles the
    /// count kept, one bit each (the scatter writes them without testing
    /// the rules again).
    pair_tiles: GrowBuffer,
}

/// What the count found: the binned pairs and the occlusion work units.
#[derive(Clone, Copy, Debug)]
pub struct BinTotals {
    /// (Pair, tile) entries binned over all tiles: the length of
    /// `tile_pairs`.
    pub pairs: u32,
    /// Occlusion work units over all tiles (`tile_bin_units.comp`).
    pub units: u32,
}

impl TileBinPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let sb = DescriptorKind::StorageBuffer;
        let tb = DescriptorKind::UniformTexelBuffer;
        let bin_bindings = [sb, sb, sb, tb, sb, tb, tb, tb, sb];
        let make = |name, spirv, bindings: &[DescriptorKind], spec: &[(u32, u32)]| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name,
                spirv,
                bindings,
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: spec,
            })
        };
        Ok(TileBinPass {
            count: [
                make(
                    "tile_bin_count",
                    shaders::TILE_BIN,
                    &bin_bindings,
                    &[(1, 0), (4, 0)],
                )?,
                make(
                    "tile_bin_count_soft",
                    shaders::TILE_BIN,
                    &bin_bindings,
                    &[(1, 0), (4, 1)],
                )?,
                make(
                    "tile_bin_count_soft_blocks",
                    shaders::TILE_BIN,
                    &bin_bindings,
                    &[(1, 0), (4, 1), (5, 1)],
                )?,
            ],
            scatter: [
                make(
                    "tile_bin_scatter",
                    shaders::TILE_BIN,
                    &bin_bindings,
                    &[(1, 1), (4, 0)],
                )?,
                make(
                    "tile_bin_scatter_soft",
                    shaders::TILE_BIN,
                    &bin_bindings,
                    &[(1, 1), (4, 1)],
                )?,
                make(
                    "tile_bin_scatter_soft_blocks",
                    shaders::TILE_BIN,
                    &bin_bindings,
                    &[(1, 1), (4, 1), (5, 1)],
                )?,
            ],
            units_hard: make("tile_bin_units", shaders::TILE_BIN_UNITS, &[sb; 3], &[])?,
            units_soft: make(
                "tile_bin_units_soft",
                shaders::TILE_BIN_UNITS_SAMPLE_LANES,
                &[sb; 3],
                &[SOFT_PAIR_CHUNK],
            )?,
            units_lookup: make(
                "tile_bin_units_lookup",
                shaders::TILE_BIN_UNITS_SAMPLE_LANES,
                &[sb; 3],
                &[LOOKUP_PAIR_CHUNK],
            )?,
            scan: ScanPass::new(ctx)?,
            args: make("record_args", shaders::RECORD_ARGS, &[sb; 5], &[])?,
            dispatch_args: {
                let mut args = BufferDesc::storage("occlusion_dispatch_args", 0);
                args.usage |= vk::BufferUsageFlags::INDIRECT_BUFFER;
                GrowBuffer::new(args)
            },
            tile_counts: GrowBuffer::storage("tile_counts"),
            tile_offsets: GrowBuffer::storage("tile_offsets"),
            tile_units: GrowBuffer::storage("tile_units"),
            unit_offsets: GrowBuffer::storage("unit_offsets"),
            tile_pairs: GrowBuffer::storage("tile_pairs"),
            pair_tiles: GrowBuffer::storage("pair_tiles"),
        })
    }

    /// Sizes the per-tile buffers (`tile_pairs` is sized by the count).
    pub fn prepare(&mut self, ctx: &GpuContext, frame: &LightFrame) -> Result<()> {
        let tiles = frame.tiles as u64;
        self.tile_counts.get(ctx, 4 * tiles)?;
        self.tile_offsets.get(ctx, 4 * (tiles + 1))?;
        self.tile_units.get(ctx, 4 * tiles)?;
        self.unit_offsets.get(ctx, 4 * (tiles + 1))?;
        self.pair_tiles
            .get(ctx, 4 * frame.pair_capacity.max(1) as u64)?;
        Ok(())
    }

    /// Sizes the binned-pair list of a caller's recording, which cannot
    /// wait for the count: `capacity` entries (past them,
    /// `record_args.comp` reports the overflow and runs no unit).
    pub fn prepare_for_caller(
        &mut self,
        ctx: &GpuContext,
        frame: &LightFrame,
        capacity: u32,
    ) -> Result<()> {
        self.tile_pairs.get(ctx, 4 * capacity.max(1) as u64)?;
        self.dispatch_args.get(ctx, 12)?;
        self.scan.reserve(frame.tiles)?;
        Ok(())
    }

    /// A caller's recording, after the scatter: the occlusion passes'
    /// workgroup counts from the scans' totals, and the light's status
    /// words (binned pairs, units, overflow, 1).
    pub fn record_args(&mut self, r: &mut Recording) -> Result<()> {
        let status = r.for_caller.ok_or_else(|| {
            crate::Error::Vulkan("internal: record_args outside a caller's recording".into())
        })?;
        let (offsets, units) = (&self.tile_offsets, &self.unit_offsets);
        let (pairs, args) = (&self.tile_pairs, &self.dispatch_args);
        r.pass("record_args", |rec, pc| {
            let bindings = [
                storage(offsets),
                storage(units),
                storage(pairs),
                storage(args),
                storage(status),
            ];
            rec.dispatch(&self.args, &bindings, pc, [1, 1, 1])?;
            rec.barrier(Barrier::ComputeToIndirect);
            Ok(())
        })
    }

    /// Records the clears this pass needs before the run's first pass.
    pub fn record_clears(&self, rec: &mut CommandRecorder) -> Result<()> {
        rec.fill_buffer(self.tile_counts.slice(), 0)
    }

    /// Records the count of pairs per tile (of the `casters`' pairs, over
    /// the tiles the `lists` occupy) and of work units per tile (soft: one
    /// lane per listed sample; hard: chunks of the tile's longest list), and
    /// both scans; ends with a barrier to the host, which reads the totals.
    pub fn record_count(
        &mut self,
        r: &mut Recording,
        (casters, lists, clusters): (&CasterPass, &TexelListPass, &ClusterPass),
        counters: &GrowBuffer,
        soft: Option<&SoftLight>,
    ) -> Result<()> {
        let tiles = r.frame.tiles;
        r.pass("tile_bin_count", |rec, pc| {
            let bindings = [
                storage(&casters.pairs),
                storage(counters),
                storage(&self.tile_counts),
                Binding::uniform_texel(&self.tile_offsets, R32UI),
                storage(&self.tile_offsets),
                Binding::uniform_texel(&lists.tile_max_len, R32UI),
                Binding::uniform_texel(&clusters.boxes, RGBA32UI),
                Binding::uniform_texel(&casters.large_pairs, R32UI),
                storage(&self.pair_tiles),
            ];
            self.dispatch_bins(rec, &self.count, soft.is_some(), &bindings, pc, casters)?;
            let (units, per_tile) = match soft {
                None => (&self.units_hard, &lists.tile_max_len),
                Some(sl) if sl.mode != SoftMode::Exact => (&self.units_lookup, &lists.offsets),
                Some(_) => (&self.units_soft, &lists.offsets),
            };
            let bindings = [
                storage(&self.tile_counts),
                storage(per_tile),
                storage(&self.tile_units),
            ];
            rec.dispatch(units, &bindings, pc, groups(tiles))
        })?;
        let scan = &mut self.scan;
        let (tile_counts, tile_offsets) = (&self.tile_counts, &self.tile_offsets);
        let (tile_units, unit_offsets) = (&self.tile_units, &self.unit_offsets);
        r.pass("tile_scan", |rec, _| {
            scan.record(rec, tile_counts.slice(), tile_offsets.slice(), tiles)?;
            scan.record(rec, tile_units.slice(), unit_offsets.slice(), tiles)?;
            rec.barrier(Barrier::ComputeToHost);
            Ok(())
        })
    }

    /// The totals the count found (after its submission was waited for).
    pub fn totals(&self, ctx: &GpuContext, frame: &LightFrame) -> Result<BinTotals> {
        let at = 4 * frame.tiles as u64;
        let pairs: Vec<u32> = ctx.read_buffer_staged(self.tile_offsets.buffer(), at, 1)?;
        let units: Vec<u32> = ctx.read_buffer_staged(self.unit_offsets.buffer(), at, 1)?;
        Ok(BinTotals {
            pairs: pairs[0],
            units: units[0],
        })
    }

    /// Records the scatter of the pairs into their tiles' lists, sized to
    /// the `totals` the count found (`None`: a caller's recording, whose
    /// list was sized by [`TileBinPass::prepare_for_caller`]).
    pub fn record_scatter(
        &mut self,
        r: &mut Recording,
        totals: Option<BinTotals>,
        (casters, lists, clusters): (&CasterPass, &TexelListPass, &ClusterPass),
        counters: &GrowBuffer,
    ) -> Result<()> {
        match totals {
            Some(totals) => {
                self.tile_pairs.get(r.ctx, 4 * totals.pairs as u64)?;
            }
            // The scans read tile_counts, which the fill below rewrites.
            None => r.cmd.barrier(Barrier::ComputeToTransfer),
        }
        r.cmd.fill_buffer(self.tile_counts.slice(), 0)?;
        r.cmd.barrier(Barrier::TransferToCompute);
        let soft = r.frame.is_soft();
        r.pass("tile_bin_scatter", |rec, pc| {
            let bindings = [
                storage(&casters.pairs),
                storage(counters),
                storage(&self.tile_counts),
                Binding::uniform_texel(&self.tile_offsets, R32UI),
                storage(&self.tile_pairs),
                Binding::uniform_texel(&lists.tile_max_len, R32UI),
                Binding::uniform_texel(&clusters.boxes, RGBA32UI),
                Binding::uniform_texel(&casters.large_pairs, R32UI),
                storage(&self.pair_tiles),
            ];
            self.dispatch_bins(rec, &self.scatter, soft, &bindings, pc, casters)
        })
    }

    /// The count's or scatter's dispatches over the pairs written (an
    /// indirect dispatch: over their capacity, triangles × faces, the idle
    /// invocations cost ToyCar's count 26 ms): soft runs bin the pairs of
    /// many tiles in a pipeline of their own, first, so that they lead
    /// their tiles' lists (after the others, TransmissionTest's occlusion
    /// took 1590–1620 ms against 1585–1590 with the same tests).
    fn dispatch_bins(
        &self,
        rec: &mut CommandRecorder,
        pipelines: &[ComputePipeline; 3],
        soft: bool,
        bindings: &[Binding],
        pc: &[u8],
        casters: &CasterPass,
    ) -> Result<()> {
        let [hard, rows, blocks] = pipelines;
        let (pairs, large) = (&casters.pair_dispatch, &casters.large_pair_dispatch);
        let runs: &[(&ComputePipeline, &GrowBuffer)] = if soft {
            // The large pairs' list first, then the others.
            &[(blocks, large), (rows, pairs)]
        } else {
            &[(hard, pairs)]
        };
        for &(pipeline, args) in runs {
            rec.dispatch_indirect(pipeline, bindings, pc, args.buffer())?;
            rec.barrier(Barrier::ComputeToCompute);
        }
        Ok(())
    }

    /// Bytes this run binds.
    pub fn bytes(&self) -> u64 {
        [
            &self.tile_counts,
            &self.tile_offsets,
            &self.tile_units,
            &self.unit_offsets,
            &self.tile_pairs,
            &self.pair_tiles,
        ]
        .iter()
        .map(|b| b.len())
        .sum()
    }
}
