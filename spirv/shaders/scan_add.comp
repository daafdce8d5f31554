#version 460
// Exclusive prefix sum, level three: adds each block's scanned offset.
// Block size must match scan_blocks.comp.
#define WORKGROUP_SIZE_X 256
#include "common.glsl"
#include "address.glsl"

#define SCAN_BLOCK (WORKGROUP_SIZE_X * 4)

// Keep in sync with engine/src/splat/scan.rs `ScanPush`.
layout(push_constant) uniform Push {
    uvec2 data;
    uvec2 sums;
    uint count;
    uint write_sums;
} pc;

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    uint block = i / SCAN_BLOCK;
    if (block == 0) return;
    Uints data = Uints(pc.data);
    data.v[i] += Uints(pc.sums).v[block];
}
