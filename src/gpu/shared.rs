//! Rust twins of the structs and constants in `shaders/common.glsl`.
//!
//! Each GLSL `vec4` whose `w` holds uint bits is spelled here as `[f32; 3]` +
//! `u32`: same bytes, typed fields. All members are 16-byte groups, so std430
//! (storage buffers, push constants) and std140 (uniform buffers) agree with
//! `#[repr(C)]`. `tests/layout.rs` checks every field on the device.

use bytemuck::{Pod, Zeroable};

/// `DEFAULT_WORKGROUP_SIZE`: workgroup size of 1D passes.
pub const DEFAULT_WORKGROUP_SIZE: u32 = 64;
/// `SCAN_WORKGROUP_SIZE`: default scan workgroup size.
pub const SCAN_WORKGROUP_SIZE: u32 = 256;
/// `SCAN_VECS_PER_THREAD`: default uvec4 loads per scan invocation.
pub const SCAN_VECS_PER_THREAD: u32 = 2;
/// `MAX_VECS` of `scan_block.comp`: the most uvec4 loads per invocation.
pub const SCAN_MAX_VECS_PER_THREAD: u32 = 16;
/// `SCAN_FLAG_BLOCK_OFFSETS`.
pub const SCAN_FLAG_BLOCK_OFFSETS: u32 = 1;

/// `VIEW_SAMPLE_VALID`.
pub const VIEW_SAMPLE_VALID: u32 = 1;
/// `VIEW_SAMPLE_BACKFACING`.
pub const VIEW_SAMPLE_BACKFACING: u32 = 2;
/// `TRIANGLE_DOUBLE_SIDED`.
pub const TRIANGLE_DOUBLE_SIDED: u32 = 1;
/// `TRIANGLE_CASTS_SHADOW`.
pub const TRIANGLE_CASTS_SHADOW: u32 = 2;
/// `LIGHT_KIND_POINT`.
pub const LIGHT_KIND_POINT: u32 = 0;
/// `LIGHT_KIND_DIRECTIONAL`.
pub const LIGHT_KIND_DIRECTIONAL: u32 = 1;
/// `LIGHT_KIND_RECT`.
pub const LIGHT_KIND_RECT: u32 = 2;
/// `LIGHT_KIND_DISK`.
pub const LIGHT_KIND_DISK: u32 = 3;
/// `LIGHT_KIND_SPHERE`.
pub const LIGHT_KIND_SPHERE: u32 = 4;

/// `ScanPush`: push constants of the scan shaders.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct ScanPush {
    /// Elements in this level.
    pub n: u32,
    /// `SCAN_FLAG_*`.
    pub flags: u32,
    /// Workgroups that hold data.
    pub group_count: u32,
    /// Workgroups per row of a 2D dispatch.
    pub groups_x: u32,
}

/// `GpuViewSample`: one eye-space sample (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuViewSample {
    /// Camera-relative position (`position_triangle.xyz`).
    pub position: [f32; 3],
    /// Triangle id (`position_triangle.w` bits).
    pub triangle: u32,
    /// Unit normal (`normal_flags.xyz`).
    pub normal: [f32; 3],
    /// `VIEW_SAMPLE_*` flags (`normal_flags.w` bits).
    pub flags: u32,
}

/// `GpuTriangle`: one triangle, vertices relative to the camera (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTriangle {
    /// Vertex 0 (`v0_flags.xyz`).
    pub v0: [f32; 3],
    /// `TRIANGLE_*` flags (`v0_flags.w` bits).
    pub flags: u32,
    /// Vertex 1 (`v1_mesh.xyz`).
    pub v1: [f32; 3],
    /// Mesh id (`v1_mesh.w` bits).
    pub mesh: u32,
    /// Vertex 2 (`v2_pad.xyz`).
    pub v2: [f32; 3],
    /// With [`TRIANGLE_ALPHA`]: the triangle's alpha-test record
    /// (`cpu::alpha::AlphaTables`); else 0 (`v2_pad.w`).
    pub alpha_record: u32,
}

