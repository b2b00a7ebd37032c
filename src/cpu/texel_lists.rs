//! CPU twin of the per-light-texel lists (`texel_count.comp`, the scan,
//! `texel_scatter.comp`): every view sample that faces the light is
//! projected to a light texel; an atomic counter per texel counts them and
//! hands each sample its index in the texel's list; an exclusive scan of the
//! counts gives each list's offset; the scatter writes every sample into
//! one compact array (paper §3.1).

use glam::Vec3;

use super::light_view::{texel_of, FaceWindow, LightView};
use super::tile_bin::TILE;

/// Sentinel texel of a sample that is not in any list.
pub const NOT_LISTED: u32 = u32::MAX;

/// The lists: `offsets[t]..offsets[t] + counts[t]` of `list` are texel t's samples.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TexelLists {
    /// Per sample: its texel (face·R² + row·R + column), or [`NOT_LISTED`].
    pub sample_texel: Vec<u32>,
    /// Per texel: number of samples.
    pub counts: Vec<u32>,
    /// Per texel: exclusive prefix sum of `counts`.
    pub offsets: Vec<u32>,
    /// Sample indices grouped by texel.
    pub list: Vec<u32>,
}

/// Builds the lists. The order inside one texel's list depends on the
/// order atomics are served in; this twin lists samples by index, so a GPU
/// comparison sorts each list first.
pub fn build_texel_lists(
    light: &LightView,
    windows: &[FaceWindow],
    samples: &[Option<(Vec3, Vec3)>],
    resolution: u32,
) -> TexelLists {
    let r2 = (resolution as usize) * (resolution as usize);
    let mut counts = vec![0u32; r2 * windows.len()];
    let mut sample_texel = Vec::with_capacity(samples.len());
    for s in samples {
        let t = s
            .filter(|&(p, n)| light.faces(p, n))
            .and_then(|(p, _)| light.project(p))
            .map(|(f, x, y, _)| {
                let (tx, ty) = texel_of(&windows[f], x, y, resolution);
                (f * r2) as u32 + ty * resolution + tx
            })
            .unwrap_or(NOT_LISTED);
        if t != NOT_LISTED {
            counts[t as usize] += 1;
        }
        sample_texel.push(t);
    }
    let (offsets, total) = super::scan::exclusive_scan(&counts);
    let mut cursor = offsets.clone();
    let mut list = vec![0u32; total as usize];
    for (i, &t) in sample_texel.iter().enumerate() {
        if t != NOT_LISTED {
            list[cursor[t as usize] as usize] = i as u32;
            cursor[t as usize] += 1;
        }
    }
    TexelLists {
        sample_texel,
        counts,
        offsets,
        list,
    }
}

/// Which tiles of [`TILE`]² texels hold a listed sample, as the GPU's count
/// pass marks them after the per-tile longest list lengths
/// (`occupancy_word` in `shadow_common.glsl`): per face and row of tiles,
/// `tiles_per_row / 32` words (rounded up), bit `tx % 32` of word `tx / 32`
/// set for an occupied tile. `counts` are [`TexelLists::counts`].
pub fn tile_occupancy(counts: &[u32], resolution: u32, faces: u32) -> Vec<u32> {
    let tiles_per_row = resolution.div_ceil(TILE);
    let words_per_row = tiles_per_row.div_ceil(32);
    let mut words = vec![0u32; (faces * tiles_per_row * words_per_row) as usize];
    let r2 = resolution as usize * resolution as usize;
    for (t, _) in counts.iter().enumerate().filter(|&(_, &c)| c != 0) {
        let (f, rest) = ((t / r2) as u32, (t % r2) as u32);
        let (tx, ty) = ((rest % resolution) / TILE, (rest / resolution) / TILE);
        words[((f * tiles_per_row + ty) * words_per_row + tx / 32) as usize] |= 1 << (tx % 32);
    }
    words
}
