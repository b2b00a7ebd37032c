//! # alias-free-shadows
//!
//! Pixel-exact hard shadows and sample-exact soft shadows computed with
//! alias-free shadow maps on Vulkan compute, after Sintorn, Eisemann and
//! Assarsson, *Sample Based Visibility for Soft Shadows using Alias-free
//! Shadow Maps* (EGSR 2008).
//!
//! The crate is organised as the pipeline is:
//! - [`scene`]: triangles, materials and cameras from glTF files, TOML scene
//!   files and built-in generated scenes;
//! - [`light`]: light shapes and their deterministic light samples;
//! - [`oracle`]: the independent CPU ray-casting reference that every GPU
//!   pass is tested against;
//! - [`vulkan`]: the small Vulkan backend (instance, device, buffers,
//!   pipelines, barriers, profiler);
//! - [`gpu`] and [`cpu`]: each compute pass and its CPU twin;
//! - [`render`]: a frame top to bottom and the public [`render::Engine`];
//! - [`stats`]: a frame's statistics, typed;
//! - [`dump`]: the on-disk result format shared by the GPU path and the oracle.

pub mod baselines;
pub mod bench;
pub mod cpu;
pub mod dump;
pub mod error;
pub mod gpu;
pub mod light;
pub mod oracle;
pub mod render;
pub mod scene;
pub mod shade;
pub mod stats;
pub mod vulkan;

pub use error::{Error, Result};

/// The `ash` this crate is built with, for [`vulkan::ExternalDevice`].
pub use ash;
/// The `gpu-allocator` this crate is built with, for a shared allocator in
/// [`vulkan::ExternalDevice`].
pub use gpu_allocator;
