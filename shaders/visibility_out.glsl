// The visibility a caller's target receives (Engine::record_frame), from
// resolve_hard.comp's flags or resolve_soft.comp's fraction: what
// Engine::render's frame holds, 0 where no sample was evaluated.
#include "shadow_common.glsl"
layout(local_size_x = WORKGROUP_1D) in;
layout(constant_id = 0) const uint SOFT = 0u;

layout(set = 0, binding = 0) readonly buffer Result { uint result[]; };

float visibility_of(uint i) {
    uint r = result[i];
    if (SOFT == 0u) {
        return (r & 3u) == 3u ? 1.0 : 0.0;
    }
    return max(uintBitsToFloat(r), 0.0);
}
