#version 450
// View samples, pass 1 (raster): the id + 1 of the nearest triangle per
// pixel centre (0 where nothing is seen, the clear value). An
// alpha-tested triangle is seen only where it is opaque at the pixel's
// sample (view_ray.glsl, the point the resolve will compute; coverage:
// alpha_common.glsl): elsewhere the fragment is discarded, so the raster
// keeps what lies behind its holes.
#include "common.glsl"
#include "view_ray.glsl"
#include "alpha_common.glsl"

layout(location = 0) flat in uint triangle_id;
layout(location = 0) out uint id_plus_one;

layout(push_constant) uniform RasterPush {
    vec4 right;
    vec4 down;
    vec4 forward;
    ViewRay ray;
} pc;

layout(set = 0, binding = 0) uniform usamplerBuffer triangles_tb; // GpuTriangle: 3 RGBA32UI texels
layout(set = 0, binding = 1) uniform usamplerBuffer alpha_records;
layout(set = 0, binding = 2) uniform usamplerBuffer alpha_textures;
layout(set = 0, binding = 3) uniform usamplerBuffer alpha_texels;

// OPAQUE=1 (build.rs), for frames without alpha-tested triangles: no
// discard, so the depth test runs before the shader. Lavapipe then skips
// the hidden fragments (ToyCar at 512²: raster 62 -> 30 ms); with a
// discard it must shade every fragment before testing its depth.
#ifndef OPAQUE
#define OPAQUE 0
#endif
#if OPAQUE
layout(early_fragment_tests) in;
#endif

void main() {
#if !OPAQUE
    if (pc.ray.sizes.w != 0u) {
        uint t = triangle_id;
        uvec4 t0 = texelFetch(triangles_tb, int(3u * t));
        if ((t0.w & TRIANGLE_ALPHA) != 0u) {
            vec3 v0 = uintBitsToFloat(t0.xyz);
            vec3 v1 = uintBitsToFloat(texelFetch(triangles_tb, int(3u * t + 1u)).xyz);
            uvec4 t2 = texelFetch(triangles_tb, int(3u * t + 2u));
            vec3 v2 = uintBitsToFloat(t2.xyz);
            uvec2 pixel = uvec2(gl_FragCoord.xy);
            vec3 n;
            vec3 p = pixel_sample(pc.ray, pixel.x, pixel.y, v0, v1, v2, n);
            vec2 b = point_barycentrics(p, v0, v1, v2);
            if (!alpha_opaque_at(alpha_records, alpha_textures, alpha_texels, t2.w, b)) {
                discard;
            }
        }
    }
#endif
    id_plus_one = triangle_id + 1u;
}
