//! A frame, top to bottom. The GPU frame ([`Engine::render`], in
//! [`gpu_frame`]) runs the paper's passes in order; the CPU oracle's frame
//! ([`render_reference`], in [`reference`](mod@reference)) is the reference:
//!
//! 1. view samples (what the camera sees);
//! 2. per light: per-light-texel lists of view samples (count, scan, scatter);
//! 3. each caster's influence region, conservatively rasterized (binned);
//! 4. occlusion of every listed view sample by every covering caster (one
//!    bit, or a light-sample bitmask from the plane look-up texture);
//! 5. visibility = visible light samples / light samples, then shading.
//!
//! Steps 2–5 for one light are one function, `record_passes` in
//! [`crate::gpu::light_passes`] (run by
//! [`crate::gpu::light_passes::LightPasses::run`]): read it against the
//! paper's §3 and §4.
//!
//! The public API is [`Engine`] ([`engine`]): frames of a scene, and the
//! visibility of the caller's own view samples. Around it: [`inputs`] (the
//! caller's data in GPU form), [`validate`] (the checks on it) and
//! [`dump_assembly`] (a frame's dump); [`accumulate`] (frames with fresh
//! light samples, averaged); [`record`](mod@record) (the same passes recorded into a
//! renderer's own command buffer, from its G-buffer into its images).

pub mod accumulate;
pub mod dump_assembly;
pub mod engine;
pub mod gpu_frame;
pub mod inputs;
mod progress;
pub mod record;
pub mod reference;
pub mod reuse;
pub mod validate;

pub use accumulate::{frame_lights, frame_seed, Accumulator};
pub use dump_assembly::make_dump;
pub use engine::{Engine, HardShadowResult, SoftShadowResult};
pub(crate) use inputs::user_gpu_inputs;
pub use inputs::{
    gpu_triangles, light_view, soft_light, user_gpu_triangles, INFLUENCE_POLYGON_DEGREE,
};
pub use record::{
    RecordOptions, RecordReport, RecordedFrame, RecordedLight, ViewSampleSource, VisibilityTarget,
};
pub use reference::{render_reference, MAX_REFERENCE_PIXELS};
pub use reuse::{FrameReuse, Generations};
pub use validate::{validate_gpu_inputs, validate_shadow_inputs};

use crate::dump::Dump;
use crate::oracle::ViewSamples;
use crate::stats::Stats;

/// A rendered frame: the dump (view samples, visibility, scene, stats), the
/// shaded image and the statistics.
#[derive(Clone)]
pub struct Frame {
    /// Everything the frame computed, as `--dump DIR` writes it.
    pub dump: Dump,
    /// The shaded image (sRGB, `image.png` of the dump).
    pub image: image::RgbImage,
    /// The view samples the frame used (with triangle ids, which the dump omits).
    pub view: ViewSamples,
    /// The statistics (also `dump.stats`, as JSON).
    pub stats: Stats,
}

/// Options for a frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameOptions {
    /// Show progress bars on standard error (when it is a terminal): the
    /// GPU frame's steps (view samples, each light and its batches,
    /// shading), the reference's rows.
    pub progress: bool,
}
