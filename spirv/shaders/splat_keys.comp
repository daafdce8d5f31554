#version 460
// Splatting stage 2b: one (key, value) pair per (Gaussian, tile) it covers,
// written at the Gaussian's scanned offset. Key = tile << 32 | depth bits
// (positive floats order like unsigned ints); value = Gaussian index.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "splat.glsl"

void main() {
    uint i = linear_index();
    if (i >= frame.counts.x) return;
    Splat s = Splats(frame.scene5.zw).v[i];
    uint offset = Uints(frame.work0.zw).v[i];
    uint depth_bits = floatBitsToUint(s.head.z);
    Uvec2s keys = Uvec2s(frame.work1.xy);
    Uints values = Uints(frame.work1.zw);
    for (uint y = s.rect.y; y < s.rect.w; y++) {
        for (uint x = s.rect.x; x < s.rect.z; x++) {
            keys.v[offset] = uvec2(depth_bits, y * frame.size.z + x);
            values.v[offset] = i;
            offset++;
        }
    }
}
