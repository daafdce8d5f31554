// The body of sort_scatter.comp and sort_scatter_texel.comp (see there).
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
        uvec4 v = texelFetch(value_quads_view, int(i / 4u));
        uvec2 k[4] = uvec2[4](k01.xy, k01.zw, k23.xy, k23.zw);
        [[unroll]] for (uint j = 0u; j < 4u; j++) {
            uint dst = next[digit_of(k[j])]++;
            keys_out.v[dst] = packUint2x32(k[j]);
            UintsOut(pc.values_out).v[dst] = v[j];
        }
    }
    for (; i < end; i++) {
        uvec2 key = KEY(i);
        uint dst = next[digit_of(key)]++;
        keys_out.v[dst] = packUint2x32(key);
        UintsOut(pc.values_out).v[dst] = VALUE(i);
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
        keys_out.v[dst] = packUint2x32(key);
        UintsOut(pc.values_out).v[dst] = VALUE(i);
    }
#endif
}
