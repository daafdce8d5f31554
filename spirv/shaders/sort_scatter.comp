#version 460
// Radix sort pass, step 3 (after the histogram scan): stable scatter.
// Each thread owns ITEMS consecutive keys. Per-digit counts and each item's
// rank among earlier equal digits come from fully unrolled compare-and-add
// over the thread's own items (registers only: dynamically indexed private
// arrays are slow on CPU implementations such as lavapipe); per-digit counts
// are scanned across the workgroup's threads in shared memory, so equal
// digits keep their order.
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
    uint dig[ITEMS];
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        bool valid = base + i < pc.count;
        k[i] = valid ? keys.v[base + i] : uvec2(0u);
        dig[i] = valid ? digit_of(k[i]) : NONE;
    }
    [[unroll]] for (uint d = 0; d < RADIX; d++) {
        uint c = 0;
        [[unroll]] for (uint i = 0; i < ITEMS; i++) c += dig[i] == d ? 1u : 0u;
        table[d][t] = c;
    }
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
    UintsIn values = UintsIn(pc.values_in);
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        if (dig[i] != NONE) {
            uint earlier = 0;
            [[unroll]] for (uint j = 0; j < i; j++) earlier += dig[j] == dig[i] ? 1u : 0u;
            uint dst = table[dig[i]][t] + earlier;
            Uvec2sOut(pc.keys_out).v[dst] = k[i];
            UintsOut(pc.values_out).v[dst] = values.v[base + i];
        }
    }
}
