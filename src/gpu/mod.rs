//! The GPU passes, each with a CPU twin in [`crate::cpu`], and what they
//! share with the shaders.
//!
//! - [`shaders`]: SPIR-V of every `shaders/*.comp`, compiled by `build.rs`;
//! - [`shared`]: Rust twins of the structs in `shaders/common.glsl`;
//! - [`scan`]: exclusive prefix scan of `u32` arrays;
//! - [`hard_shadows`]: the alias-free hard-shadow passes.

pub mod hard_shadows;
pub mod scan;
pub mod shaders;
pub mod shared;
pub mod view_samples;
