// Input access shared by the scan kernels (scan_reduce.glsl, scan_block.glsl).
//
// The input is bound twice: binding 0 as whole uvec4s (n / 4 of them),
// binding 1 as single uints for the tail when n is not a multiple of 4, so
// callers need no padding. Built two ways:
// - default: storage buffers (the fast path on GPUs);
// - SCAN_TEXEL_LOADS: uniform texel buffers (RGBA32UI and R32UI views). On
//   lavapipe every storage-buffer load is a per-lane loop with bounds checks
//   and texel fetches are ~6x faster (see /work/shared/notes/lavapipe.md).
#ifndef AFS_SCAN_IO_GLSL
#define AFS_SCAN_IO_GLSL

layout(push_constant) uniform Push { ScanPush pc; };

#ifdef SCAN_TEXEL_LOADS
layout(set = 0, binding = 0) uniform usamplerBuffer in_vec;
layout(set = 0, binding = 1) uniform usamplerBuffer in_scalar;
uvec4 load_vec(uint v) { return texelFetch(in_vec, int(v)); }
uint load_scalar(uint i) { return texelFetch(in_scalar, int(i)).x; }
#else
layout(set = 0, binding = 0) readonly buffer InputVec { uvec4 in_vec[]; };
layout(set = 0, binding = 1) readonly buffer InputScalar { uint in_scalar[]; };
uvec4 load_vec(uint v) { return in_vec[v]; }
uint load_scalar(uint i) { return in_scalar[i]; }
#endif

// Linear workgroup index of a (possibly 2D) dispatch.
uint scan_group_index() {
    return gl_WorkGroupID.y * pc.groups_x + gl_WorkGroupID.x;
}

// Elements 4*v .. 4*v+3 of the input, zero past `n`.
uvec4 load4(uint v) {
    uint first = v * 4u;
    if (first + 3u < pc.n) {
        return load_vec(v);
    }
    uvec4 r = uvec4(0u);
    if (first < pc.n) r.x = load_scalar(first);
    if (first + 1u < pc.n) r.y = load_scalar(first + 1u);
    if (first + 2u < pc.n) r.z = load_scalar(first + 2u);
    return r;
}

#endif
