#version 450
// View samples, pass 2 (resolve): per pixel, the exact sample on the
// triangle the raster pass found: the pixel-centre ray (the formula of
// Camera::ray_direction, y = 0 on top) meets that triangle's plane; the
// geometric normal is flipped to face the camera. Where the raster's
// sub-pixel snapping chose a triangle that the pixel-centre ray just
// misses (next to an edge), that point lies on the plane past the edge,
// possibly inside a neighbouring solid; it is moved to the nearest point of
// the triangle, so that every view sample lies on its own triangle.

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

// The point of triangle (a, b, c) nearest to p, for p on its plane
// (Ericson, Real-Time Collision Detection, 5.1.5).
vec3 nearest_on_triangle(vec3 p, vec3 a, vec3 b, vec3 c) {
    vec3 ab = b - a, ac = c - a, ap = p - a;
    float d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return a;
    vec3 bp = p - b;
    float d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return b;
    float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + ab * (d1 / (d1 - d3));
    vec3 cp = p - c;
    float d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return c;
    float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + ac * (d2 / (d2 - d6));
    float va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    return p; // inside: the ray-plane point itself
}

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
        vec3 p = nearest_on_triangle(dir * (dot(n, v0) / dn), v0, v1, v2);
        if (dn > 0.0) {
            n = -n;
        }
        s.position_triangle = vec4(p, uintBitsToFloat(t));
        s.normal_flags = vec4(n, uintBitsToFloat(VIEW_SAMPLE_VALID));
    }
    samples[pixel] = s;
}
