//! GPU timestamps around named passes, resolved to milliseconds with the
//! device's `timestampPeriod`. On a queue without timestamps every pass is
//! reported with `ms: None` instead of failing.

use std::sync::Arc;

use ash::vk;

use super::commands::CommandRecorder;
use super::context::GpuContext;
use super::device::Device;
use crate::{Error, Result};

/// The time one pass took.
#[derive(Clone, Debug, PartialEq)]
pub struct PassTiming {
    /// The pass name given to [`Profiler::begin`].
    pub name: String,
    /// GPU milliseconds, `None` when the device has no timestamps.
    pub ms: Option<f64>,
}

/// A started pass, to give back to [`Profiler::end`].
#[derive(Debug)]
#[must_use = "end the pass with Profiler::end"]
pub struct PassScope(usize);

/// Timestamp query pools, `chunk` passes each, made as a round needs them.
///
/// Usage: `begin`/`end` around passes while recording (possibly in several
/// recorders submitted in order), `submit_and_wait`, then [`Profiler::results`].
/// [`Profiler::clear`] starts over. Each pool's reset is recorded before its
/// first timestamp of a round, in the recorder that writes it, so every
/// recorder that `begin` or `end` was given must be submitted.
pub struct Profiler {
    pools: Vec<vk::QueryPool>,
    chunk: u32,
    passes: Vec<(String, Option<u32>)>,
    /// Pools whose reset is recorded this round (the first ones).
    pools_reset: usize,
    valid_mask: u64,
    period_ns: f64,
    supported: bool,
    device: Arc<Device>,
}

/// Most passes of one round: a bound on the pools a runaway loop could make.
const MAX_PASSES: usize = 1 << 16;

impl Profiler {
    /// A profiler that times passes in pools of `chunk` passes (made when a
    /// round first needs them; a round may hold any number of passes).
    pub fn new(ctx: &GpuContext, chunk: u32) -> Result<Self> {
        let device = ctx.device();
        let info = device.info();
        let bits = info.timestamp_valid_bits;
        let mut profiler = Profiler {
            pools: Vec::new(),
            chunk: chunk.max(1),
            passes: Vec::new(),
            pools_reset: 0,
            valid_mask: if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            },
            period_ns: info.timestamp_period_ns as f64,
            supported: bits > 0 && chunk > 0,
            device: Arc::clone(device),
        };
        if profiler.supported {
            profiler.add_pool()?;
        }
        Ok(profiler)
    }

    fn add_pool(&mut self) -> Result<()> {
        let pool_info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(2 * self.chunk);
        let pool = unsafe { self.device.raw().create_query_pool(&pool_info, None) }?;
        self.pools.push(pool);
        Ok(())
    }

    /// The pool and first query of pass `index`.
    fn slot(&self, index: usize) -> (vk::QueryPool, u32) {
        let chunk = self.chunk as usize;
        (self.pools[index / chunk], 2 * (index % chunk) as u32)
    }

    /// Whether timestamps are really measured.
    pub fn supported(&self) -> bool {
        self.supported
    }

    /// Marks the start of pass `name` (after all earlier commands finished).
    pub fn begin(&mut self, rec: &mut CommandRecorder, name: &str) -> Result<PassScope> {
        if self.passes.len() >= MAX_PASSES {
            return Err(Error::InvalidInput(format!(
                "profiler holds at most {MAX_PASSES} passes per round; \"{name}\" is one too many"
            )));
        }
        let index = self.passes.len();
        if self.supported() {
            let pool = index / self.chunk as usize;
            if pool >= self.pools.len() {
                self.add_pool()?;
            }
            let d = self.device.raw();
            if pool >= self.pools_reset {
                unsafe { d.cmd_reset_query_pool(rec.raw(), self.pools[pool], 0, 2 * self.chunk) };
                self.pools_reset = pool + 1;
            }
            let (pool, query) = self.slot(index);
            // BOTTOM_OF_PIPE: written once every earlier command completed, so
            // the pass's time does not include work queued before it.
            unsafe {
                d.cmd_write_timestamp(
                    rec.raw(),
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    pool,
                    query,
                )
            };
        }
        self.passes.push((name.to_string(), None));
        Ok(PassScope(index))
    }

    /// Marks the end of a pass.
    pub fn end(&mut self, rec: &mut CommandRecorder, scope: PassScope) {
        let index = scope.0;
        if self.supported() {
            let (pool, query) = self.slot(index);
            unsafe {
                self.device.raw().cmd_write_timestamp(
                    rec.raw(),
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    pool,
                    query + 1,
                )
            };
        }
        self.passes[index].1 = Some(2 * index as u32 + 1);
    }

    /// The time of every ended pass, in begin order. Call after the
    /// submissions that recorded them were waited for.
    pub fn results(&self) -> Result<Vec<PassTiming>> {
        let ended: Vec<_> = self.passes.iter().filter(|(_, e)| e.is_some()).collect();
        if !self.supported() || self.passes.is_empty() {
            return Ok(ended
                .into_iter()
                .map(|(n, _)| PassTiming {
                    name: n.clone(),
                    ms: None,
                })
                .collect());
        }
        let mut out = Vec::with_capacity(ended.len());
        for (i, (name, end)) in self.passes.iter().enumerate() {
            if end.is_none() {
                // Never written: waiting for it would block forever.
                continue;
            }
            let mut ticks = [0u64; 2];
            let (pool, query) = self.slot(i);
            unsafe {
                self.device.raw().get_query_pool_results(
                    pool,
                    query,
                    &mut ticks,
                    // No WAIT: results asked for before the submission ran
                    // are an error, not a hang.
                    vk::QueryResultFlags::TYPE_64,
                )
            }
            .map_err(|e| {
                Error::Vulkan(if e == vk::Result::NOT_READY {
                    format!("timestamps of \"{name}\" are not ready: submit_and_wait the recording first")
                } else {
                    format!("reading timestamps of \"{name}\": {e:?}")
                })
            })?;
            let delta = (ticks[1] & self.valid_mask).wrapping_sub(ticks[0] & self.valid_mask)
                & self.valid_mask;
            out.push(PassTiming {
                name: name.clone(),
                ms: Some(delta as f64 * self.period_ns * 1e-6),
            });
        }
        Ok(out)
    }

    /// The time of the first ended pass called `name`.
    pub fn pass_ms(&self, name: &str) -> Result<Option<f64>> {
        Ok(self
            .results()?
            .into_iter()
            .find(|t| t.name == name)
            .and_then(|t| t.ms))
    }

    /// Forgets all passes; the next `begin` resets the queries again.
    pub fn clear(&mut self) {
        self.passes.clear();
        self.pools_reset = 0;
    }
}

impl Drop for Profiler {
    fn drop(&mut self) {
        for &pool in &self.pools {
            unsafe { self.device.raw().destroy_query_pool(pool, None) };
        }
    }
}
