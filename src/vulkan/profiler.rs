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

/// A timestamp query pool for up to `capacity` passes.
///
/// Usage: `begin`/`end` around passes while recording (possibly in several
/// recorders submitted in order), `submit_and_wait`, then [`Profiler::results`].
/// [`Profiler::clear`] starts over.
pub struct Profiler {
    pool: vk::QueryPool,
    capacity: u32,
    passes: Vec<(String, Option<u32>)>,
    reset_recorded: bool,
    valid_mask: u64,
    period_ns: f64,
    device: Arc<Device>,
}

impl Profiler {
    /// A profiler for at most `capacity` passes per round.
    pub fn new(ctx: &GpuContext, capacity: u32) -> Result<Self> {
        let device = ctx.device();
        let info = device.info();
        let bits = info.timestamp_valid_bits;
        let mut profiler = Profiler {
            pool: vk::QueryPool::null(),
            capacity,
            passes: Vec::new(),
            reset_recorded: false,
            valid_mask: if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            },
            period_ns: info.timestamp_period_ns as f64,
            device: Arc::clone(device),
        };
        if bits > 0 && capacity > 0 {
            let pool_info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::TIMESTAMP)
                .query_count(2 * capacity);
            profiler.pool = unsafe { device.raw().create_query_pool(&pool_info, None) }?;
        }
        Ok(profiler)
    }

    /// Whether timestamps are really measured.
    pub fn supported(&self) -> bool {
        self.pool != vk::QueryPool::null()
    }

    /// Marks the start of pass `name` (after all earlier commands finished).
    pub fn begin(&mut self, rec: &mut CommandRecorder, name: &str) -> Result<PassScope> {
        if self.passes.len() as u32 >= self.capacity {
            return Err(Error::InvalidInput(format!(
                "profiler holds at most {} passes; \"{name}\" is one too many",
                self.capacity
            )));
        }
        let index = self.passes.len();
        if self.supported() {
            let d = self.device.raw();
            if !self.reset_recorded {
                unsafe { d.cmd_reset_query_pool(rec.raw(), self.pool, 0, 2 * self.capacity) };
                self.reset_recorded = true;
            }
            // BOTTOM_OF_PIPE: written once every earlier command completed, so
            // the pass's time does not include work queued before it.
            unsafe {
                d.cmd_write_timestamp(
                    rec.raw(),
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    self.pool,
                    2 * index as u32,
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
            unsafe {
                self.device.raw().cmd_write_timestamp(
                    rec.raw(),
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    self.pool,
                    2 * index as u32 + 1,
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
            unsafe {
                self.device.raw().get_query_pool_results(
                    self.pool,
                    2 * i as u32,
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
        self.reset_recorded = false;
    }
}

impl Drop for Profiler {
    fn drop(&mut self) {
        unsafe { self.device.raw().destroy_query_pool(self.pool, None) };
    }
}
