#version 450
// View samples, pass 2 (resolve): per pixel, the exact sample on the
// triangle the raster pass found: the pixel-centre ray (the formula of
// Camera::ray_direction, y = 0 on top) meets that triangle's plane; the
// geometric normal is flipped to face the camera.

#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

// Per pixel (y * width + x): triangle id + 1, 0 for nothing seen.
layout(set = 0, binding = 0) uniform usamplerBuffer pixel_ids;
// GpuTriangle as three RGBA32F texels (xyz: vertex).
layout(set = 0, binding = 1) uniform samplerBuffer triangles;
layout(set = 0, binding = 2, std430) writeonly buffer Samples {
    GpuViewSample samples[];
};

layout(push_constant) uniform ResolvePush {
    vec4 right;   // xyz: camera right; w: tan(fov/2) * aspect
    vec4 up;      // xyz: camera up; w: tan(fov/2)
    vec4 forward; // xyz: camera forward
    uvec4 sizes;  // x: width; y: height; z: triangles
} pc;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = gl_GlobalInvocationID.y;
    if (x >= pc.sizes.x || y >= pc.sizes.y) {
        return;
    }
    uint pixel = y * pc.sizes.x + x;
    uint id = texelFetch(pixel_ids, int(pixel)).x;
    GpuViewSample s;
    s.position_triangle = vec4(0.0);
    s.normal_flags = vec4(0.0);
    if (id != 0u && id <= pc.sizes.z) {
        uint t = id - 1u;
        vec3 v0 = texelFetch(triangles, int(3u * t)).xyz;
        vec3 v1 = texelFetch(triangles, int(3u * t + 1u)).xyz;
        vec3 v2 = texelFetch(triangles, int(3u * t + 2u)).xyz;
        float sx = ((float(x) + 0.5) / float(pc.sizes.x) * 2.0 - 1.0) * pc.right.w;
        float sy = (1.0 - (float(y) + 0.5) / float(pc.sizes.y) * 2.0) * pc.up.w;
        vec3 dir = normalize(pc.forward.xyz + pc.right.xyz * sx + pc.up.xyz * sy);
        vec3 n = normalize(cross(v1 - v0, v2 - v0));
        float dn = dot(n, dir);
        // The ray from the eye (the origin) meets the plane dot(n, p) = dot(n, v0).
        vec3 p = dir * (dot(n, v0) / dn);
        if (dn > 0.0) {
            n = -n;
        }
        s.position_triangle = vec4(p, uintBitsToFloat(t));
        s.normal_flags = vec4(n, uintBitsToFloat(VIEW_SAMPLE_VALID));
    }
    samples[pixel] = s;
}
