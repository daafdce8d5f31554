#version 460
// Radix sort pass, step 3 (after the histogram scan): stable scatter.
// Each thread owns ITEMS consecutive keys; per-digit counts are scanned across
// the workgroup's threads in shared memory, so equal digits keep their order.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

#define ITEMS 16
#define SORT_BLOCK (WORKGROUP_SIZE_X * ITEMS)
#define RADIX 16

// Keep in sync with engine/src/splat/sort.rs `SortPush`.
layout(push_constant) uniform Push {
    uvec2 keys_in;
    uvec2 values_in;
    uvec2 keys_out;
    uvec2 values_out;
    uvec2 hist;
    uint count;
    uint shift;
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
    uvec2 k[ITEMS];
    uint local_count[RADIX];
    for (uint d = 0; d < RADIX; d++) local_count[d] = 0;
    for (uint i = 0; i < ITEMS; i++) {
        if (base + i < pc.count) {
            k[i] = keys.v[base + i];
            local_count[digit_of(k[i])]++;
        }
    }
    for (uint d = 0; d < RADIX; d++) table[d][t] = local_count[d];
    barrier();
    // Exclusive scan of each digit's row across threads (one thread per digit).
    if (t < RADIX) {
        uint running = Uints(pc.hist).v[t * pc.blocks + block];
        for (uint j = 0; j < WORKGROUP_SIZE_X; j++) {
            uint c = table[t][j];
            table[t][j] = running;
            running += c;
        }
    }
    barrier();
    uint next[RADIX];
    for (uint d = 0; d < RADIX; d++) next[d] = table[d][t];
    UintsIn values = UintsIn(pc.values_in);
    for (uint i = 0; i < ITEMS; i++) {
        if (base + i < pc.count) {
            uint d = digit_of(k[i]);
            uint dst = next[d]++;
            Uvec2sOut(pc.keys_out).v[dst] = k[i];
            UintsOut(pc.values_out).v[dst] = values.v[base + i];
        }
    }
}
