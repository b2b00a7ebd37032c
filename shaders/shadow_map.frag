#version 450
// Baseline shadow map, raster: the nearest caster's light-space depth per
// texel centre (the clear value, a huge depth, where nothing is drawn).

layout(location = 0) in float light_depth;
layout(location = 0) out float depth_out;

void main() {
    depth_out = light_depth;
}
