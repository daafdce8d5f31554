#version 460
// Floor probe for sort passes: every (key, value) pair read once through
// texel-buffer views, as the sort reads them, and (WORDS) written once by
// device address to the same index, so the destination costs nothing.
// Each invocation owns ITEMS consecutive pairs, as in the sort. A radix pass
// reads its pairs at least once and writes them at least once, so this
// bounds a pass from below on the device. With SCATTER the writes go instead
// to a random permutation's index (read from a third view): how much more a
// write costs when neighbouring pairs land far apart, as with many digits.
// CPU twin: engine/src/bench.rs `pair_move_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

// Keep in sync with engine/src/bench.rs `PAIR_MOVE_ITEMS`.
#define ITEMS 64
// 32-bit words written per pair: 3 key and value, 1 value only, 0 none (the
// pairs are only read, and each invocation writes the xor of what it read).
// Keep in sync with engine/src/bench.rs `PairWrites`.
layout(constant_id = 0) const uint WORDS = 3u;
layout(constant_id = 1) const bool SCATTER = false;

// Keep in sync with engine/src/bench.rs `PairMovePush`.
layout(push_constant) uniform PairMovePush {
    uvec2 keys_out;    // uvec2[count]
    uvec2 values_out;  // uint[count]; with WORDS 0, one checksum per invocation
    uint count;
    uint blocks;
} pc;

layout(set = 0, binding = 0) uniform utextureBuffer keys_view;    // RG32UI
layout(set = 0, binding = 1) uniform utextureBuffer values_view;  // R32UI
layout(set = 0, binding = 2) uniform utextureBuffer dest_view;    // R32UI, a permutation (SCATTER)

void main() {
    uint me = block_index() * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
    uint sum = 0u;
    uint end = min(me * ITEMS + ITEMS, pc.count);
    for (uint i = me * ITEMS; i < end; i++) {
        uvec2 key = texelFetch(keys_view, int(i)).xy;
        uint value = texelFetch(values_view, int(i)).x;
        uint dst = SCATTER ? texelFetch(dest_view, int(i)).x : i;
        if (WORDS == 3u) Uvec2sOut(pc.keys_out).v[dst] = key;
        if (WORDS != 0u) UintsOut(pc.values_out).v[dst] = value;
        sum ^= key.x ^ key.y ^ value;
    }
    // Only invocations that own pairs write, so `values_out` (count words) holds every checksum.
    if (WORDS == 0u && me * ITEMS < pc.count) UintsOut(pc.values_out).v[me] = sum;
}
