//! Runs too large for one binding, split into batches around a light's
//! passes. View samples whose buffers (the samples, 32 B; the masks, 16 B
//! per block) would pass the device's binding limit run in batches, each a
//! complete run over all triangles, so the results are the same as in one
//! run (concatenated). Triangles whose caster pairs or planes would pass it,
//! or whose binned pairs do (known only after the count), run in batches
//! too, each over every view sample with its triangles named by global id;
//! a light sample is visible when no batch blocks it (the AND of the
//! batches). Forced small batches give bit-identical results
//! (`tests/soft_conformance.rs::triangle_batches_equal_one_run`).

use crate::cpu::light_view::LightView;
use crate::gpu::light_frame::LightInputs;
use crate::gpu::light_passes::{LightPasses, Ran, ShadowOutput};
use crate::gpu::shared::counter;
use crate::gpu::soft_light::{SampleRotation, SoftLight};
use crate::vulkan::{Barrier, BufferSlice, GpuContext, GrowBuffer};
use crate::{Error, Result};

/// Told (batch, batches), from 0, before each batch of view samples when a
/// run takes more than one (a frame's progress bar).
pub type BatchProgress = std::sync::Arc<dyn Fn(usize, usize) + Send + Sync>;

/// The batch limits and the copies batches run on (kept across frames).
pub struct Batches {
    /// At most this many view samples per run (None: as many as the
    /// device's binding limits allow).
    pub view_sample_limit: Option<usize>,
    /// At most this many triangles per run (None: as many as the device's
    /// binding limits allow for the caster pairs and planes).
    pub triangle_limit: Option<usize>,
    /// Told before each batch of view samples (None: nobody).
    pub progress: Option<BatchProgress>,
    samples_copy: GrowBuffer,
    triangles_copy: GrowBuffer,
}

/// What a batched run needs besides its inputs.
#[derive(Clone, Copy)]
pub struct RunOf<'a> {
    /// The light (camera-relative), or the centre of a light with extent.
    pub light: &'a LightView,
    /// Light texels per face side.
    pub resolution: u32,
    /// The light's samples and mode for soft shadows; `None` for hard
    /// shadows.
    pub soft: Option<&'a SoftLight>,
}

impl Batches {
    /// No limits, no copies yet.
    pub fn new() -> Self {
        Batches {
            view_sample_limit: None,
            triangle_limit: None,
            progress: None,
            samples_copy: GrowBuffer::storage("view_sample_batch"),
            triangles_copy: GrowBuffer::storage("triangle_batch"),
        }
    }

    /// The light's passes over `inputs`, in as many batches as the device's
    /// limits (or the forced ones) need.
    pub fn run(
        &mut self,
        passes: &mut LightPasses,
        ctx: &GpuContext,
        inputs: &LightInputs,
        of: RunOf,
    ) -> Result<ShadowOutput> {
        let max_range = ctx.info().limits.max_storage_buffer_range as u64;
        let words = of.soft.map_or(0, |sl| sl.mask_words()) as u64;
        let batch = batch_len(max_range, 32.max(4 * words), self.view_sample_limit);
        let n = inputs.n as usize;
        let limit = self.triangle_limit;
        if n <= batch {
            return triangle_batches(passes, &mut self.triangles_copy, limit, ctx, inputs, of);
        }
        let mut out: Option<ShadowOutput> = None;
        for start in (0..n).step_by(batch) {
            if let Some(progress) = &self.progress {
                progress(start / batch, n.div_ceil(batch));
            }
            let len = batch.min(n - start);
            let samples = copy_range(ctx, inputs.samples, &mut self.samples_copy, 32, start, len)?;
            let part = LightInputs {
                samples,
                n: len as u32,
                ..*inputs
            };
            // The batch's view sample 0 is pixel `start` (per-pixel rotation).
            let shifted = of.soft.and_then(|sl| {
                sl.rotation.map(|r| SoftLight {
                    rotation: Some(SampleRotation {
                        first_pixel: r.first_pixel + start as u32,
                        ..r
                    }),
                    ..sl.clone()
                })
            });
            let of = RunOf {
                soft: shifted.as_ref().or(of.soft),
                ..of
            };
            let o = triangle_batches(passes, &mut self.triangles_copy, limit, ctx, &part, of)?;
            out = Some(match out {
                None => {
                    let mut first = o;
                    reserve_results(&mut first, n)?;
                    first
                }
                Some(acc) => concatenate(acc, o),
            });
        }
        out.ok_or_else(|| Error::InvalidInput("no view samples".into()))
    }

