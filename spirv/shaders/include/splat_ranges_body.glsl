// Body of splat_ranges.comp and splat_ranges_texel.comp (see their headers).
// Splatting stage 4: each tile's [start, end) in the sorted pairs, an
// invocation per PAIRS consecutive pairs, which handles the boundary after
// each of them (and the first pair its own start): PAIRS + 1 key reads for
// PAIRS pairs where one pair an invocation reads two keys a pair (on
// lavapipe each read is a call). Ranges are zero-filled before, so tiles without pairs
// stay empty. Pairs with a tile id past the last tile (the keys kernel's
// padding) sort last and are skipped. The tile is read back from the key as
// splat_keys.comp packed it (`pair_key_tile`), past any row mask in its top bits.
#extension GL_EXT_control_flow_attributes : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "splat.glsl"

// Depth key bits, as the keys kernel's.
layout(constant_id = 3) const uint DEPTH_BITS = 32u;
// Pairs an invocation (engine/src/splat/forward.rs `RANGE_PAIRS`, which sizes the grid).
layout(constant_id = 4) const uint PAIRS = 1u;

#ifdef TEXEL_KEYS
// The sorted keys as an RG32UI texel view (binding 1): one vector gather
// per read on lavapipe, where a device-address load is a loop over the lanes.
layout(set = 0, binding = 1) uniform utextureBuffer key_texels;
#define KEY(i) texelFetch(key_texels, int(i)).xy
#else
#define KEY(i) Uvec2s(frame.keys).v[i]
#endif

void main() {
    uint first = linear_index() * PAIRS;
    uint n = frame.counts.w;
    if (first >= n) return;
    Uvec2s ranges = Uvec2s(frame.ranges);
    uint tiles = frame.size.z * frame.size.w;
    uint tile = pair_key_tile(KEY(first), DEPTH_BITS, tiles);
    if (first == 0u && tile < tiles) ranges.v[tile].x = 0u;
    // An `if`, not a `break`: an unrolled loop must not leave early (spirv/tests/unrolled_loops.rs).
    [[unroll]] for (uint j = 0u; j < PAIRS; j++) {
        uint i = first + j;
        if (i < n) {
            uint next = i + 1u < n ? pair_key_tile(KEY(i + 1u), DEPTH_BITS, tiles) : tiles;
            if (next != tile) {
                if (tile < tiles) ranges.v[tile].y = i + 1u;
                if (next < tiles) ranges.v[next].x = i + 1u;
            }
            tile = next;
        }
    }
}
