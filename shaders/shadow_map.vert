#version 450
// Baseline shadow map, raster: every triangle (the GpuTriangle buffer bound
// as a vertex buffer, 16-byte stride, camera-relative vertices) seen from
// the light. Perspective (point light or light sample) with an infinite
// reversed-Z depth, or orthographic (directional light) with reversed depth
// over the scene's depth range; the fragment shader stores the light-space
// depth z, which a planar triangle interpolates exactly.

layout(location = 0) in vec3 position; // camera-relative vertex

layout(push_constant) uniform ShadowMapPush {
    vec4 origin;  // xyz: light position (camera-relative); w: 1 = orthographic
    vec4 right;   // xyz: light right; w: x scale
    vec4 up;      // xyz: light up; w: y scale
    vec4 forward; // xyz: light forward; w: x offset
    vec4 proj;    // x: y offset; y: near (perspective) or far (orthographic); z: 1 / depth range
} pc;

layout(location = 0) out float light_depth;

void main() {
    vec3 d = position - pc.origin.xyz;
    float x = dot(d, pc.right.xyz);
    float y = dot(d, pc.up.xyz);
    float z = dot(d, pc.forward.xyz);
    light_depth = z;
    if (pc.origin.w != 0.0) {
        gl_Position = vec4(x * pc.right.w + pc.forward.w, y * pc.up.w + pc.proj.x,
                           (pc.proj.y - z) * pc.proj.z, 1.0);
    } else {
        // ndc = (x / z) * scale + offset; depth near / z.
        gl_Position = vec4(x * pc.right.w + z * pc.forward.w, y * pc.up.w + z * pc.proj.x,
                           pc.proj.y, z);
    }
}
