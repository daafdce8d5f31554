#version 460
// Vulkan-core check of texel-buffer bindings: copies `count` elements of a
// textureBuffer view (R32F or R16F, widened to fp32 by the fetch) to a float
// buffer. Host and CPU twin: tests/tests/gpu_core.rs `texel_buffer_views`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"

layout(set = 0, binding = 0) uniform textureBuffer src;
layout(std430, set = 0, binding = 1) writeonly buffer Dst { float dst[]; };

layout(push_constant) uniform Push {
    uint count;
} pc;

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    dst[i] = texelFetch(src, int(i)).r;
}
