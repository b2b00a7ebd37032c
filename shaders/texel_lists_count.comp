#version 450
// Per view sample facing the light, its light texel; an atomic
// counter per texel counts the samples and gives each its index in the list.
// Twin: cpu::texel_lists::build_texel_lists.
#extension GL_GOOGLE_include_directive : require
#include "shadow_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;

layout(set = 0, binding = 0) readonly buffer Samples { GpuViewSample samples[]; };
layout(set = 0, binding = 1) uniform Faces { LightFace faces[6]; }; // read alike: a uniform buffer
layout(set = 0, binding = 2) buffer Counts { uint counts[]; };
layout(set = 0, binding = 3) writeonly buffer SampleTexel { uint sample_texel[]; };
layout(set = 0, binding = 4) writeonly buffer SampleLocal { uint sample_local[]; };
// Per tile its longest list, then the tiles' occupancy bits (occupancy_word).
layout(set = 0, binding = 5) buffer TileMaxLen { uint tile_max_len[]; };

void main() {
    uint i = linear_invocation();
    if (i >= pc.sizes.x) {
        return;
    }
    GpuViewSample s = samples[i];
    vec3 p = sample_position(s);
    uint f;
    vec3 xyz;
    uint texel = NOT_LISTED;
    uint local = 0u;
    if ((sample_flags(s) & VIEW_SAMPLE_VALID) != 0u && faces_light(p, sample_normal(s))
        && project_to_face(p, f, xyz)) {
        uint res = pc.sizes.z;
        uvec2 t = texel_of(faces[f].window, xyz.x, xyz.y, res);
        texel = texel_index(f, t);
        local = atomicAdd(counts[texel], 1u);
        uvec2 tt = t / TILE;
        atomicMax(tile_max_len[f * pc.more.z + tt.y * pc.more.y + tt.x], local + 1u);
        if (local == 0u) {
            atomicOr(tile_max_len[occupancy_word(f, tt.y, tt.x / 32u)], 1u << (tt.x % 32u));
        }
    }
    sample_texel[i] = texel;
    sample_local[i] = local;
}