/// `FrameConstants`: the per-frame uniform buffer (std140, 160 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FrameConstants {
    /// Camera-relative position to light clip space; columns (as glam's
    /// `Mat4::to_cols_array_2d`, GLSL's `mat4` column order).
    pub light_view_proj: [[f32; 4]; 4],
    /// Camera-relative light centre (`light_position.xyz`).
    pub light_position: [f32; 3],
    /// `LIGHT_KIND_*` (`light_position.w` bits).
    pub light_kind: u32,
    /// Unit axis the light faces (xyz); w reserved.
    pub light_direction: [f32; 4],
    /// Area light half sizes / radius (xyz); w reserved.
    pub light_extent: [f32; 4],
    /// x, y: light texels; z: light samples; w: reserved.
    pub light_resolution: [u32; 4],
    /// x: view samples; y: triangles; z, w: image width, height.
    pub counts: [u32; 4],
    /// World position of the camera-relative origin (xyz); w reserved.
    pub camera_origin: [f32; 4],
}

impl GpuViewSample {
    /// A sample from glam vectors.
    pub fn new(position: glam::Vec3, triangle: u32, normal: glam::Vec3, flags: u32) -> Self {
        GpuViewSample {
            position: position.to_array(),
            triangle,
            normal: normal.to_array(),
            flags,
        }
    }
}

impl GpuTriangle {
    /// A triangle from glam vectors.
    pub fn new(v: [glam::Vec3; 3], flags: u32, mesh: u32) -> Self {
        GpuTriangle {
            v0: v[0].to_array(),
            flags,
            v1: v[1].to_array(),
            mesh,
            v2: v[2].to_array(),
            alpha_record: 0,
        }
    }
}

// The sizes the GLSL side has; a mismatch fails the build.
const _: () = assert!(std::mem::size_of::<ScanPush>() == 16);
const _: () = assert!(std::mem::size_of::<GpuViewSample>() == 32);
const _: () = assert!(std::mem::size_of::<GpuTriangle>() == 48);
const _: () = assert!(std::mem::size_of::<FrameConstants>() == 160);

// ---- The shadow passes of a light (shaders/shadow_common.glsl) -------------

