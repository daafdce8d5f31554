#version 460
// y = a·x + b over buffers reached by device address, so either may exceed
// maxStorageBufferRange. A core test kernel for large buffers.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#define SRUG_ADDRESS_64
#include "address.glsl"


// Host mirror: gpu/src/selftest.rs `AffineAddressedPush` (its layout is checked against this block).
layout(push_constant) uniform AddressedPush {
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
    // 64-bit addresses: the test's buffers exceed 4 GiB on devices that bind 4 GiB.
    FloatOut(element_address(pc.y, i, 4)).v = pc.a * FloatIn(element_address(pc.x, i, 4)).v + pc.b;
}
