#version 460
// Exclusive prefix sum of uints, level one: each workgroup scans a block of
// SCAN_BLOCK values in place and writes the block's total to `sums`.
// Level two scans `sums` (recursively), and scan_add.comp adds it back.
// CPU twin: engine/src/splat/scan.rs `exclusive_scan_cpu`.
#define WORKGROUP_SIZE_X 256
#include "common.glsl"
#include "address.glsl"

#define ITEMS 4
#define SCAN_BLOCK (WORKGROUP_SIZE_X * ITEMS)

// Keep in sync with engine/src/splat/scan.rs `ScanPush`.
layout(push_constant) uniform Push {
    uvec2 data;  // uint[count], scanned in place
    uvec2 sums;  // uint[blocks], block totals (unused when `write_sums` is 0)
    uint count;
    uint write_sums;
} pc;

shared uint partial[2][WORKGROUP_SIZE_X];

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    uint base = block * SCAN_BLOCK + t * ITEMS;
    Uints data = Uints(pc.data);
    uint v[ITEMS];
    uint total = 0;
    for (uint i = 0; i < ITEMS; i++) {
        v[i] = base + i < pc.count ? data.v[base + i] : 0u;
        total += v[i];
    }
    // Inclusive Hillis-Steele scan of per-thread totals, double-buffered.
    partial[0][t] = total;
    barrier();
    uint src = 0;
    for (uint offset = 1; offset < WORKGROUP_SIZE_X; offset <<= 1) {
        uint x = partial[src][t];
        if (t >= offset) x += partial[src][t - offset];
        partial[1 - src][t] = x;
        src = 1 - src;
        barrier();
    }
    uint running = partial[src][t] - total;  // exclusive prefix of this thread
    for (uint i = 0; i < ITEMS; i++) {
        if (base + i < pc.count) data.v[base + i] = running;
        running += v[i];
    }
    if (pc.write_sums != 0 && t == WORKGROUP_SIZE_X - 1) {
        Uints(pc.sums).v[block] = partial[src][t];
    }
}
