#version 460
// The shadow-map tiles a camera's receivers look up, one invocation per
// receiver pixel: its world point (as the shadow test finds it, bias offsets
// included) projected into light space marks the tile under it, and
// shadow_tile_dilate.comp then wants that tile and the eight around it (the
// test's bilinear taps stay within one texel), so a map splatted only in the
// wanted tiles (`Splatter::render_frame_in_tiles`) gives every receiver the
// visibility the whole map gives. Marks are u32 flags, zeroed by the host
// first; several cameras may mark one mask. Receivers outside the uniform's
// camera-depth range mark nothing (a cascade serves its slice of the view
// only).
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shadow.glsl"

void main() {
    uint p = linear_index();
    if (p >= shadow.size.x * shadow.size.y) return;
    // Only receivers whose camera depth lies in the map's range (a cascade's slice).
    float z;
    if (!resolve_depth(shadow.modes.y, shadow.receiver_depth, shadow.receiver_alpha, p, z)) return;
    if (z < shadow.receiver_range.x || z > shadow.receiver_range.y) return;
    vec3 from_camera;
    float bias;
    if (!receiver_point(p, from_camera, bias)) return;
    vec3 l = light_coords(from_camera);
    if (!inside_map(l.xy)) return;
    int tile = int(shadow.modes.w);
    ivec2 tiles = ivec2(int(shadow.modes.z), (int(shadow.size.w) + tile - 1) / tile);
    ivec2 t = ivec2(floor(l.xy / float(tile)));
    if (all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, tiles))) {
        atomicOr(Uints(shadow.tile_mask).v[uint(t.y * tiles.x + t.x)], 1u);
    }
}
