#version 450
// A light's visibility into a caller's storage buffer: one float per view
// sample (visibility_out.glsl).
#extension GL_GOOGLE_include_directive : require
#include "visibility_out.glsl"

layout(set = 0, binding = 1) writeonly buffer Target { float target[]; };

void main() {
    uint i = linear_invocation();
    if (i >= pc.sizes.x) {
        return;
    }
    target[i] = visibility_of(i);
}
