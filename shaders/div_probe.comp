#version 450
// Division probe for tests/vulkan.rs: q[i] = div_rn(a[i], b[i]), which the
// test compares with the CPU's IEEE a / b bit for bit.
#extension GL_GOOGLE_include_directive : require

#include "exact_div.glsl"

layout(local_size_x = 64) in;

layout(push_constant) uniform Push { uint n; };

layout(set = 0, binding = 0) readonly buffer Pairs { vec2 pairs[]; };
layout(set = 0, binding = 1) writeonly buffer Quotients { float q[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= n) {
        return;
    }
    q[i] = div_rn(pairs[i].x, pairs[i].y);
}
