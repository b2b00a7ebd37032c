//! The whole hard-shadow frame on the CPU, stage by stage, exactly as the
//! GPU runs it (the twins of every pass chained): the reference each GPU
//! stage is compared with, and a test of the algorithm itself against the
//! oracle.

use super::alpha::AlphaTables;
use glam::Vec3;

use super::casters::{setup_casters, CasterCounts};
use super::light_view::{fit_windows, LightView};
use super::occlusion::{occlusion, OcclusionCounts};
use super::texel_lists::{build_texel_lists, TexelLists, NOT_LISTED};

/// Per-sample results and the counters of a CPU hard-shadow frame.
#[derive(Clone, Debug)]
pub struct HardShadows {
    /// Per sample: `None` where there is no sample or it faces away from the
    /// light (unlit without any shadow test), else whether it is lit.
    pub lit: Vec<Option<bool>>,
    /// The per-light-texel lists of view samples the frame built.
    pub lists: TexelLists,
    /// What the caster setup did with each triangle.
    pub casters: CasterCounts,
    /// Texels visited and tests run by the occlusion.
    pub occlusion: OcclusionCounts,
}

/// Runs the twins: fit, lists, caster setup, rasterization and occlusion.
/// `samples` are camera-relative (position, normal) with their triangle
/// ids (`u32::MAX` for none); `triangles` camera-relative with their mesh's
/// closed flag, alpha-tested by `alpha` ([`AlphaTables::new`] of their
/// scene, or empty tables). The GPU's caster setup skips a triangle that
/// is transparent wherever it can be read (`TRIANGLE_INVISIBLE`); this twin
/// sets it up and counts it, and its alpha test then blocks nothing: the
/// shadows agree, the caster counters may not on such scenes.
pub fn hard_shadows(
    light: &LightView,
    samples: &[Option<(Vec3, Vec3)>],
    sample_triangles: &[u32],
    triangles: &[([Vec3; 3], bool)],
    resolution: u32,
    alpha: &AlphaTables,
) -> HardShadows {
    let listed: Vec<(Vec3, Vec3)> = samples.iter().flatten().copied().collect();
    let windows = fit_windows(light, &listed, resolution);
    let lists = build_texel_lists(light, &windows, samples, resolution);
    let (planes, pairs, casters) = setup_casters(light, &windows, triangles, resolution);
    // The segment from a sample towards the light crosses an alpha-tested
    // caster where its alpha test decides (alpha_common.glsl).
    let opaque = |t: u32, p: Vec3| {
        let d = match *light {
            LightView::Point { position } => position - p,
            LightView::Directional { direction } => -direction,
        };
        alpha.segment_opaque(t, triangles[t as usize].0, p, d)
    };
    let (shadowed, occ) = occlusion(
        light,
        samples,
        sample_triangles,
        &lists,
        &planes,
        &pairs,
        resolution,
        &opaque,
    );
    let lit = lists
        .sample_texel
        .iter()
        .zip(&shadowed)
        .map(|(&t, &s)| (t != NOT_LISTED).then_some(!s))
        .collect();
    HardShadows {
        lit,
        lists,
        casters,
        occlusion: occ,
    }
}
