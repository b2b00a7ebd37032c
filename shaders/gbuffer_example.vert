#version 450
// examples/gbuffer.rs, the renderer's own G-buffer pass: camera-relative
// vertices (three per triangle, non-indexed) through an infinite
// reversed-Z perspective whose rows the renderer computes. Not used by the
// library.

layout(location = 0) in vec3 position;

layout(push_constant) uniform Projection {
    vec4 right;   // xyz: right / (tan(fov/2) * aspect)
    vec4 down;    // xyz: -up / tan(fov/2)
    vec4 forward; // xyz: forward; w: near
} pc;

layout(location = 0) flat out uint triangle;

void main() {
    float z = dot(position, pc.forward.xyz);
    gl_Position = vec4(dot(position, pc.right.xyz), dot(position, pc.down.xyz), pc.forward.w, z);
    triangle = uint(gl_VertexIndex) / 3u;
}
