#version 460
// Splatting stage 4: each tile's [start, end) in the sorted pairs.
// Ranges are zero-filled before, so tiles without pairs stay empty. Pairs
// with a tile id past the last tile (the keys kernel's padding) sort last and
// are skipped. The tile is read back from the key as splat_keys.comp packed
// it (`pair_key_tile`), past any row mask in its top bits.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "splat.glsl"

// Depth key bits, as the keys kernel's.
layout(constant_id = 3) const uint DEPTH_BITS = 32u;

void main() {
    uint i = linear_index();
    uint n = frame.counts.w;
    if (i >= n) return;
    Uvec2s keys = Uvec2s(frame.keys);
    Uvec2s ranges = Uvec2s(frame.ranges);
    uint tiles = frame.size.z * frame.size.w;
    uint tile = pair_key_tile(keys.v[i], DEPTH_BITS, tiles);
    if (tile >= tiles) return;
    if (i == 0u || pair_key_tile(keys.v[i - 1u], DEPTH_BITS, tiles) != tile) ranges.v[tile].x = i;
    if (i + 1u == n || pair_key_tile(keys.v[i + 1u], DEPTH_BITS, tiles) != tile) ranges.v[tile].y = i + 1u;
}
