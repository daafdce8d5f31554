#version 460
// The shadow-map tiles a camera's receivers need, from the tiles under them:
// one invocation per map tile, wanted where it or one of its eight
// neighbours holds a receiver's light-space point (shadow_receiver_tiles.comp
// marks those, one atomic per receiver; the test's bilinear taps reach at
// most one texel from the point, so within those nine tiles). Several
// cameras may mark one `centres`; every tile of `wanted` is written.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

// Host mirror: engine/src/shadow/layout.rs `TileDilatePush` (its layout is checked against this block).
layout(push_constant) uniform TileDilatePush {
    uvec2 centres;  // u32 per tile, non-zero where a receiver's point lies
    uvec2 wanted;   // u32 per tile, out: 1 where the tile or a neighbour is marked, else 0
    uint tiles_x;
    uint tiles_y;
} push;

void main() {
    uint t = linear_index();
    if (t >= push.tiles_x * push.tiles_y) return;
    ivec2 c = ivec2(t % push.tiles_x, t / push.tiles_x);
    ivec2 last = ivec2(push.tiles_x, push.tiles_y) - 1;
    UintsIn centres = UintsIn(push.centres);
    uint any_marked = 0u;
    for (int y = max(c.y - 1, 0); y <= min(c.y + 1, last.y); y++) {
        for (int x = max(c.x - 1, 0); x <= min(c.x + 1, last.x); x++) {
            any_marked |= centres.v[uint(y) * push.tiles_x + uint(x)];
        }
    }
    Uints(push.wanted).v[t] = any_marked != 0u ? 1u : 0u;
}
