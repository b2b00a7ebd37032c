//! Statistics of a frame, typed: what `--stats` prints and `stats.json`
//! holds. The shadow passes' counters and times of one light
//! ([`ShadowStats`], from [`ShadowOutput`]), a GPU frame ([`FrameStats`])
//! and an oracle frame ([`ReferenceStats`]).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::gpu::shared::counter;
use crate::gpu::{ShadowOutput, SoftLight};
use crate::scene::file::ShadowSettings;
use crate::vulkan::Allocations;

/// The shadow passes of one light: list, caster and occlusion counters,
/// milliseconds per pass, buffers used and created.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ShadowStats {
    /// Light-texel map resolution per face.
    pub light_texels: u32,
    /// Light faces (6 for a point light, 1 for a directional light).
    pub light_faces: usize,
    /// View samples in some light-texel list.
    pub listed_view_samples: u64,
    /// Light texels (over all faces) with a non-empty list.
    pub occupied_texels: usize,
    /// `occupied_texels` as a percentage of all `light_faces` ×
    /// `light_texels`² texels.
    pub occupied_texels_percent: f64,
    /// Mean list length over the occupied texels.
    pub average_list_length: f64,
    /// Length of the longest light-texel list (view samples).
    pub max_list_length: u32,
    /// Triangles the caster setup saw: `triangles_culled` plus
    /// `triangles_rasterized`.
    pub triangles_submitted: u64,
    /// Triangles dropped before rasterization: the sum of the degenerate,
    /// front-facing closed and outside-frustum counts.
    pub triangles_culled: u64,
    /// Triangles with a zero or non-finite normal or a plane through the
    /// light, dropped by `casters_setup.comp` (`COUNTER_DEGENERATE`).
    pub triangles_degenerate: u32,
    /// Triangles of closed meshes that face the light (paper §3.3), dropped
    /// because the mesh's back faces shadow the same samples
    /// (`COUNTER_FRONT_FACING_CLOSED`).
    pub triangles_front_facing_closed: u32,
    /// Triangles that overlap no light face's frustum (`COUNTER_CULLED`).
    pub triangles_outside_frustum: u32,
    /// Triangles that produced at least one (caster, face) pair
    /// (`COUNTER_RASTERIZED`).
    pub triangles_rasterized: u32,
    /// (Caster, light face) pairs rasterized.
    pub caster_face_pairs: u32,
    /// (Caster, texel) pairs the occlusion visited.
    pub texels_visited: u32,
    /// View-sample–triangle tests.
    pub view_sample_triangle_tests: u32,
    /// (Pair, tile) bins that view-sample clusters dropped
    /// ([`crate::gpu::clusters`]): every sample of the tile's box on the
    /// light's side of the caster's plane.
    pub bins_dropped_light_side: u32,
    /// The same, every sample behind a closed caster (soft shadows).
    pub bins_dropped_behind_closed: u32,
    /// The same, the caster beyond the reach of every sample of the tile
    /// (soft shadows; `COUNTER_BIN_BEYOND_REACH`).
    #[serde(default)]
    pub bins_dropped_beyond_reach: u32,
    /// The same, the caster's ball outside the hull of a ball holding the
    /// tile's samples and the light's sphere (soft shadows;
    /// `COUNTER_BIN_OUTSIDE_HULL`).
    #[serde(default)]
    pub bins_dropped_outside_hull: u32,
    /// Soft occlusion: (pair, chunk of 64 samples) visits that the chunk's
    /// own box (the same rules) or texels ruled out before the loop.
    pub chunk_pairs_dropped: u32,
    /// Of those, the visits whose chunk's box lies outside the caster's
    /// penumbra volume (one edge's plane through any sample of the box
    /// leaves the whole light outside the caster's cone).
    pub chunk_pairs_outside_penumbra: u32,
    /// Soft occlusion: of [`Self::chunk_pairs_dropped`], the visits that
    /// the reach rule dropped: every point of the caster farther from the
    /// light's centre than the chunk's samples and the light's radius
    /// (`COUNTER_CLUSTER_BEYOND_REACH`).
    #[serde(default)]
    pub chunk_pairs_beyond_reach: u32,
    /// Soft occlusion: of [`Self::chunk_pairs_dropped`], the visits that
    /// the boxes of the groups of 512 samples the chunk lies in ruled out
    /// (by the chunk's rules, once per group instead of once per chunk)
    /// before the chunk's own tests (`COUNTER_CLUSTER_GROUPS`).
    #[serde(default)]
    pub chunk_pairs_group_dropped: u32,
    /// Bytes of GPU buffers the passes used.
    pub gpu_buffer_bytes: u64,
    /// Buffers and images the passes created (0 once warm).
    pub allocations: Allocations,
    /// Milliseconds per pass (passes run once per 128-sample block summed).
    pub ms: BTreeMap<String, Option<f64>>,
    /// Their sum.
    pub gpu_ms: f64,
    /// Host wall time of the light's whole run.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub wall_ms: Option<f64>,
    /// Lights with extent only.
    #[serde(flatten, skip_serializing_if = "Option::is_none", default)]
    pub soft: Option<SoftStats>,
}

