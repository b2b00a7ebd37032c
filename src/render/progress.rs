//! A GPU frame's progress on standard error ([`super::FrameOptions::progress`]):
//! one bar over its steps (the view samples, each light, shading), the
//! light's batch in its message when the light runs in several (images
//! past one storage binding). The bar ticks on its own, so its elapsed
//! time moves during a long step; indicatif draws nothing when standard
//! error is not a terminal, and the bar is cleared when the frame ends.

use std::sync::Arc;

use crate::gpu::batches::BatchProgress;

/// The bar of one frame, or nothing.
pub(crate) struct FrameProgress {
    bar: Option<indicatif::ProgressBar>,
    lights: usize,
}

impl FrameProgress {
    /// A bar for a frame of `lights` lights, shown when `show`.
    pub fn new(show: bool, lights: usize) -> Self {
        let bar = show.then(|| {
            let bar = indicatif::ProgressBar::new(lights as u64 + 2);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{msg:>28} [{bar:30}] {pos}/{len} steps, {elapsed}",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
            );
            bar.enable_steady_tick(std::time::Duration::from_millis(250));
            bar.set_message("view samples");
            bar
        });
        FrameProgress { bar, lights }
    }

    /// The previous step is done; light `k` (from 0) starts.
    pub fn light(&self, k: usize) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
            bar.set_message(format!("light {}/{}", k + 1, self.lights));
        }
    }

    /// What light `k`'s batches report: "light k/N, batch b/B".
    pub fn batches(&self, k: usize) -> Option<BatchProgress> {
        let bar = self.bar.clone()?;
        let lights = self.lights;
        Some(Arc::new(move |batch: usize, batches: usize| {
            bar.set_message(format!(
                "light {}/{lights}, batch {}/{batches}",
                k + 1,
                batch + 1
            ));
        }))
    }

    /// The lights are done; shading starts.
    pub fn shading(&self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
            bar.set_message("shading");
        }
    }
}

impl Drop for FrameProgress {
    fn drop(&mut self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