    /// Frees the copies.
    pub fn release(&mut self) {
        self.samples_copy.release();
        self.triangles_copy.release();
    }
}

impl Default for Batches {
    fn default() -> Self {
        Self::new()
    }
}

/// The light's passes over every view sample of `inputs` and its
/// triangles, in batches of triangles when their buffers need it.
fn triangle_batches(
    passes: &mut LightPasses,
    copy: &mut GrowBuffer,
    limit: Option<usize>,
    ctx: &GpuContext,
    inputs: &LightInputs,
    of: RunOf,
) -> Result<ShadowOutput> {
    // Caster pairs (64 B per face) and planes (80 B) per triangle.
    let max_range = ctx.info().limits.max_storage_buffer_range as u64;
    let per_triangle = (64 * of.light.face_count() as u64).max(80);
    let batch = batch_len(max_range, per_triangle, limit);
    triangle_range(passes, copy, ctx, inputs, 0, inputs.nt as usize, batch, of)
}

/// Triangles `start..start + len` of `inputs` (all of them, or copied into
/// `copy`) in batches of at most `batch`, split further when their binned
/// pairs pass the binding limit.
#[allow(clippy::too_many_arguments)]
fn triangle_range(
    passes: &mut LightPasses,
    copy: &mut GrowBuffer,
    ctx: &GpuContext,
    inputs: &LightInputs,
    start: usize,
    len: usize,
    batch: usize,
    of: RunOf,
) -> Result<ShadowOutput> {
    if len > batch {
        // The batches' AND needs each one's masks, wanted or not.
        let wanted = std::mem::replace(&mut passes.read_masks, true);
        let mut out: Option<ShadowOutput> = None;
        let mut batches = || -> Result<()> {
            for s in (start..start + len).step_by(batch) {
                let l = batch.min(start + len - s);
                let o = triangle_range(passes, copy, ctx, inputs, s, l, batch, of)?;
                out = Some(match out.take() {
                    None => o,
                    Some(acc) => intersect(acc, o, of.soft),
                });
            }
            Ok(())
        };
        let ran = batches();
        passes.read_masks = wanted;
        ran?;
        let mut out = out.ok_or_else(|| Error::InvalidInput("no triangles".into()))?;
        if let (false, Some(so)) = (wanted, out.soft.as_mut()) {
            so.visible = Vec::new();
        }
        return Ok(out);
    }
    let ran = if start == 0 && len == inputs.nt as usize {
        passes.run(ctx, inputs, of.light, of.resolution, of.soft)?
    } else {
        let part = LightInputs {
            triangles: copy_range(ctx, inputs.triangles, copy, 48, start, len)?,
            nt: len as u32,
            triangle_base: inputs.triangle_base + start as u32,
            ..*inputs
        };
        passes.run(ctx, &part, of.light, of.resolution, of.soft)?
    };
    match ran {
        Ran::Done(o) => Ok(*o),
        Ran::TooManyPairs { binned_bytes } => {
            let max_range = ctx.info().limits.max_storage_buffer_range as u64;
            let smaller = (len as u64 * max_range / binned_bytes / 2).max(1) as usize;
            triangle_range(passes, copy, ctx, inputs, start, len, smaller, of)
        }
    }
}

/// Items per batch: as many as fit in `max_range` bytes at `per_item`
/// bytes each, at most `limit` (tests force small batches), at least one.
fn batch_len(max_range: u64, per_item: u64, limit: Option<usize>) -> usize {
    ((max_range / per_item) as usize)
        .min(limit.unwrap_or(usize::MAX))
        .max(1)
}