/// What the soft-shadow passes add.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SoftStats {
    /// Light samples of the light (1 to
    /// [`MAX_SOFT_SAMPLES`](crate::gpu::soft_light::MAX_SOFT_SAMPLES)).
    pub light_samples: usize,
    /// The evaluation mode's name ([`SoftMode::name`](crate::scene::file::SoftMode::name):
    /// `lut`, `exact` or `approx`).
    pub mode: String,
    /// Plane look-up texture resolution (`lut_resolution`³ texels per
    /// 128-sample block); unused in `exact` mode.
    pub lut_resolution: u32,
    /// View-sample–triangle tests that blocked at least one light sample
    /// (`COUNTER_BLOCKING`).
    pub blocking_tests: u32,
    /// `blocking_tests` as a fraction (0 to 1) of all
    /// view-sample–triangle tests.
    pub blocking_share: f64,
    /// Tests that the caster's own plane rejected: the light's whole
    /// bounding sphere on the sample's side of it (`COUNTER_PLANE_REJECTED`).
    #[serde(default)]
    pub plane_rejected_tests: u32,
    /// Tests that a plane through the sample and one of the caster's edges
    /// rejected: the light's whole bounding sphere outside the caster's
    /// cone from the sample.
    #[serde(default)]
    pub edge_rejected_tests: u32,
    /// Tests past those bounding-sphere tests that the wedge rule
    /// rejected: two of the edges' planes together leave the light's
    /// sphere outside, where neither does alone (exact mode only;
    /// `COUNTER_WEDGE_REJECTED`).
    #[serde(default)]
    pub wedge_rejected_tests: u32,
    /// Tests past those bounding-sphere tests and the wedge rule, which
    /// went on to the look-ups (or, in exact mode, to every light sample);
    /// with the three above they make up all the view-sample–triangle
    /// tests (`COUNTER_PAST_SPHERE`).
    #[serde(default)]
    pub past_sphere_tests: u32,
    /// (View sample, work unit) visits of the occlusion passes: a sample
    /// whose texel's pairs span several units is visited once per unit
    /// (and once per block pass in exact mode). Unlike the tests, the same
    /// in every run of a frame: it does not depend on the order in which
    /// atomics filled the lists (`COUNTER_SAMPLE_VISITS`).
    #[serde(default)]
    pub sample_unit_visits: u32,
    /// (View sample, triangle) visits that the reach rule culled before the
    /// test (not counted as tests): every point of the caster farther from
    /// the light's centre than the sample and the light's radius, so that
    /// no segment from the sample to the light meets it; a caster beyond
    /// the reach of a whole subgroup's samples counts once per sample
    /// (`COUNTER_BEYOND_REACH`).
    #[serde(default)]
    pub beyond_reach_pairs: u32,
    /// (View sample, triangle) visits that the hull rule culled before the
    /// test (not counted as tests): a ball holding the caster lies outside
    /// the convex hull of the sample and the light's bounding sphere, which
    /// holds every segment between them; a caster outside the hull of a
    /// whole subgroup's samples counts once per sample
    /// (`COUNTER_OUTSIDE_HULL`).
    #[serde(default)]
    pub outside_hull_pairs: u32,
    /// Whether this run built the plane look-up texture (it is built once
    /// per light shape and reused: its time, `ms.lut_build`, appears only
    /// in the frame that built it).
    pub lut_built: bool,
    /// Look-up mode: (test, light sample) bits the table left unsure, which
    /// the exact per-sample test decided, and their share of all the tests'
    /// bits (tests × light samples).
    pub unsure_bits: u64,
    /// `unsure_bits` as a fraction (0 to 1) of tests × light samples.
    pub unsure_share: f64,
    /// Look-up mode: entries of the unsure list (a test's unsure bits in
    /// one 128-sample block: one exact-test invocation each).
    #[serde(default)]
    pub unsure_entries: u64,
    /// Look-up mode: ranges of work units the occlusion ran in, each
    /// followed by the exact tests of its entries (planned to list about
    /// 2^17 entries in each of the list's four segments: small lists run
    /// faster; fewer when the list's buffer is smaller).
    #[serde(default)]
    pub unsure_ranges: u32,
    /// Exact mode: (test, group of 16 light samples) pairs whose samples
    /// were tested one by one. A test past the bounding-sphere tests first
    /// tests its four planes against a sphere around each group; the
    /// groups neither counted here nor in `light_groups_every` lay wholly
    /// outside one of the planes and needed no per-sample test.
    #[serde(default)]
    pub light_groups_tested: u64,
    /// Exact mode: (test, group) pairs whose group lay wholly inside all
    /// four planes: every sample blocked without a per-sample test.
    #[serde(default)]
    pub light_groups_every: u64,
}

