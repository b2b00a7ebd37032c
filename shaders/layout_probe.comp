#version 450
// Layout probe for tests/layout.rs: checks that the structs of common.glsl
// and their Rust twins in src/gpu/shared.rs agree.
//
// Write direction: every scalar k of a struct gets a known value (float(base + k),
// base + k, or 0x40000000 + base + k as the bits of a float slot), written
// through the struct type, so a wrong offset or stride shows up in Rust as a
// wrong field.
// Read direction: the FrameConstants uniform and the ScanPush push constants
// that Rust filled are flattened, scalar by scalar in declaration order, into
// `flat`.
#extension GL_GOOGLE_include_directive : require

#include "common.glsl"

layout(local_size_x = 1) in;

layout(push_constant) uniform Push { ScanPush pc; };

layout(set = 0, binding = 0) writeonly buffer Samples { GpuViewSample samples[]; };
layout(set = 0, binding = 1) writeonly buffer Triangles { GpuTriangle triangles[]; };
// std140, as the uniform buffer that FrameConstants is meant for.
layout(set = 0, binding = 2, std140) writeonly buffer FrameOut { FrameConstants frame_out[]; };
layout(set = 0, binding = 3) writeonly buffer ScanOut { ScanPush scan_out[]; };
layout(set = 0, binding = 4) uniform FrameIn { FrameConstants frame_in; };
layout(set = 0, binding = 5) writeonly buffer Flat { uint flat_out[]; };

float f(uint base, uint k) { return float(base + k); }
// uint bits stored in a float slot; offset so the bits are a normal float
// (never a denormal or NaN that some path could flush).
float u(uint base, uint k) { return uintBitsToFloat(0x40000000u + base + k); }

vec4 fv(uint base, uint k) { return vec4(f(base, k), f(base, k + 1u), f(base, k + 2u), f(base, k + 3u)); }
uvec4 uv(uint base, uint k) { return uvec4(base + k, base + k + 1u, base + k + 2u, base + k + 3u); }

uint n_flat = 0u;
void put(float x) { flat_out[n_flat++] = floatBitsToUint(x); }
void put(uint x) { flat_out[n_flat++] = x; }
void put(vec4 x) { put(x.x); put(x.y); put(x.z); put(x.w); }
void put(uvec4 x) { put(x.x); put(x.y); put(x.z); put(x.w); }

void main() {
    // Two elements each, so the array stride is checked too.
    for (uint e = 0u; e < 2u; ++e) {
        uint b = 1000u + 100u * e;
        GpuViewSample s;
        s.position_triangle = vec4(f(b, 0u), f(b, 1u), f(b, 2u), u(b, 3u));
        s.normal_flags = vec4(f(b, 4u), f(b, 5u), f(b, 6u), u(b, 7u));
        samples[e] = s;

        b = 2000u + 100u * e;
        GpuTriangle t;
        t.v0_flags = vec4(f(b, 0u), f(b, 1u), f(b, 2u), u(b, 3u));
        t.v1_mesh = vec4(f(b, 4u), f(b, 5u), f(b, 6u), u(b, 7u));
        t.v2_pad = vec4(f(b, 8u), f(b, 9u), f(b, 10u), u(b, 11u));
        triangles[e] = t;

        b = 3000u + 100u * e;
        FrameConstants c;
        c.light_view_proj = mat4(fv(b, 0u), fv(b, 4u), fv(b, 8u), fv(b, 12u));
        c.light_position = vec4(f(b, 16u), f(b, 17u), f(b, 18u), u(b, 19u));
        c.light_direction = fv(b, 20u);
        c.light_extent = fv(b, 24u);
        c.light_resolution = uv(b, 28u);
        c.counts = uv(b, 32u);
        c.camera_origin = fv(b, 36u);
        frame_out[e] = c;

        b = 4000u + 100u * e;
        scan_out[e] = ScanPush(b, b + 1u, b + 2u, b + 3u);
    }

    put(frame_in.light_view_proj[0]);
    put(frame_in.light_view_proj[1]);
    put(frame_in.light_view_proj[2]);
    put(frame_in.light_view_proj[3]);
    put(frame_in.light_position);
    put(frame_in.light_direction);
    put(frame_in.light_extent);
    put(frame_in.light_resolution);
    put(frame_in.counts);
    put(frame_in.camera_origin);
    put(pc.n);
    put(pc.flags);
    put(pc.group_count);
    put(pc.groups_x);
}
