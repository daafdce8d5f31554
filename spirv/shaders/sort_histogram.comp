#version 460
// Radix sort pass, step 1: per-block histogram of one 4-bit digit.
// hist[digit * blocks + block] = count (digit-major, so one exclusive scan of
// hist gives every (digit, block) its output start). No subgroup operations
// and no cross-workgroup waiting: correct for any subgroup size and without
// forward-progress guarantees.
// CPU reference: std sort (tests), engine/src/splat/sort.rs.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

#define ITEMS 16
#define SORT_BLOCK (WORKGROUP_SIZE_X * ITEMS)
#define RADIX 16

// Keep in sync with engine/src/splat/sort.rs `SortPush`.
layout(push_constant) uniform Push {
    uvec2 keys_in;    // uvec2[count] (low, high)
    uvec2 values_in;  // uint[count]
    uvec2 keys_out;
    uvec2 values_out;
    uvec2 hist;       // uint[RADIX * blocks]
    uint count;
    uint shift;       // digit = (key >> shift) & 15, over the 64-bit key
    uint blocks;
    uint digit_mask;  // 15, or fewer bits on the last pass
} pc;

shared uint counts[RADIX];

uint digit_of(uvec2 key) {
    return (pc.shift < 32 ? key.x >> pc.shift : key.y >> (pc.shift - 32)) & pc.digit_mask;
}

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    if (t < RADIX) counts[t] = 0;
    barrier();
    Uvec2sIn keys = Uvec2sIn(pc.keys_in);
    uint base = block * SORT_BLOCK;
    uint n = min(uint(SORT_BLOCK), pc.count - base);
    // Coalesced: lane t takes items t, t + 64, ...
    for (uint i = t; i < n; i += WORKGROUP_SIZE_X) atomicAdd(counts[digit_of(keys.v[base + i])], 1u);
    barrier();
    if (t < RADIX) Uints(pc.hist).v[t * pc.blocks + block] = counts[t];
}