impl ShadowStats {
    /// The statistics of one light's run over `resolution`² texels per
    /// face; `soft` for a light with extent.
    pub fn new(
        out: &ShadowOutput,
        resolution: u32,
        faces: usize,
        soft: Option<&SoftLight>,
    ) -> Self {
        let occupied = out.list_lengths.iter().filter(|&&c| c > 0).count();
        let listed: u64 = out.list_lengths.iter().map(|&c| c as u64).sum();
        let c = &out.counters;
        let culled = c[counter::DEGENERATE] as u64
            + c[counter::FRONT_FACING_CLOSED] as u64
            + c[counter::CULLED] as u64;
        let mut ms = BTreeMap::new();
        for t in &out.timings {
            let prev: Option<f64> = ms.get(&t.name).copied().flatten();
            let v = match (prev, t.ms) {
                (Some(a), Some(b)) => Some(a + b),
                (None, b) => b,
                (a, None) => a,
            };
            ms.insert(t.name.clone(), v);
        }
        let texels = (faces as f64 * (resolution as f64).powi(2)).max(1.0);
        let unsure = counter::wide(c, counter::UNSURE_LO);
        ShadowStats {
            light_texels: resolution,
            light_faces: faces,
            listed_view_samples: listed,
            occupied_texels: occupied,
            occupied_texels_percent: 100.0 * occupied as f64 / texels,
            average_list_length: listed as f64 / occupied.max(1) as f64,
            max_list_length: out.list_lengths.iter().copied().max().unwrap_or(0),
            triangles_submitted: culled + c[counter::RASTERIZED] as u64,
            triangles_culled: culled,
            triangles_degenerate: c[counter::DEGENERATE],
            triangles_front_facing_closed: c[counter::FRONT_FACING_CLOSED],
            triangles_outside_frustum: c[counter::CULLED],
            triangles_rasterized: c[counter::RASTERIZED],
            caster_face_pairs: c[counter::PAIRS],
            texels_visited: c[counter::TEXELS_VISITED],
            view_sample_triangle_tests: c[counter::TESTS],
            bins_dropped_light_side: c[counter::CLUSTER_LIGHT_SIDE],
            bins_dropped_behind_closed: c[counter::CLUSTER_BEHIND_CLOSED],
            bins_dropped_beyond_reach: c[counter::BIN_BEYOND_REACH],
            bins_dropped_outside_hull: c[counter::BIN_OUTSIDE_HULL],
            chunk_pairs_dropped: c[counter::CLUSTER_CHUNK],
            chunk_pairs_outside_penumbra: c[counter::CLUSTER_OUTSIDE_PENUMBRA],
            chunk_pairs_beyond_reach: c[counter::CLUSTER_BEYOND_REACH],
            chunk_pairs_group_dropped: c[counter::CLUSTER_GROUPS],
            gpu_buffer_bytes: out.buffer_bytes,
            allocations: out.allocations,
            ms,
            gpu_ms: out.timings.iter().filter_map(|t| t.ms).sum(),
            wall_ms: None,
            soft: soft.map(|sl| SoftStats {
                light_samples: sl.samples.len(),
                mode: sl.mode.name().into(),
                lut_resolution: sl.lut_resolution,
                blocking_tests: c[counter::BLOCKING],
                blocking_share: c[counter::BLOCKING] as f64 / c[counter::TESTS].max(1) as f64,
                plane_rejected_tests: c[counter::PLANE_REJECTED],
                edge_rejected_tests: c[counter::TESTS]
                    .saturating_sub(c[counter::PLANE_REJECTED])
                    .saturating_sub(c[counter::PAST_SPHERE])
                    .saturating_sub(c[counter::WEDGE_REJECTED]),
                wedge_rejected_tests: c[counter::WEDGE_REJECTED],
                past_sphere_tests: c[counter::PAST_SPHERE],
                sample_unit_visits: c[counter::SAMPLE_VISITS],
                beyond_reach_pairs: c[counter::BEYOND_REACH],
                outside_hull_pairs: c[counter::OUTSIDE_HULL],
                lut_built: out.soft.as_ref().is_some_and(|s| s.lut_built),
                unsure_bits: unsure,
                unsure_share: unsure as f64
                    / (c[counter::TESTS] as f64 * sl.samples.len() as f64).max(1.0),
                unsure_entries: out.soft.as_ref().map_or(0, |s| s.unsure_entries),
                unsure_ranges: out.soft.as_ref().map_or(0, |s| s.unsure_ranges),
                light_groups_tested: counter::wide(c, counter::GROUPS_TESTED_LO),
                light_groups_every: counter::wide(c, counter::GROUPS_EVERY_LO),
            }),
        }
    }
}

