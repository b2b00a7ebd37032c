// Per-pixel rotation of a symmetric light's samples (paper §4.2): view
// sample i sees every light sample turned by its own angle about the
// light's axis through its centre. The passes turn the view sample and the
// casters back by that angle instead (the same geometry, so every test and
// every table look-up stays as it is). Compiled in with ROTATION = 1
// (specialization constant 6), else compiled out. Each shader defines
// PIXEL_ROTATION_BINDING before including this file.
// Twin: light::{hash32, pixel_rotation_angle, pixel_rotation_table, unrotation_f32,
// unrotate_f32}.
#ifndef AFS_PIXEL_ROTATION_GLSL
#define AFS_PIXEL_ROTATION_GLSL

layout(constant_id = 6) const uint ROTATION = 0u;

// PIXEL_ROTATION_ANGLES (256) angles, two per vec4: (cos, sin, cos, sin).
layout(set = 0, binding = PIXEL_ROTATION_BINDING, std140) uniform PixelRotation {
    vec4 rotation_centre; // xyz: the light's centre, camera-relative
    vec4 rotation_axis;   // xyz: unit axis
    uvec4 rotation_seed;  // x: hash32 of the light's rotation seed; y: the run's first pixel
    vec4 rotation_angles[128];
};

uint hash32(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    return x ^ (x >> 16);
}

// (cos, sin) of the angle of the run's view sample `i` (a batch of view
// samples starts at pixel rotation_seed.y).
vec2 pixel_angle(uint i) {
    uint k = hash32((i + rotation_seed.y) ^ rotation_seed.x) >> 24;
    vec4 two = rotation_angles[k >> 1];
    return (k & 1u) != 0u ? two.zw : two.xy;
}

// The turn back by the angle cs = (cos, sin) about the axis, as a matrix
// (built once per view sample: each point then costs 9 products).
mat3 unrotation(vec2 cs) {
    float c = cs.x, s = -cs.y, t = 1.0 - c;
    vec3 w = rotation_axis.xyz;
    return mat3(
        vec3(t * w.x * w.x + c, t * w.x * w.y + s * w.z, t * w.x * w.z - s * w.y),
        vec3(t * w.x * w.y - s * w.z, t * w.y * w.y + c, t * w.y * w.z + s * w.x),
        vec3(t * w.x * w.z + s * w.y, t * w.y * w.z - s * w.x, t * w.z * w.z + c));
}
// Point v turned back about the axis through the light's centre.
vec3 unrotate_point(vec3 v, mat3 m) {
    vec3 o = rotation_centre.xyz;
    return o + m * (v - o);
}

#endif
