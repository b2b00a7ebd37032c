#version 450
// Scan kernel, texel-buffer loads (lavapipe); body in scan_reduce.glsl.
#extension GL_GOOGLE_include_directive : require
#define SCAN_TEXEL_LOADS
#include "scan_reduce.glsl"
