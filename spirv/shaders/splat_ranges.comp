#version 460
// Splatting stage 4: each tile's [start, end) in the sorted pairs.
// Ranges are zero-filled before, so tiles without pairs stay empty. Pairs
// with a tile id past the last tile (the keys kernel's padding) sort last and
// are skipped. With ROW_MASKS the key's top TILE bits are the pair's row
// mask (splat_keys.comp), not its tile.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "splat.glsl"

layout(constant_id = 2) const bool ROW_MASKS = false;
layout(constant_id = 15) const uint TILE = 16u;
const uint TILE_ID = ROW_MASKS ? (1u << (32u - TILE)) - 1u : ~0u;

void main() {
    uint i = linear_index();
    uint n = frame.counts.w;
    if (i >= n) return;
    Uvec2s keys = Uvec2s(frame.keys);
    Uvec2s ranges = Uvec2s(frame.ranges);
    uint tile = keys.v[i].y & TILE_ID;
    if (tile >= frame.size.z * frame.size.w) return;
    if (i == 0u || (keys.v[i - 1u].y & TILE_ID) != tile) ranges.v[tile].x = i;
    if (i + 1u == n || (keys.v[i + 1u].y & TILE_ID) != tile) ranges.v[tile].y = i + 1u;
}
