#version 450
// Per view sample facing the light, its face and projection;
// per face the min/max of x, y and the max depth (paper §4.3 frustum fit).
// Twin: cpu::light_view::fit_windows.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#include "shadow_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer Samples { GpuViewSample samples[]; };
layout(set = 0, binding = 1) buffer Fit { uint fit_keys[]; }; // 8 per face: xmin ymin xmax ymax zmax

// View samples per invocation: each lane keeps its own bounds per face
// over FIT_PER_LANE samples before the subgroup reduces them, so that the
// contended atomics (the pass's main cost on lavapipe) are 16x fewer.
#define FIT_PER_LANE 16u

// Lane-local bounds of face F: keys of x min, y min, x max, y max, z max.
#define FIT_FACE_DECL(F) uvec4 lo##F = uvec4(0xffffffffu, 0xffffffffu, 0u, 0u); uint zmax##F = 0u;
#define FIT_FACE_ADD(F)                                                       \
    if (face == F) {                                                          \
        lo##F = uvec4(min(lo##F.xy, uvec2(kx, ky)), max(lo##F.zw, uvec2(kx, ky))); \
        zmax##F = max(zmax##F, kz);                                          \
    }
#define FIT_FACE_FLUSH(F)                                                     \
    if (F < pc.sizes.w) {                                                     \
        bool mine = lo##F.x <= lo##F.z;                                       \
        if (subgroupAny(mine)) {                                              \
            uint xmin = subgroupMin(lo##F.x), ymin = subgroupMin(lo##F.y);    \
            uint xmax = subgroupMax(lo##F.z), ymax = subgroupMax(lo##F.w);    \
            uint zmax = subgroupMax(zmax##F);                                 \
            if (subgroupElect()) {                                            \
                atomicMin(fit_keys[F * 8u + 0u], xmin);                       \
                atomicMin(fit_keys[F * 8u + 1u], ymin);                       \
                atomicMax(fit_keys[F * 8u + 2u], xmax);                       \
                atomicMax(fit_keys[F * 8u + 3u], ymax);                       \
                atomicMax(fit_keys[F * 8u + 4u], zmax);                       \
            }                                                                 \
        }                                                                     \
    }
#define FIT_FACES(M) M(0u) M(1u) M(2u) M(3u) M(4u) M(5u)

void main() {
    FIT_FACES(FIT_FACE_DECL)
    // Workgroup w reads FIT_PER_LANE blocks of WORKGROUP_1D consecutive samples.
    uint group = workgroup_index();
    uint first = group * FIT_PER_LANE * WORKGROUP_1D + gl_LocalInvocationID.x;
    for (uint r = 0u; r < FIT_PER_LANE; r++) {
        uint i = first + r * WORKGROUP_1D;
        uint face = 0xffu;
        vec3 xyz = vec3(0.0);
        if (i < pc.sizes.x) {
            GpuViewSample s = samples[i];
            vec3 p = sample_position(s);
            uint f;
            if ((sample_flags(s) & VIEW_SAMPLE_VALID) != 0u && faces_light(p, sample_normal(s))
                && project_to_face(p, f, xyz)) {
                face = f;
            }
        }
        uint kx = float_key(xyz.x), ky = float_key(xyz.y), kz = float_key(xyz.z);
        FIT_FACES(FIT_FACE_ADD)
    }
    FIT_FACES(FIT_FACE_FLUSH)
}
