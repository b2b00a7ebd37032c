//! The time of each pass of a light's run: GPU timestamps where they
//! bracket the passes, else wall clock on the host with every pass its own
//! submission. Lavapipe's timestamps do not bracket the passes of one
//! command buffer (measured: 11 ms reported for a 1.4 s run), so on a CPU
//! device passes are timed on the host; `AFS_PROFILE_WALL=1` / `0` forces
//! either way.

use crate::vulkan::{CommandRecorder, GpuContext, PassTiming, Profiler};
use crate::Result;

/// Timed passes per query pool (a run with more makes another pool): the
/// LUT build, a dozen passes and one occlusion pass per 128-sample block in
/// exact mode, or per list segment in look-up mode.
const POOL_PASSES: u32 = 128;

/// Times the passes of one run; made once, restarted per run.
pub struct PassClock {
    profiler: Profiler,
    /// Wall-clock mode: the passes timed so far.
    walls: Option<Vec<PassTiming>>,
    /// Timestamp mode: the passes done on the host, timed there.
    host: Vec<PassTiming>,
}

impl PassClock {
    /// A clock with its timestamp pool (made once).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(PassClock {
            profiler: Profiler::new(ctx, POOL_PASSES)?,
            walls: None,
            host: Vec::new(),
        })
    }

    /// Forgets the last run's passes.
    pub fn restart(&mut self, ctx: &GpuContext) {
        self.profiler.clear();
        self.host.clear();
        self.walls = walls_wanted(ctx).then(Vec::new);
    }

    /// Records `f` as pass `name`. In wall-clock mode the recording so far
    /// is submitted, `f`'s commands are submitted on their own and timed, and
    /// `rec` is a fresh recorder afterwards.
    pub fn time(
        &mut self,
        ctx: &GpuContext,
        rec: &mut CommandRecorder,
        name: &str,
        f: impl FnOnce(&mut CommandRecorder) -> Result<()>,
    ) -> Result<()> {
        match &mut self.walls {
            Some(list) => {
                let t = std::time::Instant::now();
                f(rec)?;
                let done = std::mem::replace(rec, ctx.begin()?);
                ctx.submit_and_wait(done)?;
                list.push(PassTiming {
                    name: name.to_string(),
                    ms: Some(t.elapsed().as_secs_f64() * 1e3),
                });
                Ok(())
            }
            None => {
                let scope = self.profiler.begin(rec, name)?;
                f(rec)?;
                self.profiler.end(rec, scope);
                Ok(())
            }
        }
    }

    /// Times `f`, work done on the host (reading or building a table), as
    /// pass `name` with the wall clock in either mode: it records no GPU
    /// commands, so timestamps would bracket nothing.
    pub fn time_host<T>(&mut self, name: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let t = std::time::Instant::now();
        let out = f()?;
        let timing = PassTiming {
            name: name.to_string(),
            ms: Some(t.elapsed().as_secs_f64() * 1e3),
        };
        self.walls.as_mut().unwrap_or(&mut self.host).push(timing);
        Ok(out)
    }

    /// The passes of this run so far (after their submissions were waited
    /// for): in order with the wall clock; with timestamps, the passes done
    /// on the host first, then the GPU's in order.
    pub fn results(&self) -> Result<Vec<PassTiming>> {
        match &self.walls {
            Some(w) => Ok(w.clone()),
            None => {
                let mut all = self.host.clone();
                all.extend(self.profiler.results()?);
                Ok(all)
            }
        }
    }
}

/// Whether passes are timed on the host (see the module documentation).
fn walls_wanted(ctx: &GpuContext) -> bool {
    match std::env::var("AFS_PROFILE_WALL").as_deref() {
        Ok("1") => true,
        Ok("0") => false,
        _ => ctx.info().is_cpu(),
    }
}
