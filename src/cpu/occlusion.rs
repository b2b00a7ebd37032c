//! CPU twin of the conservative rasterization and occlusion passes
//! (`occlusion.comp`): every (caster, face) pair visits
//! every light texel its projection may touch, and every view sample listed
//! there is tested against the caster's planes; a hit sets the sample's
//! shadow bit (paper §3.2–3.3).
//!
//! The GPU bins pairs into tiles of [`TILE`]² texels first
//! ([`crate::cpu::tile_bin`]); this twin visits the same texels directly,
//! which is what makes it a reference for the binning.

use glam::Vec3;

use super::casters::{CasterFace, CasterPlanes};
use super::light_view::LightView;
use super::texel_lists::TexelLists;
use super::tile_bin::texel_touched;
#[cfg(doc)]
use super::tile_bin::TILE;

/// Per-pass counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OcclusionCounts {
    /// Texels visited (caster, texel pairs).
    pub texels_visited: u64,
    /// View-sample–triangle tests.
    pub tests: u64,
}

/// Runs every pair over its texels and returns per-sample shadow bits. A
/// hit of triangle `t` on sample `p` counts only where `opaque(t, p)` (its
/// alpha test where the segment to the light crosses it; always, for
/// opaque triangles).
#[allow(clippy::too_many_arguments)]
pub fn occlusion(
    light: &LightView,
    samples: &[Option<(Vec3, Vec3)>],
    sample_triangles: &[u32],
    lists: &TexelLists,
    planes: &[Option<CasterPlanes>],
    pairs: &[CasterFace],
    resolution: u32,
    opaque: &dyn Fn(u32, Vec3) -> bool,
) -> (Vec<bool>, OcclusionCounts) {
    let r2 = resolution * resolution;
    let origin = light.origin();
    let mut shadowed = vec![false; samples.len()];
    let mut counts = OcclusionCounts::default();
    for cf in pairs {
        let Some(pl) = planes[cf.triangle as usize] else {
            continue;
        };
        for ty in cf.rect[1]..=cf.rect[3] {
            for tx in cf.rect[0]..=cf.rect[2] {
                if !texel_touched(cf, tx, ty) {
                    continue;
                }
                counts.texels_visited += 1;
                let t = (cf.face * r2 + ty * resolution + tx) as usize;
                let start = lists.offsets[t] as usize;
                for &i in &lists.list[start..start + lists.counts[t] as usize] {
                    let i = i as usize;
                    if sample_triangles[i] == cf.triangle {
                        continue;
                    }
                    counts.tests += 1;
                    let (p, _) = samples[i].expect("listed samples exist");
                    if pl.blocks(p, origin) && opaque(cf.triangle, p) {
                        shadowed[i] = true;
                    }
                }
            }
        }
    }
    (shadowed, counts)
}
