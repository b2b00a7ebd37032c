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
//!
//! # Example
//!
//! The visibility of your own points: a unit square 1 above the floor,
//! two floor points under it and two far from it, under a point light
//! (hard shadows) and a sphere light of 128 samples (soft shadows). The
//! whole program is `examples/points.rs`.
//!
//! ```
//! use alias_free_shadows::light::{Distribution, Light, LightShape};
//! use alias_free_shadows::oracle::ViewSample;
//! use alias_free_shadows::render::Engine;
//! use alias_free_shadows::scene::file::{LightTexels, ShadowSettings};
//! use alias_free_shadows::scene::{Mesh, Scene};
//! use alias_free_shadows::vulkan::ContextOptions;
//! use glam::DVec3;
//! # fn main() -> alias_free_shadows::Result<()> {
//! let square = [[-0.5, 1.0, -0.5], [0.5, 1.0, -0.5], [0.5, 1.0, 0.5], [-0.5, 1.0, 0.5]];
//! let positions = square.iter().map(|&p| DVec3::from_array(p)).collect();
//! let scene = Scene {
//!     meshes: vec![Mesh::new("square", positions, vec![[0, 1, 2], [0, 2, 3]])],
//!     ..Default::default()
//! };
//! // Floor points (y = 0, normals up): two under the square, two far away.
//! let points: Vec<_> = [[0.0, 0.0], [0.2, -0.2], [-1.5, 1.5], [1.5, 1.5]]
//!     .iter()
//!     .map(|&[x, z]| Some(ViewSample::user(DVec3::new(x, 0.0, z), DVec3::Y)))
//!     .collect();
//! let eye = DVec3::new(0.0, 5.0, 5.0);
//! let mut engine = Engine::new(&ContextOptions::default())?;
//! let light = |shape, samples| Light {
//!     shape, samples, distribution: Distribution::Sobol, seed: 1, color: [1.0; 3], intensity: 1.0,
//!     emission: None,
//!     per_pixel_rotation: false,
//! };
//! let centre = DVec3::new(0.3, 3.0, 0.0);
//!
//! let point = light(LightShape::Point { position: centre }, 1);
//! // The light-texel map: chosen for the points and triangles (or a number).
//! let hard = engine.hard_shadows(&scene, eye, &points, &point, LightTexels::Auto)?;
//! assert_eq!(hard.lit, [Some(false), Some(false), Some(true), Some(true)]);
//!
//! let sphere = light(LightShape::Sphere { position: centre, radius: 0.5 }, 128);
//! let soft = engine.soft_shadows(&scene, eye, &points, &sphere, &ShadowSettings::default())?;
//! assert_eq!(soft.visibility, [Some(0.0), Some(0.0), Some(1.0), Some(1.0)]);
//! # engine.context().check_validation()?;
//! # Ok(()) }
//! ```

#![warn(missing_docs)]

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
