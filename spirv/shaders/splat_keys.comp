#version 460
// Splatting stage 2b: one (key, value) pair per (Gaussian, tile) it covers,
// written at the Gaussian's scanned offset. Key = tile above DEPTH_BITS bits
// of depth key (`pair_key`: the depth's float bits less the near plane's,
// less DEPTH_SHIFT low mantissa bits, so the sort orders only bits that vary
// within [near, far]); value = Gaussian
// index. The tile ids are also kept in emission order (pair tiles) for the
// backward pass. With ELLIPSE_TILES only the tiles of `tile_row_span` get
// pairs, as the preprocess counted them. Columns x ≥ tiles_x (a full
// equirectangular panorama) are column x − tiles_x. With ROW_MASKS the key's
// top TILE bits, above every bit the sort orders (the host checks they are
// free), carry `tile_block_mask`: which blocks of the tile the splat reaches.
// Should this compilation of it find fewer pairs (f32 rounding at the
// widened bound), the rest get the key of tile `tiles` with every depth bit
// set: they sort last and belong to no tile; it never writes past the count.
#define WORKGROUP_SIZE_X 64
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

void main() {
    uint i = linear_index();
    if (i >= frame.counts.x) return;
    Splat s = Splats(frame.splats).v[i];
    Uints offsets = Uints(frame.tile_counts);
    uint offset = offsets.v[i], end = offsets.v[i + 1u];
    uint depth_key = (floatBitsToUint(s.head.z) - (DEPTH_BITS < 32u ? floatBitsToUint(frame.clip.x) : 0u)) >> DEPTH_SHIFT;
    uint tiles = frame.size.z * frame.size.w;
    Uvec2s keys = Uvec2s(frame.keys);
    Uints values = Uints(frame.values);
    Uints pair_tiles = Uints(frame.pair_tiles);
    TileEllipse e = tile_ellipse(s.head, s.conic.xyz);
    // A rectangle past the right edge (a wrapping panorama) continues at the left, whole rows.
    bool wraps = s.rect.z > frame.size.z;
    // Block masks test columns only where x does not wrap (not on panoramas).
    bool check_x = !wraps && frame.camera.lens2.x != 9.0;
    for (uint y = s.rect.y; y < s.rect.w; y++) {
        uvec2 span = ELLIPSE_TILES && !wraps ? tile_row_span(e, s.head.xy, s.rect, y, TILE) : s.rect.xz;
        for (uint x = span.x; x < span.y && offset < end; x++) {
            uint tile = y * frame.size.z + (x < frame.size.z ? x : x - frame.size.z);
            if (TILE_MASK && !tile_wanted(tile)) continue;
            uint blocks = ROW_MASKS ? tile_block_mask(e, s.head.xy, x, y, TILE, check_x) << (32u - TILE) : 0u;
            keys.v[offset] = pair_key(tile, depth_key, DEPTH_BITS, blocks);
            values.v[offset] = i;
            pair_tiles.v[offset] = tile;
            offset++;
        }
    }
    for (; offset < end; offset++) {
        keys.v[offset] = pair_key(tiles, DEPTH_BITS >= 32u ? ~0u : (1u << DEPTH_BITS) - 1u, DEPTH_BITS, 0u);
        values.v[offset] = i;
        pair_tiles.v[offset] = tiles;
    }
}
