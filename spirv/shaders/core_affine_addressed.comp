#version 460
// y = a·x + b over buffers reached by device address, so either may exceed
// maxStorageBufferRange. A core test kernel for large buffers.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"


// Keep in sync with engine/src/gpu/selftest.rs `AffineAddressedPush`.
layout(push_constant) uniform Push {
    uvec2 x;
    uvec2 y;
    float a;
    float b;
    uint count;
    uint pad;
} pc;

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    FloatsOut(pc.y).v[i] = pc.a * FloatsIn(pc.x).v[i] + pc.b;
}
