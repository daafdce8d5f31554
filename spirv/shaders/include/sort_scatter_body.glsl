// The body of sort_scatter.comp and sort_scatter_texel.comp (see there).
#define SORT_VALUES
#include "sort_common.glsl"

void main() {
    uint me = invocation();
    // After the scan: where this invocation's first key of each digit goes.
    uint next[RADIX];
    Uints hist = Uints(pc.hist);
    [[unroll]] for (uint d = 0; d < RADIX; d++) next[d] = hist.v[d * invocations() + me];
    uint end = min(me * ITEMS + ITEMS, pc.count);
    for (uint i = me * ITEMS; i < end; i++) {
        uvec2 key = KEY(i);
        uint digit = digit_of(key);
        // next[digit] without a dynamic index (registers only), then advance it.
        uint dst = 0u;
        [[unroll]] for (uint d = 0; d < RADIX; d++) {
            bool here = digit == d;
            dst = here ? next[d] : dst;
            next[d] += here ? 1u : 0u;
        }
        Uvec2sOut(pc.keys_out).v[dst] = key;
        UintsOut(pc.values_out).v[dst] = VALUE(i);
    }
}
