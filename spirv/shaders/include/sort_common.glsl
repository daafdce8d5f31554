// Shared by the radix sort kernels (sort_histogram_body.glsl,
// sort_scatter_body.glsl): block layout, push constants, the digit, and how
// keys (and, with SORT_VALUES, values) are read — through texel-buffer views
// with TEXEL_INPUT, else by device address.
//
// Every invocation owns ITEMS consecutive keys and keeps its own 16 digit
// counts in registers (unrolled compare-and-add), or with WIDE_DIGITS its
// share of the keys and up to 2048 counts in an array indexed by the digit
// (cheap where invocations are CPU lanes); the histogram is per
// invocation, digit-major: hist[digit * invocations + invocation]. Nothing
// crosses lanes or goes through shared memory: on CPU implementations such
// as lavapipe every shared-memory or cross-lane access with a lane-dependent
// index is a loop over the lanes (they were two thirds of the earlier
// per-workgroup scatter).
#ifndef SRUG_SORT_COMMON_GLSL
#define SRUG_SORT_COMMON_GLSL
#extension GL_EXT_control_flow_attributes : require
#if defined(WIDE_DIGITS)
#define WORKGROUP_SIZE_X 8
#elif defined(BLOCK_DIGITS)
// Block digits (sort_*_block.comp): a workgroup ranks BLOCK_KEYS keys in
// shared memory and writes each digit's run of them together.
#define WORKGROUP_SIZE_X 128
// Keys per invocation (engine/src/primitives/sort.rs `block_items`: as many
// as the scatter's shared memory allows).
layout(constant_id = 1) const uint BLOCK_ITEMS = 8u;
#define BLOCK_KEYS (WORKGROUP_SIZE_X * BLOCK_ITEMS)
#else
#define WORKGROUP_SIZE_X 64
#endif
#define SRUG_WORDS_64
#include "common.glsl"
#include "address.glsl"

// Keys per invocation (engine/src/primitives/sort.rs `sort_items`: more on CPU
// devices, where fewer, longer invocations shrink the histogram and its scan).
layout(constant_id = 0) const uint ITEMS = 64u;
#ifdef WIDE_DIGITS
// Wide digits (engine/src/primitives/sort.rs `WIDE_DIGIT_BITS`): up to 11
// bits per pass, the counts in an array indexed by the digit; this pass's
// radix is digit_mask + 1.
#define RADIX 2048
#define PASS_RADIX (pc.digit_mask + 1u)
#define UNROLL_RADIX
#elif defined(BLOCK_DIGITS)
// Block digits (engine/src/primitives/sort.rs `BLOCK_DIGIT_BITS`): up to 8 bits a pass.
#define RADIX 256
#define PASS_RADIX (pc.digit_mask + 1u)
#else
#define RADIX 16
#define PASS_RADIX RADIX
#define UNROLL_RADIX [[unroll]]
#endif

// Keep in sync with engine/src/splat/sort.rs `SortPush`.
layout(push_constant) uniform SortPush {
    uvec2 keys_in;    // uvec2[count] (low, high)
    uvec2 values_in;  // uint[count]
    uvec2 keys_out;
    uvec2 values_out;
    uvec2 hist;       // uint[RADIX * blocks * WORKGROUP_SIZE_X]
    uint count;
    uint shift;       // digit = (key >> shift) & digit_mask, over the 64-bit key
    uint blocks;
    uint digit_mask;  // RADIX - 1, or fewer bits on the last pass
    // Packed passes (the scatter's PACKED_IN / PACKED_OUT): a packed word is
    // the key's sort bits above its first digit (pack_field bits), the value
    // above them and the key's top pack_high bits kept in place
    // (engine/src/primitives/sort.rs `PairPacking`).
    uint pack_drop;   // the first digit's bits, dropped from the word
    uint pack_field;  // sort bits the word keeps
    uint pack_high;   // top key bits the word keeps
    uint pack_pad;
} pc;