/// `NOT_LISTED`: a sample in no light-texel list.
pub const NOT_LISTED: u32 = u32::MAX;
/// `TRIANGLE_CLOSED`: [`GpuTriangle::flags`] bit of triangles of closed meshes.
pub const TRIANGLE_CLOSED: u32 = 4;
/// `TRIANGLE_ALPHA` (alpha_common.glsl): [`GpuTriangle::flags`] bit of
/// alpha-tested triangles, whose record is [`GpuTriangle::alpha_record`].
pub const TRIANGLE_ALPHA: u32 = 8;
/// `TRIANGLE_INVISIBLE`: with [`TRIANGLE_ALPHA`], transparent wherever its
/// coverage can be read: it casts nothing (`cpu::alpha::Footprint`).
pub const TRIANGLE_INVISIBLE: u32 = 16;
/// Counter slots of the shadow passes (`COUNTER_*`).
pub mod counter {
    /// (Caster, light face) pairs the caster passes appended, including
    /// any past the pair buffer's capacity (`COUNTER_PAIRS`).
    pub const PAIRS: usize = 0;
    /// Triangles with a zero or non-finite normal or a plane through the
    /// light, dropped by `casters_setup.comp`.
    pub const DEGENERATE: usize = 1;
    /// Triangles of closed meshes that face the light, dropped by
    /// `casters_setup.comp` (paper §3.3).
    pub const FRONT_FACING_CLOSED: usize = 2;
    /// Triangles that overlap no light face (no pair appended).
    pub const CULLED: usize = 3;
    /// Triangles that appended at least one (caster, face) pair.
    pub const RASTERIZED: usize = 4;
    /// (Caster, texel) pairs that `occlusion.comp` visited.
    pub const TEXELS_VISITED: usize = 5;
    /// View-sample–triangle tests of `occlusion.comp` and
    /// `soft_occlusion.comp`.
    pub const TESTS: usize = 6;
    /// (Triangle, face mask) items left to `caster_clip`.
    pub const CLIP_ITEMS: usize = 7;
    /// Soft occlusion: tests that blocked at least one light sample.
    pub const BLOCKING: usize = 8;
    /// Soft occlusion, look-up mode: light-sample bits the table left
    /// unsure and the exact test decided (low and high word of a u64).
    pub const UNSURE_LO: usize = 9;
    /// High word of the unsure-bit count (see [`UNSURE_LO`]).
    pub const UNSURE_HI: usize = 10;
    /// Soft occlusion: tests rejected by the caster's own plane (the whole
    /// light's bounding sphere on the sample's side of it).
    pub const PLANE_REJECTED: usize = 11;
    /// Tile binning: (pair, tile) bins dropped because every view sample of
    /// the tile's box lies on the light's side of the caster's plane.
    pub const CLUSTER_LIGHT_SIDE: usize = 12;
    /// The same, because every sample lies behind a closed caster (soft).
    pub const CLUSTER_BEHIND_CLOSED: usize = 13;
    /// Soft occlusion: (pair, chunk of 64 samples) visits that the chunk's
    /// own box or texels ruled out.
    pub const CLUSTER_CHUNK: usize = 14;
    /// Soft occlusion: of those, the visits whose chunk's box lies outside
    /// the caster's penumbra volume (one edge's plane through any of its
    /// samples leaves the whole light outside the caster's cone).
    pub const CLUSTER_OUTSIDE_PENUMBRA: usize = 15;
    /// Soft occlusion: tests past the bounding-sphere tests of all four
    /// planes and the wedge rule, which went on to the look-ups or the
    /// per-light-sample tests (the other tests were rejected by an edge's
    /// plane or by the wedge rule).
    pub const PAST_SPHERE: usize = 16;
    /// Exact soft occlusion: light-sample groups (`LIGHT_GROUP_SIZE`
    /// samples) whose samples were tested one by one, low word of a 64-bit
    /// sum.
    pub const GROUPS_TESTED_LO: usize = 17;
    /// High word of [`GROUPS_TESTED_LO`].
    pub const GROUPS_TESTED_HI: usize = 18;
    /// Exact soft occlusion: light-sample groups wholly blocked by a pair
    /// without a per-sample test, low word of a 64-bit sum.
    pub const GROUPS_EVERY_LO: usize = 19;
    /// High word of [`GROUPS_EVERY_LO`].
    pub const GROUPS_EVERY_HI: usize = 20;
    /// Soft occlusion: tests past the four planes' sphere tests that the
    /// wedge rule rejected (two edges' planes together leave the light's
    /// sphere outside; exact mode only).
    pub const WEDGE_REJECTED: usize = 21;
    /// Soft occlusion: (view sample, work unit) visits, once per block
    /// pass in exact mode. Unlike the tests, it does not depend on the
    /// order in which atomics filled the lists.
    pub const SAMPLE_VISITS: usize = 22;
    /// Soft occlusion: (view sample, pair) visits that the reach rule
    /// culled before the test (`clusters_common.glsl`: `beyond_reach`).
    pub const BEYOND_REACH: usize = 23;
    /// Soft occlusion: of [`CLUSTER_CHUNK`]'s visits, those that the reach
    /// rule dropped for the chunk's box.
    pub const CLUSTER_BEYOND_REACH: usize = 24;
    /// Soft occlusion: (view sample, pair) visits that the hull rule
    /// culled before the test (`clusters_common.glsl`: `outside_hull`).
    pub const OUTSIDE_HULL: usize = 25;
    /// Tile binning: (pair, tile) bins dropped because the caster lies
    /// beyond the reach of every sample of the tile's box (soft).
    pub const BIN_BEYOND_REACH: usize = 26;
    /// Tile binning: (pair, tile) bins dropped because the caster's ball
    /// lies outside the hull of the tile box's ball and the light (soft).
    pub const BIN_OUTSIDE_HULL: usize = 27;
    /// Caster setup, soft shadows: the large pairs listed for tile
    /// binning's by-blocks pipeline (`large_pair` in `shadow_common.glsl`).
    pub const LARGE_PAIRS: usize = 28;
    /// Soft occlusion: of [`CLUSTER_CHUNK`]'s visits, those that the boxes
    /// of the groups of samples the chunk lies in dropped
    /// (`pair_groups.comp`) before the chunk's own tests.
    pub const CLUSTER_GROUPS: usize = 29;
    /// Number of counter slots (`COUNTER_COUNT`): `u32`s in the counter
    /// buffer.
    pub const COUNT: usize = 30;

    /// The (low, high) slot pairs that hold 64-bit sums (the high word
    /// right after the low one: `count_wide` in soft_occlusion.comp).
    pub const WIDE: [(usize, usize); 3] = [
        (UNSURE_LO, UNSURE_HI),
        (GROUPS_TESTED_LO, GROUPS_TESTED_HI),
        (GROUPS_EVERY_LO, GROUPS_EVERY_HI),
    ];

