#version 450
// View samples, pass 1 (raster): every triangle of the non-indexed draw
// (vertex i = vertex i % 3 of triangle i / 3, read from the GpuTriangle
// buffer bound as a vertex buffer with a 16-byte stride) projected with an
// infinite reversed-Z perspective; the fragment shader writes its id.
//
// Vertices are camera-relative, so the eye is the origin and the view
// transform is three dot products with the camera basis.

#include "view_ray.glsl"

layout(location = 0) in vec3 position; // camera-relative vertex

layout(push_constant) uniform RasterPush {
    vec4 right;   // xyz: camera right / (tan(fov/2) * aspect)
    vec4 down;    // xyz: -camera up / tan(fov/2) (framebuffer y grows downwards)
    vec4 forward; // xyz: camera forward; w: near plane distance
    ViewRay ray;  // the fragment shader's alpha test
} pc;

layout(location = 0) flat out uint triangle_id;

void main() {
    float z = dot(position, pc.forward.xyz);
    // Reversed infinite depth: z_ndc = near / z, 1 at the near plane, -> 0 far away.
    gl_Position = vec4(dot(position, pc.right.xyz), dot(position, pc.down.xyz), pc.forward.w, z);
    triangle_id = uint(gl_VertexIndex) / 3u;
}
