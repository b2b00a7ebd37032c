#version 450
// A light's visibility into a caller's R32_SFLOAT storage image (GENERAL
// layout): view sample y * width + x to texel (x, y) (visibility_out.glsl).
#extension GL_GOOGLE_include_directive : require
#include "visibility_out.glsl"

layout(set = 0, binding = 1, r32f) writeonly uniform image2D target;

void main() {
    uint i = linear_invocation();
    uint width = uint(imageSize(target).x);
    if (i >= pc.sizes.x || width == 0u) {
        return;
    }
    imageStore(target, ivec2(i % width, i / width), vec4(visibility_of(i)));
}
