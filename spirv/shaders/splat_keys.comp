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
#include "splat_keys_body.glsl"