/// A GPU frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameStats {
    /// The Vulkan device.
    pub device: String,
    /// The scene's report name ([`SceneDescription::name`](crate::scene::file::SceneDescription::name)).
    pub scene: String,
    /// The engine settings the frame ran with.
    pub settings: ShadowSettings,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Milliseconds of the steps outside the lights' shadow passes.
    pub ms: FrameMs,
    /// Per light, in scene order.
    pub lights: Vec<LightStats>,
    /// Host wall time of the whole frame.
    pub total_ms: f64,
    /// Triangles and view samples of the frame.
    pub counters: FrameCounters,
    /// Buffers and images the whole frame created (0 for a second frame of
    /// the same size: every resource lives across frames).
    pub allocations: Allocations,
    /// What the frame took from the one before
    /// ([`crate::render::Engine::render_reusing`]); absent for a frame
    /// that reused nothing by design ([`crate::render::Engine::render`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reused: Option<Reused>,
}

/// What a frame of [`crate::render::Engine::render_reusing`] took from the
/// frame before instead of computing it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Reused {
    /// Nothing changed: the whole frame is the last one's (no GPU work).
    pub frame: bool,
    /// The view samples and triangles (geometry, camera and settings
    /// unchanged): no rasterization, no upload.
    pub view_samples: bool,
    /// Per light: its visibility (the light and the view unchanged), in
    /// which case its `lights` entry is the earlier frame's.
    pub lights: Vec<bool>,
}

