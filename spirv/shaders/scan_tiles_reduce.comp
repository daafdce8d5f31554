#version 460
// Exclusive prefix sum of uints on GPUs, step 1: each workgroup sums its tile
// of SCAN_TILE values (neighbouring invocations reading neighbouring values)
// into sums[tile]. The sums are scanned the same way (recursively) and
// scan_tiles_apply.comp writes the prefixes. No workgroup waits on another.
// CPU twin: engine/src/primitives/scan.rs `exclusive_scan_cpu`.
#include "scan_tiles_common.glsl"

void main() {
    uint tile = block_index();
    // The grid's padding (whole workgroups) returns before tile * SCAN_TILE could wrap (count ≥ 1).
    if (tile > (pc.count - 1u) / SCAN_TILE) return;
    uint first = tile * SCAN_TILE;
    Uints data = Uints(pc.data);
    uint t = gl_LocalInvocationID.x;
    uint sum = 0u;
    for (uint j = 0u; j < SCAN_TILE_ITEMS; j++) {
        uint i = first + j * WORKGROUP_SIZE_X + t;
        sum += i < pc.count ? data.v[i] : 0u;
    }
    uint total;
    workgroup_exclusive_scan(sum, total);
    if (t == 0u) Uints(pc.sums).v[tile] = total;
}
