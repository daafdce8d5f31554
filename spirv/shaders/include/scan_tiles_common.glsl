// Shared by scan_tiles_reduce.comp and scan_tiles_apply.comp (the GPUs' scan,
// engine/src/primitives/scan.rs): a workgroup owns a tile of SCAN_TILE
// consecutive values, read and written by neighbouring invocations at
// neighbouring addresses, and scans across its invocations in shared memory.
#ifndef SRUG_SCAN_TILES_COMMON_GLSL
#define SRUG_SCAN_TILES_COMMON_GLSL
// 128 invocations and 8.75 KiB of shared memory: within every Vulkan device's minimum limits.
#define WORKGROUP_SIZE_X 128
#include "common.glsl"
#include "address.glsl"

// Values per invocation and per tile. Keep in sync with engine/src/primitives/scan.rs `SCAN_TILE`.
#define SCAN_TILE_ITEMS 16u
#define SCAN_TILE (WORKGROUP_SIZE_X * SCAN_TILE_ITEMS)

// Keep in sync with engine/src/primitives/scan.rs `ScanPush`.
layout(push_constant) uniform ScanPush {
    uvec2 data;  // uint[count], scanned in place
    uvec2 sums;  // uint[ceil(count / SCAN_TILE)], one per tile
    uint count;
    uint has_sums;  // scan_tiles_apply.comp: whether `sums` holds scanned offsets
    uint run;       // unread here: a tile is SCAN_TILE values
    uint pad;
} pc;

shared uint partial[WORKGROUP_SIZE_X];

// The exclusive prefix of `value` over the workgroup's invocations (wrapping
// sums), and in `total` the sum of all. Every invocation must call it.
uint workgroup_exclusive_scan(uint value, out uint total) {
    uint t = gl_LocalInvocationID.x;
    partial[t] = value;
    barrier();
    for (uint stride = 1u; stride < WORKGROUP_SIZE_X; stride <<= 1u) {
        uint add = t >= stride ? partial[t - stride] : 0u;
        barrier();
        partial[t] += add;
        barrier();
    }
    total = partial[WORKGROUP_SIZE_X - 1u];
    return partial[t] - value;
}

#endif
