// Body of splat_keys.comp and splat_keys_texel.comp (see their headers).
// 256 invocations a workgroup, one per Gaussian: fewer workgroups for a CPU
// implementation to launch (docs/bench/splat.md, "Larger workgroups").
#define WORKGROUP_SIZE_X 256
#define SRUG_WORDS_64
#include "common.glsl"
#include "splat.glsl"

layout(constant_id = 1) const bool ELLIPSE_TILES = false;
// Tile edge in pixels (engine/src/splat/mod.rs `TILE_SPEC_IDS`).
layout(constant_id = 15) const uint TILE = 16u;
layout(constant_id = 2) const bool ROW_MASKS = false;
// Depth key bits (1 to 32; 32 keeps the depth's float bits whole).
layout(constant_id = 3) const uint DEPTH_BITS = 32u;
// Low mantissa bits the depth key drops (engine/src/splat/forward.rs `DepthKey`).
layout(constant_id = 5) const uint DEPTH_SHIFT = 0u;
// Pairs only for the tiles the frame's tile mask wants, as the preprocess counted.
layout(constant_id = 4) const bool TILE_MASK = false;
// Each unsorted pair's tile id (frame.pair_tiles), which only the backward
// pass reads: off for frames that are never differentiated (`Splatter::render`).
layout(constant_id = 6) const bool PAIR_TILES = true;

#ifdef TEXEL_SPLATS
// Each splat's record as 4 RGBA32UI texels (head, conic, colour, rect: its
// bits) and the scanned tile counts as R32UI: on lavapipe a texelFetch is one
// vector gather, a device-address load a loop over the lanes.
layout(set = 0, binding = 1) uniform utextureBuffer splat_texels;
layout(set = 0, binding = 2) uniform utextureBuffer offset_texels;
#define SPLAT_HEAD(i) uintBitsToFloat(texelFetch(splat_texels, int(4u * (i))))
#define SPLAT_CONIC(i) uintBitsToFloat(texelFetch(splat_texels, int(4u * (i) + 1u)).xyz)
#define SPLAT_RECT(i) texelFetch(splat_texels, int(4u * (i) + 3u))
#define OFFSET(i) texelFetch(offset_texels, int(i)).x
#else
#define SPLAT_HEAD(i) Splats(frame.splats).v[i].head
#define SPLAT_CONIC(i) Splats(frame.splats).v[i].conic.xyz
#define SPLAT_RECT(i) Splats(frame.splats).v[i].rect
#define OFFSET(i) Uints(frame.tile_counts).v[i]
#endif

void main() {
    uint i = linear_index();
    if (i >= frame.counts.x) return;
    uint offset = OFFSET(i), end = OFFSET(i + 1u);
    // A culled splat (no pairs) is not read.
    if (offset == end) return;
    vec4 head = SPLAT_HEAD(i);
    vec3 conic = SPLAT_CONIC(i);
    uvec4 rect = SPLAT_RECT(i);
    uint depth_key = (floatBitsToUint(head.z) - (DEPTH_BITS < 32u ? floatBitsToUint(frame.clip.x) : 0u)) >> DEPTH_SHIFT;
    uint tiles = frame.size.z * frame.size.w;
    // Each key as one 64-bit word (`Uint64sOut`).
    Uint64sOut keys = Uint64sOut(frame.keys);
    Uints values = Uints(frame.values);
    Uints pair_tiles = Uints(frame.pair_tiles);
    TileEllipse e = tile_ellipse(head, conic);
    // A rectangle past the right edge (a wrapping panorama) continues at the left, whole rows.
    bool wraps = rect.z > frame.size.z;
    // Block masks test columns only where x does not wrap (not on panoramas).
    bool check_x = !wraps && frame.camera.lens2.x != 9.0;
    // The rectangle, the row and the tile's first pixel as floats
    // (`tile_row_span_f`, `tile_block_mask`): no float-uint conversion a row
    // or tile but `whole_to_uint`'s.
    vec4 rect_f = uint_to_whole(rect);
    float row_f = rect_f.y;
    for (uint y = rect.y; y < rect.w; y++, row_f += 1.0) {
        vec2 span_f = ELLIPSE_TILES && !wraps ? tile_row_span_f(e, head.xy, rect_f, row_f, float(TILE)) : rect_f.xz;
        uvec2 span = whole_to_uint(span_f);
        vec2 origin = vec2(span_f.x, row_f) * float(TILE);
        for (uint x = span.x; x < span.y && offset < end; x++, origin.x += float(TILE)) {
            uint tile = y * frame.size.z + (x < frame.size.z ? x : x - frame.size.z);
            if (TILE_MASK && !tile_wanted(tile)) continue;
            uint blocks = ROW_MASKS ? tile_block_mask(e, head.xy, origin, TILE, check_x) << (32u - TILE) : 0u;
            keys.v[offset] = packUint2x32(pair_key(tile, depth_key, DEPTH_BITS, blocks));
            values.v[offset] = i;
            if (PAIR_TILES) pair_tiles.v[offset] = tile;
            offset++;
        }
    }
    for (; offset < end; offset++) {
        keys.v[offset] = packUint2x32(pair_key(tiles, DEPTH_BITS >= 32u ? ~0u : (1u << DEPTH_BITS) - 1u, DEPTH_BITS, 0u));
        values.v[offset] = i;
        if (PAIR_TILES) pair_tiles.v[offset] = tiles;
    }
}
