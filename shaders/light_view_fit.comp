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

void main() {
    uint i = linear_invocation();
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
    // Reduce in the subgroup first: contended atomics are slow on lavapipe.
    for (uint f = 0u; f < pc.sizes.w; f++) {
        bool mine = face == f;
        if (!subgroupAny(mine)) {
            continue;
        }
        uint kx = float_key(xyz.x), ky = float_key(xyz.y), kz = float_key(xyz.z);
        uint xmin = subgroupMin(mine ? kx : 0xffffffffu);
        uint ymin = subgroupMin(mine ? ky : 0xffffffffu);
        uint xmax = subgroupMax(mine ? kx : 0u);
        uint ymax = subgroupMax(mine ? ky : 0u);
        uint zmax = subgroupMax(mine ? kz : 0u);
        if (subgroupElect()) {
            atomicMin(fit_keys[f * 8u + 0u], xmin);
            atomicMin(fit_keys[f * 8u + 1u], ymin);
            atomicMax(fit_keys[f * 8u + 2u], xmax);
            atomicMax(fit_keys[f * 8u + 3u], ymax);
            atomicMax(fit_keys[f * 8u + 4u], zmax);
        }
    }
}
