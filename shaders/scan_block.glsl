// Second half of one scan level: the exclusive scan of each block, plus the
// block's offset (the scanned block sums of the level above) when
// SCAN_FLAG_BLOCK_OFFSETS is set. The last workgroup also writes the total to
// out[n], so `out` holds n + 1 values. In place (input and output the same
// memory) is allowed: every invocation reads its elements before writing
// them and no other invocation reads them. Included by scan_block.comp and
// scan_block_texel.comp.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(constant_id = 0) const uint WG = SCAN_WORKGROUP_SIZE;
layout(constant_id = 1) const uint VECS = SCAN_VECS_PER_THREAD;
layout(local_size_x_id = 0) in;

// Upper bound of VECS, so the per-invocation values live in a fixed-size array.
#define MAX_VECS 16

#include "scan_io.glsl"

layout(set = 0, binding = 2) writeonly buffer OutputVec { uvec4 out_vec[]; };
layout(set = 0, binding = 2) writeonly buffer OutputScalar { uint out_scalar[]; };
layout(set = 0, binding = 3) readonly buffer Offsets { uint offsets[]; };

shared uint sg_offsets[WG];

void store4(uint v, uvec4 value) {
    uint first = v * 4u;
    if (first + 3u < pc.n) {
        out_vec[v] = value;
        return;
    }
    if (first < pc.n) out_scalar[first] = value.x;
    if (first + 1u < pc.n) out_scalar[first + 1u] = value.y;
    if (first + 2u < pc.n) out_scalar[first + 2u] = value.z;
}

void main() {
    uint group = scan_group_index();
    // Uniform over the workgroup, so the barriers below stay in uniform flow.
    if (group >= pc.group_count) {
        return;
    }
    // Contiguous per invocation, so its running sum stays in registers.
    uint first_vec = (group * WG + gl_LocalInvocationID.x) * VECS;
    uvec4 values[MAX_VECS];
    uint total = 0u;
    for (uint j = 0u; j < VECS; ++j) {
        values[j] = load4(first_vec + j);
        total += values[j].x + values[j].y + values[j].z + values[j].w;
    }

    uint before_me = subgroupExclusiveAdd(total);
    uint sg_total = subgroupAdd(total);
    if (subgroupElect()) {
        sg_offsets[gl_SubgroupID] = sg_total;
    }
    barrier();
    // Subgroup 0 turns the subgroup totals into exclusive offsets, a subgroup
    // at a time (one pass on GPUs, WG / 8 passes on lavapipe), starting from
    // the block's offset: one load per workgroup, not per invocation.
    if (gl_SubgroupID == 0u) {
        uint carry = (pc.flags & SCAN_FLAG_BLOCK_OFFSETS) != 0u ? offsets[group] : 0u;
        for (uint start = 0u; start < gl_NumSubgroups; start += gl_SubgroupSize) {
            uint i = start + gl_SubgroupInvocationID;
            uint x = i < gl_NumSubgroups ? sg_offsets[i] : 0u;
            uint excl = subgroupExclusiveAdd(x);
            if (i < gl_NumSubgroups) {
                sg_offsets[i] = carry + excl;
            }
            carry += subgroupAdd(x);
        }
    }
    barrier();

    uint running = sg_offsets[gl_SubgroupID] + before_me;
    for (uint j = 0u; j < VECS; ++j) {
        uvec4 x = values[j];
        uvec4 r;
        r.x = running;
        r.y = r.x + x.x;
        r.z = r.y + x.y;
        r.w = r.z + x.z;
        running = r.w + x.w;
        store4(first_vec + j, r);
    }
    // The last invocation of the last block ends at the grand total (elements
    // past n are zero).
    if (group == pc.group_count - 1u && gl_LocalInvocationID.x == WG - 1u) {
        out_scalar[pc.n] = running;
    }
}
