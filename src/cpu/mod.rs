//! CPU twins of the GPU passes in [`crate::gpu`], one module per pass of the
//! same name: straightforward versions the GPU results are compared with.
//!
//! - [`alpha`]: alpha-tested casters' coverage and its tables;
//! - [`light_view`]: the light's frusta fitted to the view samples;
//! - [`texel_lists`]: the per-light-texel lists (count, [`scan`], scatter);
//! - [`clusters`]: each tile's view-sample box and the rules that drop a
//!   caster for it;
//! - [`casters`]: caster planes and conservative projections;
//! - [`tile_bin`]: the pairs binned per tile;
//! - [`pair_groups`]: per binned pair, the groups of its tile's samples it
//!   may shadow;
//! - [`occlusion`]: hard-shadow occlusion over the touched texels;
//! - [`plane_lut`]: the plane look-up texture;
//! - [`soft_occlusion`]: the light samples a caster hides from a view sample;
//! - [`resolve`]: visibility per view sample;
//! - [`hard_shadows`]: the hard-shadow twins chained into a whole frame.

pub mod alpha;
pub mod casters;
pub mod clusters;
pub mod hard_shadows;
pub mod light_view;
pub mod occlusion;
pub mod pair_groups;
pub mod plane_lut;
pub mod resolve;
pub mod scan;
pub mod soft_occlusion;
pub mod texel_lists;
pub mod tile_bin;
pub mod visibility_out;
