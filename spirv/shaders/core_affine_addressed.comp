#version 460
// y = a·x + b over buffers reached by device address, so either may exceed
// maxStorageBufferRange. A core test kernel for large buffers.
#include "common.glsl"
#include "address.glsl"

layout(local_size_x = 64) in;

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
