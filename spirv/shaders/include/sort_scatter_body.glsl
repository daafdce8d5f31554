// The body of sort_scatter.comp and sort_scatter_texel.comp (see there).
#define SORT_VALUES
#include "sort_common.glsl"

void main() {
    uint me = invocation();
    // After the scan: where this invocation's first key of each digit goes.
    uint next[RADIX];
    Uints hist = Uints(pc.hist);
    UNROLL_RADIX for (uint d = 0; d < PASS_RADIX; d++) next[d] = hist.v[d * invocations() + me];
    uint run = run_length();
    uint end = min(me * run + run, pc.count);
    for (uint i = me * run; i < end; i++) {
        uvec2 key = KEY(i);
        uint digit = digit_of(key);
#ifdef WIDE_DIGITS
        uint dst = next[digit]++;
#else
        // next[digit] without a dynamic index (registers only), then advance it.
        uint dst = 0u;
        [[unroll]] for (uint d = 0; d < RADIX; d++) {
            bool here = digit == d;
            dst = here ? next[d] : dst;
            next[d] += here ? 1u : 0u;
        }
#endif
        Uvec2sOut(pc.keys_out).v[dst] = key;
        UintsOut(pc.values_out).v[dst] = VALUE(i);
    }
}
