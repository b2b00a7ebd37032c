#version 450
// Soft pass, look-up mode: the light samples the table left unsure for a
// (view sample, caster) pair (soft_occlusion.comp with SURE), tested
// exactly as exact mode tests every light sample, ORed into the view
// sample's blocked mask. One invocation per entry of the unsure list:
// workgroup z is the list's segment (pc.more.w entries each, from entry
// z * pc.more.w), x and y the entry in it.
// Twin: cpu::soft_occlusion::blocked_bits (exact).
#extension GL_GOOGLE_include_directive : require
#include "soft_common.glsl"
#include "alpha_common.glsl"
#define PIXEL_ROTATION_BINDING 9
#include "pixel_rotation.glsl"
layout(local_size_x = WORKGROUP_1D) in;
// 1: the alpha-tested casters' round: a light sample counts as blocked
// where the caster is opaque at its segment's crossing.
layout(constant_id = 5) const uint ALPHA = 0u;

layout(set = 0, binding = 0) uniform usamplerBuffer unsure_tb;       // 2 texels per entry
layout(set = 0, binding = 1) uniform usamplerBuffer triangles_tb;    // GpuTriangle: 3 texels
layout(set = 0, binding = 2) uniform usamplerBuffer list_samples_tb; // xyz float bits, w triangle id
layout(set = 0, binding = 3) buffer Masks { uint masks[]; };         // per list slot: blocked bits
// The light samples as a texel buffer, not soft_common's uniform buffer:
// the loop below reads one per lane at its own index, a gather that
// texel buffers serve faster.
layout(set = 0, binding = 4) uniform samplerBuffer light_samples_tb;
layout(set = 0, binding = 5) uniform usamplerBuffer alpha_records;
layout(set = 0, binding = 6) uniform usamplerBuffer alpha_textures;
layout(set = 0, binding = 7) uniform usamplerBuffer alpha_texels;
layout(set = 0, binding = 8) uniform usamplerBuffer list_sample_index_tb; // per slot: its view sample
layout(set = 0, binding = 10) readonly buffer UnsureCounts { uint unsure_counts[]; };

void main() {
    uint segment = gl_WorkGroupID.z;
    uint in_segment = linear_invocation();
    if (in_segment >= min(unsure_counts[segment * UNSURE_COUNT_STRIDE], pc.more.w)) {
        return;
    }
    uint e = segment * pc.more.w + in_segment;
    uvec4 head = texelFetch(unsure_tb, int(2u * e));
    uvec4 unsure = texelFetch(unsure_tb, int(2u * e + 1u));
    uint s = head.x, tri = head.y, block = head.z;
    vec3 x = uintBitsToFloat(texelFetch(list_samples_tb, int(s)).xyz);
    vec3 a = uintBitsToFloat(texelFetch(triangles_tb, int(3u * tri)).xyz);
    vec3 b = uintBitsToFloat(texelFetch(triangles_tb, int(3u * tri + 1u)).xyz);
    uvec4 c_record = texelFetch(triangles_tb, int(3u * tri + 2u));
    vec3 c = uintBitsToFloat(c_record.xyz);
    if (ROTATION != 0u) {
        // As soft_occlusion.comp turns them: back by the pixel's angle.
        mat3 m = unrotation(pixel_angle(texelFetch(list_sample_index_tb, int(s)).x));
        x = unrotate_point(x, m);
        a = unrotate_point(a, m);
        b = unrotate_point(b, m);
        c = unrotate_point(c, m);
    }
    // The same planes as soft_occlusion.comp computes.
    vec3 n = cross(b - a, c - a);
    float sigma = dot(n, x - a) > 0.0 ? 1.0 : -1.0;
    vec3 m0 = cross(a - x, b - x), m1 = cross(b - x, c - x), m2 = cross(c - x, a - x);
    float se = dot(m0, c - x) < 0.0 ? -1.0 : 1.0;
    uint words = light_blocks() * 4u;
    // One loop over the entry's unsure bits in all four words
    // (torus_knot:20000, 1024 samples: ~6 unsure bits per entry spread over
    // the words).
    uvec4 got = exact_blocked_bits(light_samples_tb, block * 128u, unsure, n, sigma, a, x, m0, m1, m2, se);
    if (ALPHA != 0u) {
        // The opacity at the crossing, only for the samples the triangle
        // blocks, in a loop of its own over them: lavapipe runs an `if`
        // for every lane, and the opacity's texture look-ups cost more
        // than the exact tests.
        uvec4 left = got;
        got = uvec4(0u);
        while (any(notEqual(left, uvec4(0u)))) {
            uint w;
            uint bit = take_lowest_bit(left, w);
            vec3 l = texelFetch(light_samples_tb, int(block * 128u + w * 32u + bit)).xyz;
            vec2 bc = segment_barycentrics(x, l - x, a, b, c);
            got |= in_word(w, alpha_opaque_at(alpha_records, alpha_textures, alpha_texels, c_record.w, bc) ? 1u << bit : 0u);
        }
    }
    uint base = s * words + block * 4u;
    if (got.x != 0u) { atomicOr(masks[base], got.x); }
    if (got.y != 0u) { atomicOr(masks[base + 1u], got.y); }
    if (got.z != 0u) { atomicOr(masks[base + 2u], got.z); }
    if (got.w != 0u) { atomicOr(masks[base + 3u], got.w); }
}