#ifdef TEXEL_INPUT
// Keys (RG32UI, binding 0) and values (R32UI, binding 1) as texel-buffer views:
// one vector gather per fetch on lavapipe. Clamped: lanes past the end fetch
// the last element (and discard it), never outside the view.
layout(set = 0, binding = 0) uniform utextureBuffer keys_view;
#define KEY(i) texelFetch(keys_view, int(min(i, pc.count - 1u))).xy
#ifdef SORT_VALUES
layout(set = 0, binding = 1) uniform utextureBuffer values_view;
#define VALUE(i) texelFetch(values_view, int(min(i, pc.count - 1u))).x
#endif
#ifdef WIDE_DIGITS
// The same keys two per RGBA32UI texel (keys 2t and 2t + 1) and, in the
// scatter, values four per texel: on lavapipe from Mesa 25 every fetch is a
// call, so a run's keys are read two and four at a time (its start is a
// multiple of 4, `run_length`), the last few through the views above.
#ifdef SORT_VALUES
layout(set = 0, binding = 2) uniform utextureBuffer key_pairs_view;
layout(set = 0, binding = 3) uniform utextureBuffer value_quads_view;
#else
layout(set = 0, binding = 1) uniform utextureBuffer key_pairs_view;
#endif
#endif
#else
#define KEY(i) Uvec2sIn(pc.keys_in).v[i]
#define VALUE(i) UintsIn(pc.values_in).v[i]
#endif

#ifdef SORT_VALUES
// Packed passes (engine/src/primitives/sort.rs `PairPacking`): with
// PACKED_OUT each pair leaves as one 64-bit word (one store where a key and a
// value are two), with PACKED_IN it arrives as one (the values are not read).
// The first pass packs, the middle ones move words, the last one unpacks.
layout(constant_id = 2) const bool PACKED_IN = false;
layout(constant_id = 3) const bool PACKED_OUT = false;

// The word's sort bits, and the key's top bits it keeps.
uint64_t field_mask() {
    return (uint64_t(1) << pc.pack_field) - uint64_t(1);
}
uint64_t high_mask() {
    return pc.pack_high == 0u ? uint64_t(0) : ~uint64_t(0) << (64u - pc.pack_high);
}

// Writes the pair (key, value) to slot `dst`: as it came, packed or unpacked.
// With PACKED_IN `key` is the packed word and `value` unused.
void put(Uint64sOut keys_out, uint dst, uvec2 key, uint value) {
    uint64_t word = packUint2x32(key);
    if (PACKED_IN && PACKED_OUT) {
        keys_out.v[dst] = word;
    } else if (PACKED_OUT) {
        keys_out.v[dst] = ((word >> pc.pack_drop) & field_mask()) | (uint64_t(value) << pc.pack_field)
            | (word & high_mask());
    } else if (PACKED_IN) {
        keys_out.v[dst] = ((word & field_mask()) << pc.pack_drop) | (word & high_mask());
        UintsOut(pc.values_out).v[dst] = uint((word & ~high_mask()) >> pc.pack_field);
    } else {
        keys_out.v[dst] = word;
        UintsOut(pc.values_out).v[dst] = value;
    }
}
#endif

// The digit at bit `shift` of the 64-bit key; a wide digit may straddle its two words.
uint digit_of(uvec2 key) {
    uint s = pc.shift;
    uint bits = s >= 32u ? key.y >> (s - 32u) : (key.x >> s) | (s == 0u ? 0u : key.y << (32u - s));
    return bits & pc.digit_mask;
}

// This invocation's index and its histogram column: hist[digit * invocations() + invocation].
uint invocation() {
    return block_index() * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
}
uint invocations() {
    return pc.blocks * WORKGROUP_SIZE_X;
}

// Keys per invocation: ITEMS, or with wide digits the keys spread evenly over
// the dispatched invocations (the host picks the number of workgroups).
uint run_length() {
#ifdef WIDE_DIGITS
    // A multiple of 4: every run starts on a texel of key_pairs_view and value_quads_view.
    return ((pc.count + invocations() - 1u) / invocations() + 3u) & ~3u;
#else
    return ITEMS;
#endif
}

#endif
