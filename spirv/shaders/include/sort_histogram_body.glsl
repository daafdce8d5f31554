// The body of sort_histogram.comp and sort_histogram_texel.comp (see there).
#include "sort_common.glsl"

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    uint base = block * SORT_BLOCK + t * ITEMS;
    uint dig[ITEMS];
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        dig[i] = base + i < pc.count ? digit_of(KEY(base + i)) : NONE;
    }
    store_digit_counts(dig, t);
    barrier();
    if (t < RADIX) {
        uint total = 0;
        for (uint j = 0; j < WORKGROUP_SIZE_X; j++) total += table[t][j];
        Uints(pc.hist).v[t * pc.blocks + block] = total;
    }
}
