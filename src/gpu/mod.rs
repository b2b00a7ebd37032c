//! The GPU passes, each with a CPU twin of the same name in [`crate::cpu`]
//! and a shader family of the same name in `shaders/`.
//!
//! A frame: [`view_samples`] (what the camera sees), then per light the
//! [`shadow_pipeline`], whose [`light_passes::LightPasses::run`] lists the
//! passes in the paper's order:
//!
//! - [`light_view`]: the light's frusta fitted to the view samples (§4.3);
//! - [`texel_lists`]: per-light-texel lists of view samples: count, [`scan`],
//!   scatter (§3.1);
//! - [`clusters`]: each tile's view samples as one box, against which tile
//!   binning drops the casters that cannot shadow it (Sintorn et al. 2014);
//! - [`casters`]: each caster's planes and its projection or influence
//!   region (§3.3, §4.1);
//! - [`tile_bin`]: the conservative rasterization of those over tiles of
//!   light texels, and the occlusion work units (§3.2);
//! - [`pair_groups`]: per binned pair, the groups of its tile's samples it
//!   may shadow (soft shadows: a chunk skips the pairs its groups dropped);
//! - [`plane_lut`]: the plane look-up texture of a light with extent (§4.2);
//! - [`occlusion`] (one bit) and [`soft_occlusion`] (light-sample bitmasks):
//!   every listed view sample against its tile's casters (§3.3, §4.2);
//! - [`resolve`]: visibility per view sample.
//!
//! Around them: [`light_frame`] (a run's inputs, sizes and push constants),
//! [`batches`] (runs too large for one binding), [`pass_clock`] (time per
//! pass), [`dispatch`] (workgroup counts), [`soft_light`] (a light with
//! extent as the passes see it), [`shaders`] (SPIR-V of every shader,
//! compiled by `build.rs`) and [`shared`] (Rust twins of the shaders'
//! structs).

pub mod alpha;
pub mod batches;
pub mod casters;
pub mod clusters;
pub mod dispatch;
pub mod light_frame;
pub mod light_passes;
pub mod light_view;
pub mod occlusion;
pub mod pair_groups;
pub mod pass_clock;
pub mod plane_lut;
pub mod resolve;
pub mod scan;
pub mod shaders;
pub mod shadow_pipeline;
pub mod shared;
pub mod soft_light;
pub mod soft_occlusion;
pub mod texel_lists;
pub mod tile_bin;
pub mod view_samples;
pub mod visibility_out;

pub use light_passes::{ShadowOutput, SoftOutput};
pub use shadow_pipeline::{gpu_inputs, ShadowPipeline};
pub use soft_light::{SoftLight, MAX_SOFT_SAMPLES};
