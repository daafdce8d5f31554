// The body of sort_scatter.comp and sort_scatter_texel.comp (see there).
#define SORT_VALUES
#include "sort_common.glsl"

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    uint base = block * SORT_BLOCK + t * ITEMS;
    uvec2 k[ITEMS];
    uint dig[ITEMS];
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        bool valid = base + i < pc.count;
        k[i] = valid ? KEY(base + i) : uvec2(0u);
        dig[i] = valid ? digit_of(k[i]) : NONE;
    }
    store_digit_counts(dig, t);
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
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        if (dig[i] != NONE) {
            uint earlier = 0;
            [[unroll]] for (uint j = 0; j < i; j++) earlier += dig[j] == dig[i] ? 1u : 0u;
            uint dst = table[dig[i]][t] + earlier;
            Uvec2sOut(pc.keys_out).v[dst] = k[i];
            UintsOut(pc.values_out).v[dst] = VALUE(base + i);
        }
    }
}
