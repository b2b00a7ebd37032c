#version 450
// Probe for tests/vulkan.rs: each workgroup writes its spread index
// (shadow_common.glsl: spread_workgroup) at its own index, which the test
// compares with the twin, gpu::dispatch::spread_index.
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
layout(local_size_x = 1) in;

layout(set = 0, binding = 0) writeonly buffer Spread { uint spread[]; };

void main() {
    spread[workgroup_index()] = spread_workgroup();
}
