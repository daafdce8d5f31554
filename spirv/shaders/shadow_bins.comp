#version 460
// Shadow backward, binning: each texel's [start, end) in the receiver pixels
// sorted by the first texel of their bilinear footprint (ranges zero-filled
// before; pixels that pass no gradient carry the "no texel" key and no range).
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

// Host mirror: engine/src/shadow/backward.rs `BinsPush` (its layout is checked against this block).
layout(push_constant) uniform BinsPush {
    uvec2 keys;    // sorted uvec2 keys (texel, 0)
    uvec2 ranges;  // uvec2 per texel
    uint count;    // pixels
    uint none;     // the "no texel" key
} push;

void main() {
    uint i = linear_index();
    uint n = push.count;
    if (i >= n) return;
    Uvec2sIn keys = Uvec2sIn(push.keys);
    uint key = keys.v[i].x;
    if (key == push.none) return;
    Uints r = Uints(push.ranges);
    if (i == 0u || keys.v[i - 1u].x != key) r.v[2u * key] = i;
    if (i + 1u == n || keys.v[i + 1u].x != key) r.v[2u * key + 1u] = i + 1u;
}
