// The body of sort_histogram.comp and sort_histogram_texel.comp (see there).
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

#ifdef TEXEL_INPUT
// The input keys as an RG32UI texel-buffer view (one vector gather on lavapipe).
layout(set = 0, binding = 0) uniform usamplerBuffer keys_view;
// Clamped: lanes past the end fetch the last key (and discard it), never out of the view.
#define KEY(i) texelFetch(keys_view, int(min(i, pc.count - 1u))).xy
#else
#define KEY(i) Uvec2sIn(pc.keys_in).v[i]
#endif

uint digit_of(uvec2 key) {
    return (pc.shift < 32 ? key.x >> pc.shift : key.y >> (pc.shift - 32)) & pc.digit_mask;
}

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    uint base = block * SORT_BLOCK + t * ITEMS;
    uint dig[ITEMS];
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        dig[i] = base + i < pc.count ? digit_of(KEY(base + i)) : NONE;
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
