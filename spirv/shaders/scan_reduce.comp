#version 460
// Exclusive prefix sum of uints, step 1: each invocation sums its `run`
// consecutive values (push constant) into sums[invocation]. The sums are scanned the same way
// (recursively) and scan_apply.comp writes the prefixes. Each invocation
// works alone, in registers: no shared memory, no subgroup operations, no
// workgroup waiting on another (on CPU implementations such as lavapipe,
// shared-memory accesses indexed by lane are loops over the lanes).
// CPU twin: engine/src/primitives/scan.rs `exclusive_scan_cpu`.
#include "scan_common.glsl"

void main() {
    uint me = linear_index();
    // Runs past the last (the grid's padding) return before me * run could wrap (count ≥ 1).
    if (me > (pc.count - 1u) / pc.run) return;
    uint start = me * pc.run;
    uint end = start + min(pc.run, pc.count - start);
    Uints data = Uints(pc.data);
    uint total = 0u;
    for (uint i = start; i < end; i++) total += data.v[i];
    Uints(pc.sums).v[me] = total;
}
