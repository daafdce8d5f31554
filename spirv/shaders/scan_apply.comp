#version 460
// Exclusive prefix sum of uints, step 2: each invocation rewrites its
// SCAN_ITEMS consecutive values in place as their exclusive prefix, starting
// from its scanned sum (sums[invocation]; 0 when `has_sums` is 0, i.e. when
// everything fits one invocation). See scan_reduce.comp.
// CPU twin: engine/src/primitives/scan.rs `exclusive_scan_cpu`.
#include "scan_common.glsl"

void main() {
    uint me = linear_index();
    uint end = min(me * SCAN_ITEMS + SCAN_ITEMS, pc.count);
    if (me * SCAN_ITEMS >= end) return;
    Uints data = Uints(pc.data);
    uint running = pc.has_sums != 0u ? Uints(pc.sums).v[me] : 0u;
    for (uint i = me * SCAN_ITEMS; i < end; i++) {
        uint value = data.v[i];
        data.v[i] = running;
        running += value;
    }
}
