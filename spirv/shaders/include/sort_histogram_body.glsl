// The body of sort_histogram.comp and sort_histogram_texel.comp (see there).
#include "sort_common.glsl"

void main() {
    uint me = invocation();
    uint counts[RADIX];
    UNROLL_RADIX for (uint d = 0; d < PASS_RADIX; d++) counts[d] = 0u;
    uint run = run_length();
    uint end = min(me * run + run, pc.count);
#if defined(WIDE_DIGITS) && defined(TEXEL_INPUT)
    uint i = me * run;
    for (; i + 1u < end; i += 2u) {
        uvec4 pair = texelFetch(key_pairs_view, int(i / 2u));
        counts[digit_of(pair.xy)]++;
        counts[digit_of(pair.zw)]++;
    }
    if (i < end) counts[digit_of(KEY(i))]++;
#else
    for (uint i = me * run; i < end; i++) {
        uint digit = digit_of(KEY(i));
#ifdef WIDE_DIGITS
        counts[digit]++;
#else
        [[unroll]] for (uint d = 0; d < RADIX; d++) counts[d] += digit == d ? 1u : 0u;
#endif
    }
#endif
    Uints hist = Uints(pc.hist);
    UNROLL_RADIX for (uint d = 0; d < PASS_RADIX; d++) hist.v[d * invocations() + me] = counts[d];
}