/// Milliseconds of a frame's steps outside the lights' passes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameMs {
    /// GPU time of the view-sample pass (rasterization and resolve), from
    /// timestamp queries; NaN where the device has none.
    pub view_samples_gpu: f64,
    /// Host time of the frame's inputs: the triangles in GPU form, the
    /// alpha tables, their uploads, and the view samples read back and
    /// converted (the view-sample pass's own submission excluded); 0 where
    /// a frame reused its view.
    #[serde(default)]
    pub inputs_cpu: f64,
    /// Host time of shading the image on the CPU ([`crate::shade`]).
    pub shade_cpu: f64,
}

/// One light of a GPU frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LightStats {
    /// The light's index in the scene.
    pub light: usize,
    /// `gpu hard shadows` or `gpu soft shadows`.
    pub path: String,
    /// The counters and pass times of the light's shadow passes.
    pub stats: ShadowStats,
}

/// A frame's scene counters.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameCounters {
    /// Triangles uploaded to the GPU (every triangle of the scene).
    pub triangles: usize,
    /// Pixels with a valid view sample (the rest see no geometry).
    pub view_samples: usize,
    /// Triangles the view samples' raster drew: those whose image may
    /// contain a pixel centre (`gpu::view_samples`).
    #[serde(default)]
    pub view_triangles_drawn: usize,
}

/// A frame of the CPU oracle.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceStats {
    /// Always `cpu oracle (ray casting)`.
    pub device: String,
    /// The scene's report name ([`SceneDescription::name`](crate::scene::file::SceneDescription::name)).
    pub scene: String,
    /// The engine settings of the scene (the oracle itself uses none).
    pub settings: ShadowSettings,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Milliseconds per step of the frame.
    pub ms: ReferenceMs,
    /// Host wall time of the whole frame.
    pub total_ms: f64,
    /// Triangles, samples and rays of the frame.
    pub counters: ReferenceCounters,
}

/// Milliseconds of an oracle frame's steps.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceMs {
    /// Building the oracle's BVH over the scene's triangles.
    pub bvh: f64,
    /// Casting the primary rays that give the view samples.
    pub view_samples: f64,
    /// Casting the shadow rays, one entry per light in scene order.
    pub shadow_rays_per_light: Vec<f64>,
    /// Shading the image ([`crate::shade`]).
    pub shade: f64,
}

/// An oracle frame's counters.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceCounters {
    /// Triangles of the scene (the oracle's input).
    pub triangles: usize,
    /// Pixels whose primary ray hit a triangle.
    pub view_samples: usize,
    /// Light samples per light, in scene order (1 for a point or
    /// directional light).
    pub light_samples: Vec<usize>,
    /// Shadow rays cast over all lights.
    pub shadow_rays: u64,
    /// `shadow_rays` over the summed shadow-ray time (0 when that is 0).
    pub shadow_rays_per_second: f64,
    /// Rayon worker threads the oracle ran on.
    pub threads: usize,
}

/// The statistics of a frame, GPU or oracle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Stats {
    /// A frame of the GPU path ([`crate::render::Engine::render`]).
    Gpu(FrameStats),
    /// A frame of the CPU oracle ([`crate::render::render_reference`]).
    Reference(ReferenceStats),
}

impl Stats {
    /// Host wall time of the frame.
    pub fn total_ms(&self) -> f64 {
        match self {
            Stats::Gpu(s) => s.total_ms,
            Stats::Reference(s) => s.total_ms,
        }
    }

    /// The device the frame ran on.
    pub fn device(&self) -> &str {
        match self {
            Stats::Gpu(s) => &s.device,
            Stats::Reference(s) => &s.device,
        }
    }

    /// As JSON (`stats.json`).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
}
