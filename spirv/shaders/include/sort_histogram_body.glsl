// The body of sort_histogram.comp and sort_histogram_texel.comp (see there).
#include "sort_common.glsl"

void main() {
    uint me = invocation();
    uint counts[RADIX];
    [[unroll]] for (uint d = 0; d < RADIX; d++) counts[d] = 0u;
    uint end = min(me * ITEMS + ITEMS, pc.count);
    for (uint i = me * ITEMS; i < end; i++) {
        uint digit = digit_of(KEY(i));
        [[unroll]] for (uint d = 0; d < RADIX; d++) counts[d] += digit == d ? 1u : 0u;
    }
    Uints hist = Uints(pc.hist);
    [[unroll]] for (uint d = 0; d < RADIX; d++) hist.v[d * invocations() + me] = counts[d];
}
