#version 460
// y = a·x + b (MODE 0) or y = a·x² + b (MODE 1) over bound buffers.
// A core test kernel: push constants, a specialization constant, two bindings.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"

layout(constant_id = 0) const uint MODE = 0;

layout(std430, set = 0, binding = 0) readonly buffer Input { float x[]; } src;
layout(std430, set = 0, binding = 1) writeonly buffer Output { float y[]; } dst;

// Keep in sync with engine/src/gpu/selftest.rs `AffinePush`.
layout(push_constant) uniform Push {
    float a;
    float b;
    uint count;
    uint pad;
} pc;

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    float x = src.x[i];
    dst.y[i] = MODE == 0 ? pc.a * x + pc.b : pc.a * x * x + pc.b;
}
