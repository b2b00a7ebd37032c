//! SPIR-V words of every compute shader in `shaders/`, compiled at build time
//! by `build.rs` (GLSL 450, Vulkan 1.2, SPIR-V 1.5): one `pub const NAME:
//! &[u32]` per `shaders/name.comp`, e.g. [`SCAN_BLOCK`] for
//! `shaders/scan_block.comp`.

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
