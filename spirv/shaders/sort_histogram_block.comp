#version 460
// Digit counts of one block of BLOCK_KEYS consecutive keys per workgroup, for
// the block-digit radix sort (up to 8 bits a pass; engine/src/primitives/sort.rs,
// "block digits"): counted with shared-memory atomics, written digit-major,
// hist[digit * blocks + block], for the scan. Keys by device address.
// CPU reference: std sort (tests/tests/sort.rs).
#define BLOCK_DIGITS
#include "sort_common.glsl"

shared uint counts[RADIX];

void main() {
    uint block = block_index();
    if (block >= pc.blocks) return;  // the grid's padding: whole workgroups
    uint t = gl_LocalInvocationID.x;
    for (uint d = t; d < RADIX; d += WORKGROUP_SIZE_X) counts[d] = 0u;
    barrier();
    uint first = block * BLOCK_KEYS;
    for (uint r = 0u; r < BLOCK_ITEMS; r++) {
        uint i = first + r * WORKGROUP_SIZE_X + t;
        if (i < pc.count) atomicAdd(counts[digit_of(KEY(i))], 1u);
    }
    barrier();
    Uints hist = Uints(pc.hist);
    for (uint d = t; d < PASS_RADIX; d += WORKGROUP_SIZE_X) hist.v[d * pc.blocks + block] = counts[d];
}