    /// The 64-bit sum whose low word is slot `lo` of `c` (one of the
    /// [`WIDE`] pairs: the high word is the next slot).
    pub fn wide(c: &[u32; COUNT], lo: usize) -> u64 {
        c[lo] as u64 | (c[lo + 1] as u64) << 32
    }

    /// Adds the counters `other` (of another round, batch or run) to
    /// `acc`: the [`WIDE`] pairs as 64-bit sums, every other slot
    /// saturating at `u32::MAX`.
    pub fn add(acc: &mut [u32; COUNT], other: &[u32; COUNT]) {
        let mut sum = *acc;
        for (a, b) in sum.iter_mut().zip(other) {
            *a = a.saturating_add(*b);
        }
        for (lo, hi) in WIDE {
            let total = wide(acc, lo).saturating_add(wide(other, lo));
            sum[lo] = total as u32;
            sum[hi] = (total >> 32) as u32;
        }
        *acc = sum;
    }
}

/// `LightPush`: push constants of every shadow pass of a light, hard and soft.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LightPush {
    /// xyz: light position (point) or 0; w: `LIGHT_KIND_*` bits.
    pub origin: [f32; 4],
    /// xyz: a directional light's travel direction.
    pub direction: [f32; 4],
    /// View samples, triangles, resolution, face count.
    pub sizes: [u32; 4],
    /// Pair capacity, tiles per row, tiles per face, occlusion work units
    /// (0 before they are known).
    pub more: [u32; 4],
    /// Directional light's face basis: xyz the right axis.
    pub dir_right: [f32; 4],
    /// Directional light's face basis: xyz the up axis (forward is
    /// `direction`).
    pub dir_up: [f32; 4],
    /// Soft shadows: 128-sample block, light samples (0: hard shadows),
    /// LUT resolution; w: look-up mode's occlusion, the dispatch's first
    /// work unit.
    pub soft: [u32; 4],
    /// Soft shadows: light bounding radius, influence polygon degree; z
    /// (all runs): the global id of this run's triangle 0 as `u32` bits
    /// (triangle batches).
    pub soft_light: [f32; 4],
}

/// `LightFace`: a light face's basis and fitted window, written by
/// `light_view_finalize.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLightFace {
    /// xyz: right; w: 1 when the face has samples.
    pub right: [f32; 4],
    /// xyz: the face's up axis; w: 0.
    pub up: [f32; 4],
    /// xyz: the axis the face looks along (depth); w: 0.
    pub forward: [f32; 4],
    /// x0, y0, sx, sy.
    pub window: [f32; 4],
    /// x: depth of the farthest sample.
    pub far: [f32; 4],
    /// Padding to 128 bytes (`pad0`..`pad2`), written as 0.
    pub pad: [[f32; 4]; 3],
}

/// `CasterPlanes` (`shadow_common.glsl`): a caster's supporting plane and
/// edge planes, written by `casters_setup.comp`. A point `p` is blocked when
/// it is behind the supporting plane and inside all three edge planes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCasterPlanes {
    /// Supporting plane (xyz normal, w offset) on camera-relative points,
    /// positive on the light's side: blocked needs `dot(xyz, p) + w < 0`.
    pub support: [f32; 4],
    /// `edge0`..`edge2`: the planes through the light and each edge, on
    /// light-relative points `q = p - origin`, oriented by `side`.
    pub edges: [[f32; 4]; 3],
    /// +1 or -1 per edge (see `CasterPlanes` in hard_common.glsl).
    pub side: [f32; 4],
}

/// `CasterFace` (`shadow_common.glsl`): one (caster, light face) pair to
/// rasterize, appended by the caster passes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCasterFace {
    /// triangle, face, rect min (x | y << 16), rect max.
    pub ids: [u32; 4],
    /// Hard pairs: texel-space edges (a, b, c; the first's w the x margin,
    /// 0 where there are none, the second's the y margin). Soft pairs: the
    /// triangle's vertices as in [`GpuTriangle`], bit for bit, with w 0,
    /// the `TRIANGLE_*` flags' bits and the alpha record's.
    pub edges: [[f32; 4]; 3],
}

const _: () = assert!(std::mem::size_of::<LightPush>() == 128);
const _: () = assert!(std::mem::size_of::<GpuLightFace>() == 128);
const _: () = assert!(std::mem::size_of::<GpuCasterPlanes>() == 80);
const _: () = assert!(std::mem::size_of::<GpuCasterFace>() == 64);

