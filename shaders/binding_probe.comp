#version 450
// Binding probe for tests/vulkan.rs: one resource of every descriptor kind
// the binding helper supports, so a wrong descriptor type, view or layout
// shows up as a wrong value or a validation error.
//   dst_texel[i] = src_texel[i] + src[i] + frame.add   (i < n)
//   image[i % 4, i / 4 % 4, i / 16] = uvec4(i, dst_texel[i], 0, 1)
#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(local_size_x_id = 0) in;

layout(push_constant) uniform Push { uint n; };

layout(set = 0, binding = 0) readonly buffer Src { uint src[]; };
layout(set = 0, binding = 1) uniform Add { uvec4 add; };
layout(set = 0, binding = 2) uniform usamplerBuffer src_texel;
layout(set = 0, binding = 3, r32ui) uniform writeonly uimageBuffer dst_texel;
layout(set = 0, binding = 4, rgba32ui) uniform writeonly uimage3D image;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= n) {
        return;
    }
    uint v = texelFetch(src_texel, int(i)).x + src[i] + add.x;
    imageStore(dst_texel, int(i), uvec4(v));
    imageStore(image, ivec3(i % 4u, (i / 4u) % 4u, i / 16u), uvec4(i, v, 0u, 1u));
}
