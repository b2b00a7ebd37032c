#version 450
// Soft pass, last: per view sample, its visible light samples = the ones in
// front of its surface (the oracle's normal rule) and not blocked;
// visibility = their count / light samples (paper §4). Samples that face
// away from the whole light were never listed: 0, not evaluated.
// Twin: cpu::resolve::resolve_soft.
#extension GL_GOOGLE_include_directive : require
#define LIGHT_SAMPLES_BINDING 6
#include "soft_common.glsl"
#define PIXEL_ROTATION_BINDING 7
#include "pixel_rotation.glsl"
#include "exact_div.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer Samples { GpuViewSample samples[]; };
layout(set = 0, binding = 1) readonly buffer SampleTexel { uint sample_texel[]; };
layout(set = 0, binding = 2) readonly buffer SampleSlot { uint sample_slot[]; };
layout(set = 0, binding = 3) readonly buffer Masks { uint masks[]; };      // blocked, per list slot
layout(set = 0, binding = 4) writeonly buffer Visible { uint visible[]; }; // visible, per view sample
layout(set = 0, binding = 5) writeonly buffer Result { float result[]; };  // visibility, -1 when not evaluated

void main() {
    uint i = linear_invocation();
    if (i >= pc.sizes.x) {
        return;
    }
    uint n_light = pc.soft.y;
    uint words = ((n_light + 127u) / 128u) * 4u;
    if (sample_texel[i] == NOT_LISTED) {
        for (uint w = 0u; w < words; w++) {
            visible[i * words + w] = 0u;
        }
        result[i] = -1.0;
        return;
    }
    GpuViewSample s = samples[i];
    vec3 p = sample_position(s);
    vec3 nrm = sample_normal(s);
    if (ROTATION != 0u) {
        // The samples as this pixel sees them: its point and normal turned back.
        mat3 m = unrotation(pixel_angle(i));
        p = unrotate_point(p, m);
        nrm = m * nrm;
    }
    uint slot = sample_slot[i];
    // Most view samples face the whole light, and then every light sample
    // passes the test below: such a sample tests none. Lavapipe runs both
    // sides of an `if` under a mask but leaves a loop once no lane is in
    // it, so the loop's bound is what skips the work (the test was 160 of
    // the pass's 180 ms at 1024 samples, builtin:demo). The twin tests
    // every sample: the same bits.
    bool all_front = faces_whole_light(p, nrm);
    uint tested = all_front ? 0u : n_light;
    uint total = 0u;
    for (uint w = 0u; w < words; w++) {
        uint first = w * 32u;
        uint front = all_front ? existing_samples(first) : 0u;
        uint end = min(first + 32u, tested);
        for (uint j = first; j < end; j++) {
            if (dot(nrm, light_samples[j].xyz - p) > 0.0) {
                front |= 1u << (j - first);
            }
        }
        uint v = front & ~masks[slot * words + w];
        visible[i * words + w] = v;
        total += bitCount(v);
    }
    result[i] = div_rn(float(total), float(n_light));
}