#[cfg(test)]
pub(crate) mod tests {
    use super::counter;

    /// The value of `#define NAME VALUE` in `source` (a trailing `u` dropped).
    pub(crate) fn glsl_define(source: &str, name: &str) -> Option<u64> {
        source.lines().find_map(|line| {
            let mut words = line.split_whitespace();
            (words.next() == Some("#define") && words.next() == Some(name))
                .then(|| words.next()?.trim_end_matches('u').parse().ok())
                .flatten()
        })
    }

    #[test]
    fn wide_counters_carry_when_added() {
        let mut a = [0u32; counter::COUNT];
        let mut b = [0u32; counter::COUNT];
        a[counter::UNSURE_LO] = u32::MAX;
        b[counter::UNSURE_LO] = 2;
        a[counter::GROUPS_TESTED_HI] = 3;
        b[counter::GROUPS_TESTED_LO] = 5;
        a[counter::TESTS] = u32::MAX - 1;
        b[counter::TESTS] = 7;
        counter::add(&mut a, &b);
        assert_eq!((a[counter::UNSURE_LO], a[counter::UNSURE_HI]), (1, 1));
        assert_eq!(
            (a[counter::GROUPS_TESTED_LO], a[counter::GROUPS_TESTED_HI]),
            (5, 3)
        );
        assert_eq!(a[counter::TESTS], u32::MAX, "narrow counters saturate");
        for (lo, hi) in counter::WIDE {
            assert_eq!(hi, lo + 1, "the shaders add the carry to the next slot");
        }
    }

    #[test]
    fn counter_slots_match_the_shaders() {
        let glsl = include_str!("../../shaders/shadow_common.glsl");
        for (name, slot) in [
            ("PAIRS", counter::PAIRS),
            ("DEGENERATE", counter::DEGENERATE),
            ("FRONT_FACING_CLOSED", counter::FRONT_FACING_CLOSED),
            ("CULLED", counter::CULLED),
            ("RASTERIZED", counter::RASTERIZED),
            ("TEXELS_VISITED", counter::TEXELS_VISITED),
            ("TESTS", counter::TESTS),
            ("CLIP_ITEMS", counter::CLIP_ITEMS),
            ("BLOCKING", counter::BLOCKING),
            ("UNSURE_LO", counter::UNSURE_LO),
            ("UNSURE_HI", counter::UNSURE_HI),
            ("PLANE_REJECTED", counter::PLANE_REJECTED),
            ("CLUSTER_LIGHT_SIDE", counter::CLUSTER_LIGHT_SIDE),
            ("CLUSTER_BEHIND_CLOSED", counter::CLUSTER_BEHIND_CLOSED),
            ("CLUSTER_CHUNK", counter::CLUSTER_CHUNK),
            (
                "CLUSTER_OUTSIDE_PENUMBRA",
                counter::CLUSTER_OUTSIDE_PENUMBRA,
            ),
            ("PAST_SPHERE", counter::PAST_SPHERE),
            ("GROUPS_TESTED_LO", counter::GROUPS_TESTED_LO),
            ("GROUPS_TESTED_HI", counter::GROUPS_TESTED_HI),
            ("GROUPS_EVERY_LO", counter::GROUPS_EVERY_LO),
            ("GROUPS_EVERY_HI", counter::GROUPS_EVERY_HI),
            ("WEDGE_REJECTED", counter::WEDGE_REJECTED),
            ("SAMPLE_VISITS", counter::SAMPLE_VISITS),
            ("BEYOND_REACH", counter::BEYOND_REACH),
            ("CLUSTER_BEYOND_REACH", counter::CLUSTER_BEYOND_REACH),
            ("OUTSIDE_HULL", counter::OUTSIDE_HULL),
            ("BIN_BEYOND_REACH", counter::BIN_BEYOND_REACH),
            ("BIN_OUTSIDE_HULL", counter::BIN_OUTSIDE_HULL),
            ("LARGE_PAIRS", counter::LARGE_PAIRS),
            ("CLUSTER_GROUPS", counter::CLUSTER_GROUPS),
            ("COUNT", counter::COUNT),
        ] {
            assert_eq!(
                glsl_define(glsl, &format!("COUNTER_{name}")),
                Some(slot as u64),
                "COUNTER_{name}"
            );
        }
    }
}
