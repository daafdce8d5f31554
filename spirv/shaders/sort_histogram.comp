#version 460
// Radix sort pass, step 1: per-block histogram of one 4-bit digit.
// hist[digit * blocks + block] = count (digit-major, so one exclusive scan of
// hist gives every (digit, block) its output start). No subgroup operations
// and no cross-workgroup waiting: correct for any subgroup size and without
// forward-progress guarantees. Per-thread counts come from unrolled
// compare-and-add in registers (see sort_scatter.comp), then 16 threads sum
// the rows.
// CPU reference: std sort (tests), engine/src/splat/sort.rs.
#extension GL_EXT_control_flow_attributes : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

#define ITEMS 16
#define SORT_BLOCK (WORKGROUP_SIZE_X * ITEMS)
#define RADIX 16
#define NONE 0xffffffffu

// Keep in sync with engine/src/splat/sort.rs `SortPush`.
layout(push_constant) uniform Push {
    uvec2 keys_in;    // uvec2[count] (low, high)
    uvec2 values_in;  // uint[count]
    uvec2 keys_out;
    uvec2 values_out;
    uvec2 hist;       // uint[RADIX * blocks]
    uint count;
    uint shift;       // digit = (key >> shift) & digit_mask, over the 64-bit key
    uint blocks;
    uint digit_mask;  // 15, or fewer bits on the last pass
} pc;

shared uint table[RADIX][WORKGROUP_SIZE_X];

uint digit_of(uvec2 key) {
    return (pc.shift < 32 ? key.x >> pc.shift : key.y >> (pc.shift - 32)) & pc.digit_mask;
}

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    Uvec2sIn keys = Uvec2sIn(pc.keys_in);
    uint base = block * SORT_BLOCK + t * ITEMS;
    uint dig[ITEMS];
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        dig[i] = base + i < pc.count ? digit_of(keys.v[base + i]) : NONE;
    }
    [[unroll]] for (uint d = 0; d < RADIX; d++) {
        uint c = 0;
        [[unroll]] for (uint i = 0; i < ITEMS; i++) c += dig[i] == d ? 1u : 0u;
        table[d][t] = c;
    }
    barrier();
    if (t < RADIX) {
        uint total = 0;
        for (uint j = 0; j < WORKGROUP_SIZE_X; j++) total += table[t][j];
        Uints(pc.hist).v[t * pc.blocks + block] = total;
    }
}
