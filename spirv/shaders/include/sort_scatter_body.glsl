// The body of sort_scatter.comp, sort_scatter_texel.comp and
// sort_scatter_wide_texel.comp (see there).
#define SORT_VALUES
#include "sort_common.glsl"

void main() {
    uint me = invocation();
    // Each key goes out as one 64-bit word: on lavapipe one scatter
    // instruction, where a uvec2 is two.
    Uint64sOut keys_out = Uint64sOut(pc.keys_out);
    // After the scan: where this invocation's first key of each digit goes.
    uint next[RADIX];
    Uints hist = Uints(pc.hist);
    UNROLL_RADIX for (uint d = 0; d < PASS_RADIX; d++) next[d] = hist.v[d * invocations() + me];
    uint run = run_length();
    uint end = min(me * run + run, pc.count);
#if defined(WIDE_DIGITS) && defined(TEXEL_INPUT)
    uint i = me * run;
    for (; i + 3u < end; i += 4u) {
        uvec4 k01 = texelFetch(key_pairs_view, int(i / 2u));
        uvec4 k23 = texelFetch(key_pairs_view, int(i / 2u + 1u));
        uvec4 v = PACKED_IN ? uvec4(0u) : texelFetch(value_quads_view, int(i / 4u));
        uvec2 k[4] = uvec2[4](k01.xy, k01.zw, k23.xy, k23.zw);
        [[unroll]] for (uint j = 0u; j < 4u; j++) put(keys_out, next[digit_of(k[j])]++, k[j], v[j]);
    }
    for (; i < end; i++) {
        uvec2 key = KEY(i);
        put(keys_out, next[digit_of(key)]++, key, PACKED_IN ? 0u : VALUE(i));
    }
#else
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
        put(keys_out, dst, key, PACKED_IN ? 0u : VALUE(i));
    }
#endif
}
