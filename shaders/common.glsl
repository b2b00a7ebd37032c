// Structs and constants shared between the shaders and Rust.
//
// Every struct here has a `#[repr(C)]` twin in src/gpu/shared.rs; tests/layout.rs
// checks on the device that both agree field by field. Members are vec4/uvec4
// (or mat4) so std430 and std140 give the same offsets and the Rust side needs
// no hidden padding. Per-element ids and flags sit in the `w` of a vec4 as
// uint bits (floatBitsToUint / uintBitsToFloat), which the Rust twin spells as
// `[f32; 3]` + `u32`.
#ifndef AFS_COMMON_GLSL
#define AFS_COMMON_GLSL

// ---- Workgroup sizes ------------------------------------------------------
// Defaults only: pipelines override them through specialization constant 0
// (`local_size_x_id = 0`), chosen per device in Rust.

// 1D passes over samples, triangles or texels.
#define DEFAULT_WORKGROUP_SIZE 64
// Prefix scan: threads per workgroup and uvec4 loads per thread.
#define SCAN_WORKGROUP_SIZE 256
#define SCAN_VECS_PER_THREAD 2

// ---- Prefix scan ----------------------------------------------------------

// ScanPush.flags: add `offsets[block]` (the scanned block sums of the level
// above) to every element of the block.
#define SCAN_FLAG_BLOCK_OFFSETS 1u

// Push constants of scan_reduce.comp and scan_block.comp.
struct ScanPush {
    uint n;           // elements in this level
    uint flags;       // SCAN_FLAG_*
    uint group_count; // workgroups that hold data (a 2D dispatch may launch more)
    uint groups_x;    // workgroups per row of a 2D dispatch
};

// ---- View samples ---------------------------------------------------------

// GpuViewSample.normal_flags.w bits.
#define VIEW_SAMPLE_VALID 1u
#define VIEW_SAMPLE_BACKFACING 2u

// One eye-space sample (a visible pixel or sub-pixel sample).
struct GpuViewSample {
    vec4 position_triangle; // xyz: camera-relative position; w: triangle id (uint bits)
    vec4 normal_flags;      // xyz: unit normal; w: VIEW_SAMPLE_* flags (uint bits)
};

// ---- Triangles ------------------------------------------------------------

// GpuTriangle.v0_flags.w bits.
#define TRIANGLE_DOUBLE_SIDED 1u
#define TRIANGLE_CASTS_SHADOW 2u

// One triangle, vertices relative to the camera origin.
struct GpuTriangle {
    vec4 v0_flags; // xyz: vertex 0; w: TRIANGLE_* flags (uint bits)
    vec4 v1_mesh;  // xyz: vertex 1; w: mesh id (uint bits)
    vec4 v2_pad;   // xyz: vertex 2; w: the alpha-test record with TRIANGLE_ALPHA, else 0 (uint bits)
};
// GpuTriangle.v0_flags.w bit: an alpha-tested triangle (alpha_common.glsl),
// whose record is v2_pad.w.
#define TRIANGLE_ALPHA 8u
// With TRIANGLE_ALPHA: transparent wherever its coverage can be read
// (cpu::alpha::Footprint): it casts nothing.
#define TRIANGLE_INVISIBLE 16u

// ---- Frame constants (uniform buffer, std140) -----------------------------

// FrameConstants.light_position.w: the light kind.
#define LIGHT_KIND_POINT 0u
#define LIGHT_KIND_DIRECTIONAL 1u
#define LIGHT_KIND_RECT 2u
#define LIGHT_KIND_DISK 3u
#define LIGHT_KIND_SPHERE 4u

struct FrameConstants {
    mat4 light_view_proj;    // camera-relative position -> light clip space
    vec4 light_position;     // xyz: camera-relative centre; w: LIGHT_KIND_* (uint bits)
    vec4 light_direction;    // xyz: unit axis the light faces; w: reserved
    vec4 light_extent;       // xyz: area light half sizes / radius; w: reserved
    uvec4 light_resolution;  // x, y: light texels; z: light samples; w: reserved
    uvec4 counts;            // x: view samples; y: triangles; z, w: image width, height
    vec4 camera_origin;      // xyz: world position of the camera-relative origin; w: reserved
};

// ---- Helpers --------------------------------------------------------------

vec3 sample_position(GpuViewSample s) { return s.position_triangle.xyz; }
uint sample_triangle(GpuViewSample s) { return floatBitsToUint(s.position_triangle.w); }
vec3 sample_normal(GpuViewSample s) { return s.normal_flags.xyz; }
uint sample_flags(GpuViewSample s) { return floatBitsToUint(s.normal_flags.w); }
uint triangle_flags(GpuTriangle t) { return floatBitsToUint(t.v0_flags.w); }
uint triangle_mesh(GpuTriangle t) { return floatBitsToUint(t.v1_mesh.w); }

#endif
