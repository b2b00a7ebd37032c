//! What the compute passes of a light's run share: workgroup counts, the
//! texel format of the hot gathers, a binding shorthand and the subgroup
//! operations the occlusion passes need.

use crate::vulkan::{vk, Binding, BufferSlice, GpuContext};
use crate::{Error, Result};

/// Workgroup size of the 1D passes (`WORKGROUP_1D` in `shadow_common.glsl`).
pub const WG: u32 = 64;

/// Texel format the hot gathers read (floats travel as bits): on lavapipe a
/// texel-buffer fetch is ~10× faster than a storage-buffer load.
pub const RGBA32UI: vk::Format = vk::Format::R32G32B32A32_UINT;

/// The same for one `u32` per texel.
pub const R32UI: vk::Format = vk::Format::R32_UINT;

/// Workgroups of [`WG`] invocations for `n` items, spread over y past the
/// 65535 a dimension may hold.
pub fn groups(n: u32) -> [u32; 3] {
    groups_2d(n.div_ceil(WG))
}

/// `g` workgroups, spread over y past the 65535 a dimension may hold.
pub fn groups_2d(g: u32) -> [u32; 3] {
    if g <= 65535 {
        [g, 1, 1]
    } else {
        [65535, g.div_ceil(65535), 1]
    }
}

/// Workgroup `w` of a dispatch of `n` as the passes whose work is uneven
/// along the index number it on a device that splits a dispatch into
/// `runs` contiguous runs, one per thread
/// ([`DeviceInfo::dispatch_runs`](crate::vulkan::DeviceInfo::dispatch_runs)):
/// run `t` takes `t, t + runs, t + 2 runs, ...`, so that every thread walks
/// the whole range. A bijection on `0..n`. Twin of `spread_index` in
/// `shaders/shadow_common.glsl`.
pub fn spread_index(w: u32, n: u32, runs: u32) -> u32 {
    let run = (n / runs).max(1);
    if w < run * runs {
        (w % run) * runs + w / run
    } else {
        w
    }
}

/// A storage-buffer binding.
pub fn storage<'a>(b: impl Into<BufferSlice<'a>>) -> Binding<'a> {
    Binding::storage(b)
}

/// The subgroup operations of the occlusion passes: ballot, shuffle (each
/// lane fetches one pair of a window and the others take it from that
/// lane, since every lane tests the same pairs) and arithmetic (the
/// counters' sums, soft occlusion's in-place budget and list offsets).
pub fn require_occlusion_subgroup_ops(ctx: &GpuContext, pass: &str) -> Result<()> {
    let ops = vk::SubgroupFeatureFlags::BASIC
        | vk::SubgroupFeatureFlags::ARITHMETIC
        | vk::SubgroupFeatureFlags::BALLOT
        | vk::SubgroupFeatureFlags::SHUFFLE;
    let info = ctx.info();
    if info.supports_subgroup(ops) {
        Ok(())
    } else {
        Err(Error::Vulkan(format!(
            "{pass} needs subgroup arithmetic, ballot and shuffle in compute shaders, which \"{}\" lacks",
            info.name
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::spread_index;

    /// A bijection on `0..n` for every run count, and run `t` of the
    /// device's split (`n / runs` consecutive workgroups each) takes every
    /// `runs`-th index from `t`.
    #[test]
    fn spread_index_is_a_bijection_that_interleaves_runs() {
        for runs in 1..=9u32 {
            for n in (0..300u32).chain([4096, 4097, 65_535, 70_001]) {
                let mut seen = vec![false; n as usize];
                for w in 0..n {
                    let b = spread_index(w, n, runs);
                    assert!(
                        b < n && !seen[b as usize],
                        "runs {runs}, n {n}, w {w} -> {b}"
                    );
                    seen[b as usize] = true;
                }
                let run = n / runs;
                for t in 0..runs.min(n) {
                    for j in 0..run {
                        assert_eq!(spread_index(t * run + j, n, runs), j * runs + t);
                    }
                }
            }
        }
    }
}
