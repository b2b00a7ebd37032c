// View samples: the exact sample of a pixel on the triangle the raster
// found (view_samples_resolve.comp), which the raster's alpha test
// (view_samples.frag) evaluates too, with the same f32 arithmetic.
#ifndef AFS_VIEW_RAY_GLSL
#define AFS_VIEW_RAY_GLSL

// The camera as the pixel rays need it.
struct ViewRay {
    vec4 right;   // xyz: camera right; w: tan(fov/2) * aspect
    vec4 up;      // xyz: camera up; w: tan(fov/2)
    vec4 forward; // xyz: camera forward
    uvec4 sizes;  // x: width; y: height; z: triangles; w: 1 when some triangle is alpha-tested
};

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

// Pixel (x, y)'s sample on triangle (v0, v1, v2): the pixel-centre ray
// (the formula of Camera::ray_direction, y = 0 on top) meets the
// triangle's plane, moved to the nearest point of the triangle (the
// raster's sub-pixel snapping may pick a triangle the ray just misses);
// n: the unit geometric normal, facing the camera.
vec3 pixel_sample(ViewRay vr, uint x, uint y, vec3 v0, vec3 v1, vec3 v2, out vec3 n) {
    float sx = ((float(x) + 0.5) / float(vr.sizes.x) * 2.0 - 1.0) * vr.right.w;
    float sy = (1.0 - (float(y) + 0.5) / float(vr.sizes.y) * 2.0) * vr.up.w;
    vec3 dir = normalize(vr.forward.xyz + vr.right.xyz * sx + vr.up.xyz * sy);
    n = normalize(cross(v1 - v0, v2 - v0));
    float dn = dot(n, dir);
    // The ray from the eye (the origin) meets the plane dot(n, p) = dot(n, v0).
    vec3 p = nearest_on_triangle(dir * (dot(n, v0) / dn), v0, v1, v2);
    if (dn > 0.0) {
        n = -n;
    }
    return p;
}

#endif
