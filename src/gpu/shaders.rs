//! SPIR-V words of every shader in `shaders/`: one `pub const NAME: &[u32]`
//! per `shaders/name.comp`, e.g. [`SCAN_BLOCK`] for `shaders/scan_block.comp`
//! (GLSL 450, Vulkan 1.2, SPIR-V 1.5).
//!
//! The SPIR-V is committed in `shaders/spirv/` and included as bytes, so a
//! crate that depends on this one compiles no shaders and needs no shader
//! compiler; `build.rs` recompiles it with the `compile-shaders` feature.

#[cfg(target_endian = "big")]
compile_error!("shaders/spirv/*.spv holds little-endian words");

/// Bytes of a SPIR-V file, aligned as the `u32` words they hold.
#[repr(C, align(4))]
struct Aligned<const N: usize>([u8; N]);

/// The words of a SPIR-V file.
const fn words<const N: usize>(bytes: &'static Aligned<N>) -> &'static [u32] {
    assert!(N.is_multiple_of(4));
    // SAFETY: `Aligned` is 4-byte aligned, `N / 4` words fit in its `N`
    // bytes, every bit pattern is a valid `u32`, and the bytes are 'static.
    unsafe { std::slice::from_raw_parts(bytes.0.as_ptr().cast::<u32>(), N / 4) }
}

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

#[cfg(test)]
mod tests {
    #[test]
    fn words_are_spirv() {
        // The SPIR-V magic number, read as a little-endian word.
        assert_eq!(super::SCAN_BLOCK[0], 0x0723_0203);
        assert_eq!(super::VIEW_SAMPLES_FRAG[0], 0x0723_0203);
    }
}
