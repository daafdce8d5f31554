#version 460
// Exclusive prefix sum of uints on GPUs, step 2: each workgroup rewrites its
// tile in place as the exclusive prefix, starting from the tile's scanned sum
// (sums[tile]; 0 when `has_sums` is 0, i.e. when everything fits one tile).
// The tile goes through shared memory: read and written by neighbouring
// invocations at neighbouring addresses, scanned there by each invocation
// over SCAN_TILE_ITEMS consecutive values (one padding word every 32 keeps
// those reads on distinct banks) and across invocations. See
// scan_tiles_reduce.comp. CPU twin: engine/src/primitives/scan.rs `exclusive_scan_cpu`.
#include "scan_tiles_common.glsl"

shared uint tile_values[SCAN_TILE + SCAN_TILE / 32u];

uint padded(uint i) {
    return i + (i >> 5u);
}

void main() {
    uint tile = block_index();
    // The grid's padding (whole workgroups) returns before tile * SCAN_TILE could wrap (count ≥ 1).
    if (tile > (pc.count - 1u) / SCAN_TILE) return;
    uint first = tile * SCAN_TILE;
    Uints data = Uints(pc.data);
    uint t = gl_LocalInvocationID.x;
    for (uint j = 0u; j < SCAN_TILE_ITEMS; j++) {
        uint i = j * WORKGROUP_SIZE_X + t;
        tile_values[padded(i)] = first + i < pc.count ? data.v[first + i] : 0u;
    }
    barrier();
    uint sum = 0u;
    for (uint k = 0u; k < SCAN_TILE_ITEMS; k++) sum += tile_values[padded(t * SCAN_TILE_ITEMS + k)];
    uint total;
    uint running = workgroup_exclusive_scan(sum, total) + (pc.has_sums != 0u ? Uints(pc.sums).v[tile] : 0u);
    for (uint k = 0u; k < SCAN_TILE_ITEMS; k++) {
        uint at = padded(t * SCAN_TILE_ITEMS + k);
        uint value = tile_values[at];
        tile_values[at] = running;
        running += value;
    }
    barrier();
    for (uint j = 0u; j < SCAN_TILE_ITEMS; j++) {
        uint i = j * WORKGROUP_SIZE_X + t;
        if (first + i < pc.count) data.v[first + i] = tile_values[padded(i)];
    }
}
