#version 450
// View samples, pass 2 (resolve): per pixel, the exact sample on the
// triangle the raster pass found: the pixel-centre ray (the formula of
// Camera::ray_direction, y = 0 on top) meets that triangle's plane; the
// geometric normal is flipped to face the camera. Where the raster's
// sub-pixel snapping chose a triangle that the pixel-centre ray just
// misses (next to an edge), that point lies on the plane past the edge,
// possibly inside a neighbouring solid; it is moved to the nearest point of
// the triangle, so that every view sample lies on its own triangle.
// An image whose samples pass one storage binding (lavapipe binds 128 MiB:
// 2048² pixels) is resolved in bands of rows, each dispatch binding its
// band's ranges of the id and sample buffers.

#include "common.glsl"
#include "view_ray.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

// Per pixel of the band ((y - first row) * width + x): triangle id + 1, 0
// for nothing seen.
layout(set = 0, binding = 0) uniform usamplerBuffer pixel_ids;
// GpuTriangle as three RGBA32F texels (xyz: vertex).
layout(set = 0, binding = 1) uniform samplerBuffer triangles;
layout(set = 0, binding = 2, std430) writeonly buffer Samples {
    GpuViewSample samples[];
};

layout(push_constant) uniform ResolvePush {
    ViewRay ray;
    uvec4 band; // x: the band's first row; y: its rows
} pc;

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint row = gl_GlobalInvocationID.y;
    if (x >= pc.ray.sizes.x || row >= pc.band.y) {
        return;
    }
    uint y = pc.band.x + row;
    uint pixel = row * pc.ray.sizes.x + x;
    uint id = texelFetch(pixel_ids, int(pixel)).x;
    GpuViewSample s;
    s.position_triangle = vec4(0.0);
    s.normal_flags = vec4(0.0);
    if (id != 0u && id <= pc.ray.sizes.z) {
        uint t = id - 1u;
        vec3 v0 = texelFetch(triangles, int(3u * t)).xyz;
        vec3 v1 = texelFetch(triangles, int(3u * t + 1u)).xyz;
        vec3 v2 = texelFetch(triangles, int(3u * t + 2u)).xyz;
        vec3 n;
        vec3 p = pixel_sample(pc.ray, x, y, v0, v1, v2, n);
        s.position_triangle = vec4(p, uintBitsToFloat(t));
        s.normal_flags = vec4(n, uintBitsToFloat(VIEW_SAMPLE_VALID));
    }
    samples[pixel] = s;
}