/// Elements `start..start + len` (of `stride` bytes) of `src`, copied into
/// `copy`: one batch's inputs.
fn copy_range<'a>(
    ctx: &GpuContext,
    src: BufferSlice<'_>,
    copy: &'a mut GrowBuffer,
    stride: u64,
    start: usize,
    len: usize,
) -> Result<BufferSlice<'a>> {
    let bytes = stride * len as u64;
    let dst = copy.get(ctx, bytes)?;
    let mut rec = ctx.begin()?;
    let from = src
        .buffer
        .slice(src.offset + stride * start as u64, bytes)?;
    rec.copy_buffer(from, dst, 0)?;
    rec.barrier(Barrier::TransferToCompute);
    ctx.submit_and_wait(rec)?;
    dst.slice(0, bytes)
}

/// The outputs of two view-sample batches, one after the other (counters
/// summed, list lengths of the batch with the longest list).
fn concatenate(mut acc: ShadowOutput, o: ShadowOutput) -> ShadowOutput {
    acc.lit.extend(o.lit);
    counter::add(&mut acc.counters, &o.counters);
    let longest = |l: &[u32]| l.iter().copied().max().unwrap_or(0);
    if longest(&o.list_lengths) > longest(&acc.list_lengths) {
        acc.list_lengths = o.list_lengths;
    }
    acc.timings.extend(o.timings);
    acc.buffer_bytes = acc.buffer_bytes.max(o.buffer_bytes);
    acc.allocations = acc.allocations + o.allocations;
    if let (Some(a), Some(b)) = (acc.soft.as_mut(), o.soft) {
        a.visibility.extend(b.visibility);
        a.visible.extend(b.visible);
        a.lut_built |= b.lut_built;
        a.unsure_entries += b.unsure_entries;
        a.unsure_ranges += b.unsure_ranges;
    }
    acc
}

/// The outputs of two triangle batches over the same view samples: lit
/// where both are, a light sample visible where both see it.
fn intersect(mut acc: ShadowOutput, o: ShadowOutput, soft: Option<&SoftLight>) -> ShadowOutput {
    for (a, b) in acc.lit.iter_mut().zip(&o.lit) {
        *a = match (*a, *b) {
            (Some(x), Some(y)) => Some(x && y),
            _ => None,
        };
    }
    counter::add(&mut acc.counters, &o.counters);
    acc.timings.extend(o.timings);
    acc.buffer_bytes = acc.buffer_bytes.max(o.buffer_bytes);
    acc.allocations = acc.allocations + o.allocations;
    if let (Some(a), Some(b), Some(sl)) = (acc.soft.as_mut(), o.soft, soft) {
        let words = a.mask_words;
        for (x, y) in a.visible.iter_mut().zip(&b.visible) {
            *x &= *y;
        }
        // Visibility = visible light samples / light samples (resolve_soft),
        // of the combined masks.
        let count = sl.samples.len() as f32;
        for (i, v) in a.visibility.iter_mut().enumerate() {
            if v.is_some() {
                let mask = &a.visible[i * words..(i + 1) * words];
                let bits: u32 = mask.iter().map(|w| w.count_ones()).sum();
                *v = Some(bits as f32 / count);
            }
        }
        a.lut_built |= b.lut_built;
        a.unsure_entries += b.unsure_entries;
        a.unsure_ranges += b.unsure_ranges;
    }
    acc
}

/// Reserves the host memory for the results of `n` view samples in `out`
/// (the first batch's), so that a request too large for this machine is a
/// clear error before the work, not an abort after it.
fn reserve_results(out: &mut ShadowOutput, n: usize) -> Result<()> {
    let more = n.saturating_sub(out.lit.len());
    let too_large = |what: &str, bytes: u128| {
        Error::InvalidInput(format!(
            "the results of {n} view samples ({what}, {:.1} GiB) do not fit in host memory; \
             pass fewer view samples per call",
            bytes as f64 / (1u64 << 30) as f64
        ))
    };
    out.lit
        .try_reserve_exact(more)
        .map_err(|_| too_large("lit flags", 2 * n as u128))?;
    if let Some(so) = out.soft.as_mut() {
        so.visibility
            .try_reserve_exact(more)
            .map_err(|_| too_large("visibility", 8 * n as u128))?;
        // Masks only where the run read them (LightPasses::read_masks).
        let words = if so.visible.is_empty() {
            0
        } else {
            so.mask_words * more
        };
        so.visible
            .try_reserve_exact(words)
            .map_err(|_| too_large("light-sample masks", 4 * (so.mask_words * n) as u128))?;
    }
    Ok(())
}
