#version 460
// The stable scatter of the block-digit radix sort (see sort_histogram_block.comp):
// a workgroup ranks its block's keys by digit in rounds of WORKGROUP_SIZE_X
// (within a subgroup by ballots on the digit's bits, across subgroups by
// their counts in shared memory), places them in shared memory in digit
// order, then writes them out in that order, so neighbouring invocations
// store neighbouring addresses of one digit's run. A key's place in a round
// is its subgroup's index times the subgroup size plus its lane, so the
// order is stable whatever the mapping of invocations to subgroups; the host
// runs it only where subgroups hold at least 8 invocations and divide the
// workgroup (MAX_SUBGROUPS), and builds it with full subgroups (it reads
// gl_SubgroupID). Packed passes (sort_common.glsl `put`) stage the pair as
// it came and pack or unpack it on the way out. CPU reference: std sort
// (tests/tests/sort.rs).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#define BLOCK_DIGITS
#define SORT_VALUES
#include "sort_common.glsl"

// Subgroups a workgroup may hold: WORKGROUP_SIZE_X / 8.
#define MAX_SUBGROUPS 16u
// Each subgroup's count of each digit in the round that last wrote it, that
// round + 1 in the bits above 16 (two barriers a round, no clearing).
shared uint round_counts[MAX_SUBGROUPS * RADIX];
// Keys of each digit ranked in the rounds before (the rounds' leaders add to
// it atomically); then each digit's first place in the block.
shared uint ranked[RADIX];
shared uint block_start[RADIX];
// Where the block's first key of each digit goes (the scanned histogram).
shared uint out_start[RADIX];
shared uvec2 block_keys[BLOCK_KEYS];
shared uint block_values[BLOCK_KEYS];

void main() {
    uint block = block_index();
    if (block >= pc.blocks) return;  // the grid's padding: whole workgroups
    uint t = gl_LocalInvocationID.x;
    uint place = gl_SubgroupID * gl_SubgroupSize + gl_SubgroupInvocationID;
    uint first = block * BLOCK_KEYS;
    Uints hist = Uints(pc.hist);
    for (uint d = t; d < RADIX; d += WORKGROUP_SIZE_X) {
        ranked[d] = 0u;
        out_start[d] = d < PASS_RADIX ? hist.v[d * pc.blocks + block] : 0u;
    }
    // Tag 0, no round's: an entry counts only in the round whose tag it holds.
    for (uint e = t; e < gl_NumSubgroups * RADIX; e += WORKGROUP_SIZE_X) round_counts[e] = 0u;
    barrier();
    uvec2 keys[BLOCK_ITEMS];
    uint values[BLOCK_ITEMS];
    uint digits[BLOCK_ITEMS];
    uint ranks[BLOCK_ITEMS];
    [[unroll]] for (uint r = 0u; r < BLOCK_ITEMS; r++) {
        uint i = first + r * WORKGROUP_SIZE_X + place;
        bool valid = i < pc.count;
        keys[r] = valid ? KEY(i) : uvec2(0u);
        values[r] = valid && !PACKED_IN ? VALUE(i) : 0u;
        uint d = digit_of(keys[r]);
        // The lanes holding a valid key of this digit.
        uvec4 peers = subgroupBallot(valid);
        [[unroll]] for (uint b = 0u; b < 8u; b++) {
            bool bit = ((d >> b) & 1u) != 0u;
            uvec4 with_bit = subgroupBallot(bit);
            peers &= bit ? with_bit : ~with_bit;
        }
        uint below = subgroupBallotBitCount(peers & gl_SubgroupLtMask);
        // One leader per digit and subgroup writes the subgroup's count,
        // tagged with the round (r + 1 above the count's 16 bits), so an entry
        // of an earlier round reads as no key and nothing needs clearing.
        bool leader = valid && below == 0u;
        uint count = subgroupBallotBitCount(peers);
        if (leader) round_counts[gl_SubgroupID * RADIX + d] = (r + 1u) << 16 | count;
        barrier();  // this round's counts and the last round's `ranked` are written
        uint rank = ranked[d] + below;
        for (uint s = 0u; s < gl_SubgroupID; s++) {
            uint tagged = round_counts[s * RADIX + d];
            rank += tagged >> 16 == r + 1u ? tagged & 0xffffu : 0u;
        }
        digits[r] = valid ? d : RADIX;
        ranks[r] = rank;
        barrier();  // every rank read `ranked` and the counts before they change
        if (leader) atomicAdd(ranked[d], count);
    }
    barrier();
    // Exclusive scan of the block's digit counts (two digits an invocation).
    uint count_lo = ranked[t], count_hi = ranked[t + WORKGROUP_SIZE_X];
    for (uint stride = 1u; stride < RADIX; stride <<= 1u) {
        uint lo = t >= stride ? ranked[t - stride] : 0u;
        uint hi = ranked[t + WORKGROUP_SIZE_X - stride];
        barrier();
        ranked[t] += lo;
        ranked[t + WORKGROUP_SIZE_X] += hi;
        barrier();
    }
    block_start[t] = ranked[t] - count_lo;
    block_start[t + WORKGROUP_SIZE_X] = ranked[t + WORKGROUP_SIZE_X] - count_hi;
    barrier();
    [[unroll]] for (uint r = 0u; r < BLOCK_ITEMS; r++) {
        if (digits[r] < RADIX) {
            uint at = block_start[digits[r]] + ranks[r];
            block_keys[at] = keys[r];
            block_values[at] = values[r];
        }
    }
    barrier();
    Uint64sOut keys_out = Uint64sOut(pc.keys_out);
    uint in_block = min(BLOCK_KEYS, pc.count - first);
    for (uint at = t; at < in_block; at += WORKGROUP_SIZE_X) {
        uvec2 key = block_keys[at];
        uint d = digit_of(key);
        uint dst = out_start[d] + (at - block_start[d]);
        put(keys_out, dst, key, block_values[at]);
    }
}
