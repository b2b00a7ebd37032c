// First half of one scan level: the sum of each block of
// WG * VECS * 4 elements, written to sums[block]. Included by
// scan_reduce.comp and scan_reduce_texel.comp.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(constant_id = 0) const uint WG = SCAN_WORKGROUP_SIZE;
layout(constant_id = 1) const uint VECS = SCAN_VECS_PER_THREAD;
layout(local_size_x_id = 0) in;

#include "scan_io.glsl"

layout(set = 0, binding = 2) writeonly buffer Sums { uint sums[]; };

// One slot per subgroup; WG slots cover any subgroup size.
shared uint sg_totals[WG];

void main() {
    uint group = scan_group_index();
    // Uniform over the workgroup, so the barrier below stays in uniform flow.
    if (group >= pc.group_count) {
        return;
    }
    uint first_vec = group * WG * VECS + gl_LocalInvocationID.x;
    uint total = 0u;
    for (uint j = 0u; j < VECS; ++j) {
        // Strided: neighbouring invocations read neighbouring uvec4s.
        uvec4 v = load4(first_vec + j * WG);
        total += v.x + v.y + v.z + v.w;
    }
    uint sg_total = subgroupAdd(total);
    if (subgroupElect()) {
        sg_totals[gl_SubgroupID] = sg_total;
    }
    barrier();
    if (gl_SubgroupID == 0u) {
        uint acc = 0u;
        for (uint i = gl_SubgroupInvocationID; i < gl_NumSubgroups; i += gl_SubgroupSize) {
            acc += sg_totals[i];
        }
        acc = subgroupAdd(acc);
        if (subgroupElect()) {
            sums[group] = acc;
        }
    }
}
