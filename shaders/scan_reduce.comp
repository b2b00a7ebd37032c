#version 450
// Scan kernel, storage-buffer loads (GPUs); body in scan_reduce.glsl.
#extension GL_GOOGLE_include_directive : require
#include "scan_reduce.glsl"
