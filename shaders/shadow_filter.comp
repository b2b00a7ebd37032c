#version 450
// Baseline shadow map, look-up: per view sample, the lit share of a shadow
// map's taps (percentage-closer filtering), or with PCSS first a blocker
// search whose mean blocker depth sizes the filter (Fernando 2005). Adds
// weight * lit to the sample's visibility, so that maps from several light
// samples can be averaged into one buffer.
//
// A tap compares the map's depth with the receiver's depth along the tap's
// texel-centre ray: with the receiver-plane flag, the depth of the plane
// through the sample (exact for a planar receiver at any kernel width),
// else the sample's own depth. The bias subtracted from that depth is
// (constant + slope * tan(angle to the light)) receiver texel footprints,
// and the sample is first moved off its surface by normal_offset
// footprints. Taps outside the map are lit; samples facing away from the
// light are unlit (0 is added), the oracle's rule.

#include "common.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0, std430) readonly buffer Samples {
    GpuViewSample samples[];
};
// The light-space depth per texel, row 0 = NDC y -1.
layout(set = 0, binding = 1) uniform samplerBuffer depth_map;
layout(set = 0, binding = 2, std430) buffer Visibility {
    float visibility[];
};

#define FLAG_PCSS 1u
#define FLAG_RECEIVER_PLANE 2u

layout(push_constant) uniform FilterPush {
    vec4 origin;  // xyz: light position (camera-relative); w: 1 = orthographic
    vec4 right;   // xyz: light right; w: x scale
    vec4 up;      // xyz: light up; w: y scale
    vec4 forward; // xyz: light forward; w: x offset
    vec4 proj;    // x: y offset; y: texel size in x/z (orthographic: x) units; z: nearest caster depth; w: light radius
    vec4 bias;    // x: constant; y: slope; z: normal offset (texel footprints); w: largest PCSS radius in texels
    uvec4 sizes;  // x: map side; y: view samples; z: kernel radius k ((2k+1)^2 taps); w: FLAG_*
    vec4 extra;   // x: weight
} pc;

bool ortho() { return pc.origin.w != 0.0; }

// Continuous texel coordinates of projected coordinates a (x/z, y/z or x, y).
vec2 to_texel(vec2 a) {
    vec2 ndc = a * vec2(pc.right.w, pc.up.w) + vec2(pc.forward.w, pc.proj.x);
    return (ndc + 1.0) * 0.5 * float(pc.sizes.x);
}

vec2 from_texel(vec2 t) {
    vec2 ndc = t / float(pc.sizes.x) * 2.0 - 1.0;
    return (ndc - vec2(pc.forward.w, pc.proj.x)) / vec2(pc.right.w, pc.up.w);
}

// Depth of the receiver along the ray through texel tx's centre.
float receiver_depth(ivec2 tx, vec3 pl, vec3 nl) {
    if ((pc.sizes.w & FLAG_RECEIVER_PLANE) == 0u) {
        return pl.z;
    }
    vec2 a = from_texel(vec2(tx) + 0.5);
    float z;
    if (ortho()) {
        z = abs(nl.z) > 1e-4 ? (dot(nl, pl) - nl.x * a.x - nl.y * a.y) / nl.z : pl.z;
    } else {
        float den = dot(nl, vec3(a, 1.0));
        z = abs(den) > 1e-6 ? dot(nl, pl) / den : pl.z;
    }
    // A plane seen nearly edge-on: its depth there means nothing.
    return (z > 0.0 || ortho()) && abs(z - pl.z) < 0.5 * abs(pl.z) + 1e-6 ? z : pl.z;
}

// The map's depth at texel tx; +inf outside the map (no caster).
float map_depth(ivec2 tx) {
    int side = int(pc.sizes.x);
    if (any(lessThan(tx, ivec2(0))) || any(greaterThanEqual(tx, ivec2(side)))) {
        return 1.0 / 0.0;
    }
    return texelFetch(depth_map, tx.y * side + tx.x).x;
}

// Lit share of (2k+1)^2 taps `step` texels apart around t.
float pcf(vec2 t, float step, vec3 pl, vec3 nl, float bias) {
    int k = int(pc.sizes.z);
    float lit = 0.0;
    for (int dy = -k; dy <= k; dy++) {
        for (int dx = -k; dx <= k; dx++) {
            ivec2 tx = ivec2(floor(t + vec2(dx, dy) * step));
            lit += map_depth(tx) >= receiver_depth(tx, pl, nl) - bias ? 1.0 : 0.0;
        }
    }
    float taps = float((2 * k + 1) * (2 * k + 1));
    return lit / taps;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.sizes.y) {
        return;
    }
    GpuViewSample s = samples[i];
    if ((sample_flags(s) & VIEW_SAMPLE_VALID) == 0u) {
        return;
    }
    vec3 p = sample_position(s);
    vec3 n = sample_normal(s);
    vec3 to_light = ortho() ? -pc.forward.xyz : normalize(pc.origin.xyz - p);
    float c = dot(n, to_light);
    if (c <= 0.0) {
        return;
    }
    vec3 d = p - pc.origin.xyz;
    vec3 pl = vec3(dot(d, pc.right.xyz), dot(d, pc.up.xyz), dot(d, pc.forward.xyz));
    vec3 nl = vec3(dot(n, pc.right.xyz), dot(n, pc.up.xyz), dot(n, pc.forward.xyz));
    if (!ortho() && pl.z <= 0.0) {
        visibility[i] += pc.extra.x;
        return;
    }
    float texel_a = pc.proj.y;
    float footprint = ortho() ? texel_a : texel_a * pl.z;
    pl += nl * (pc.bias.z * footprint);
    float tan_angle = sqrt(max(1.0 - c * c, 0.0)) / max(c, 0.1);
    float bias = (pc.bias.x + pc.bias.y * tan_angle) * footprint + 1e-5 * abs(pl.z);
    vec2 t = to_texel(ortho() ? pl.xy : pl.xy / pl.z);

    float lit;
    if ((pc.sizes.w & FLAG_PCSS) == 0u) {
        lit = pcf(t, 1.0, pl, nl, bias);
    } else {
        // Blocker search over the light's footprint at the nearest caster
        // depth, as seen from the receiver.
        float radius = pc.proj.w;
        float d_near = pc.proj.z;
        float k = max(float(pc.sizes.z), 1.0);
        float search = clamp(radius * (pl.z - d_near) / (pl.z * d_near) / texel_a, 0.0, pc.bias.w);
        float sum = 0.0;
        float blockers = 0.0;
        int ki = int(pc.sizes.z);
        for (int dy = -ki; dy <= ki; dy++) {
            for (int dx = -ki; dx <= ki; dx++) {
                ivec2 tx = ivec2(floor(t + vec2(dx, dy) * (search / k)));
                float z = map_depth(tx);
                if (z < receiver_depth(tx, pl, nl) - bias) {
                    sum += z;
                    blockers += 1.0;
                }
            }
        }
        if (blockers == 0.0) {
            lit = 1.0;
        } else {
            // Penumbra half-width from similar triangles, in texels.
            float d_blocker = max(sum / blockers, 1e-6);
            float penumbra = clamp(radius * (pl.z - d_blocker) / (d_blocker * pl.z) / texel_a,
                                   0.0, pc.bias.w);
            lit = pcf(t, penumbra / k, pl, nl, bias);
        }
    }
    visibility[i] += pc.extra.x * lit;
}
