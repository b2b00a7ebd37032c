#version 450
// Per tile of light texels, the box of its listed view samples (one
// invocation per tile; its samples are contiguous, tile-major lists):
// lo.w = 1 when the box is valid, 0 when the tile has no samples, too many
// (CLUSTER_MAX_SAMPLES) or a non-finite one (no culling there).
// BLOCKS = 1: per block of CLUSTER_BLOCK² tiles, the union of the boxes of
// its tiles that hold samples (valid when every one of them has a valid
// box), written after the tiles' boxes.
// BLOCKS = 2: per group of CLUSTER_GROUP_SAMPLES consecutive listed
// samples (clusters_common.glsl), their box (valid when every sample is
// finite), written after the blocks' boxes.
// Twin: cpu::clusters::tile_boxes, block_boxes and group_boxes.
#extension GL_GOOGLE_include_directive : require
#include "clusters_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 1) uniform usamplerBuffer list_samples_tb;
layout(set = 0, binding = 2) buffer Boxes { vec4 boxes[]; }; // per tile, then per block: lo, hi
layout(constant_id = 1) const uint BLOCKS = 0u;

void block_box(uint b) {
    uint per_row = cluster_blocks_per_row(), per_face = per_row * per_row;
    if (b >= per_face * pc.sizes.w) {
        return;
    }
    uint face = b / per_face;
    uvec2 t0 = uvec2(b % per_face % per_row, b % per_face / per_row) * CLUSTER_BLOCK;
    uvec2 t1 = min(t0 + CLUSTER_BLOCK, uvec2(pc.more.y));
    vec3 lo = vec3(1.0 / 0.0), hi = vec3(-1.0 / 0.0);
    bool any_samples = false, valid = true;
    for (uint ty = t0.y; ty < t1.y; ty++) {
        for (uint tx = t0.x; tx < t1.x; tx++) {
            uint t = face * pc.more.z + ty * pc.more.y + tx;
            if (offsets[(t + 1u) * TILE * TILE] > offsets[t * TILE * TILE]) {
                vec4 tile_lo = boxes[2u * t];
                any_samples = true;
                valid = valid && tile_lo.w != 0.0;
                lo = min(lo, tile_lo.xyz);
                hi = max(hi, boxes[2u * t + 1u].xyz);
            }
        }
    }
    uint at = cluster_block_box(face, t0 / CLUSTER_BLOCK);
    boxes[at] = vec4(lo, valid && any_samples ? 1.0 : 0.0);
    boxes[at + 1u] = vec4(hi, 0.0);
}

// The box of listed samples begin..end (inverted when empty); whether
// every one is finite.
bool samples_box(uint begin, uint end, out vec3 lo, out vec3 hi) {
    lo = vec3(1.0 / 0.0);
    hi = vec3(-1.0 / 0.0);
    bool finite = true;
    for (uint s = begin; s < end; s++) {
        vec3 x = uintBitsToFloat(texelFetch(list_samples_tb, int(s)).xyz);
        finite = finite && !any(isnan(x)) && !any(isinf(x));
        lo = min(lo, x);
        hi = max(hi, x);
    }
    return finite;
}

void group_box(uint g) {
    uint listed = offsets[pc.more.z * pc.sizes.w * TILE * TILE];
    uint begin = g * CLUSTER_GROUP_SAMPLES;
    if (begin >= listed) {
        return;
    }
    vec3 lo, hi;
    bool valid = samples_box(begin, min(begin + CLUSTER_GROUP_SAMPLES, listed), lo, hi);
    uint at = cluster_group_box(g);
    boxes[at] = vec4(lo, valid ? 1.0 : 0.0);
    boxes[at + 1u] = vec4(hi, 0.0);
}

void main() {
    uint t = linear_invocation();
    if (BLOCKS == 2u) {
        group_box(t);
        return;
    }
    if (BLOCKS != 0u) {
        block_box(t);
        return;
    }
    if (t >= pc.more.z * pc.sizes.w) {
        return;
    }
    uint begin = offsets[t * TILE * TILE], end = offsets[(t + 1u) * TILE * TILE];
    bool valid = end > begin && end - begin <= CLUSTER_MAX_SAMPLES;
    vec3 lo, hi;
    valid = samples_box(begin, valid ? end : begin, lo, hi) && valid;
    boxes[2u * t] = vec4(lo, valid ? 1.0 : 0.0);
    boxes[2u * t + 1u] = vec4(hi, 0.0);
}
