#version 460
// Exclusive prefix sum of uints, step 2: each invocation rewrites its `run`
// consecutive values (push constant) in place as their exclusive prefix,
// starting from its scanned sum (sums[invocation]; 0 when `has_sums` is 0, i.e. when
// everything fits one invocation). See scan_reduce.comp.
// CPU twin: engine/src/primitives/scan.rs `exclusive_scan_cpu`.
#include "scan_common.glsl"

void main() {
    uint me = linear_index();
    // Runs past the last (the grid's padding) return before me * run could wrap (count ≥ 1).
    if (me > (pc.count - 1u) / pc.run) return;
    uint start = me * pc.run;
    uint end = start + min(pc.run, pc.count - start);
    Uints data = Uints(pc.data);
    uint running = pc.has_sums != 0u ? Uints(pc.sums).v[me] : 0u;
    for (uint i = start; i < end; i++) {
        uint value = data.v[i];
        data.v[i] = running;
        running += value;
    }
}
