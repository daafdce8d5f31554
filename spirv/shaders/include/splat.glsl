// Shared by the splatting kernels: the frame uniform and the per-splat record.
#ifndef SRUG_SPLAT_GLSL
#define SRUG_SPLAT_GLSL
#include "address.glsl"
#include "camera.glsl"
#include "splat_types.glsl"

// Host mirror: engine/src/splat/mod.rs `FrameUniform` (its layout is checked against this block).
layout(std140, set = 0, binding = 0) uniform Frame {
    WorldToCamera camera;
    vec4 clip;         // near, far, Jacobian limit x, y (tan of the half fov × 1.3);
                       // equirectangular: near, far (distances), wrap period (0: none), 0
    vec4 eye;          // camera centre
    vec4 view_dir;     // viewing direction (orthographic SH direction)
    vec4 background;   // rgb
    uvec4 size;        // width, height, tiles_x, tiles_y
    uvec4 counts;      // gaussians, SH degree stored | used << 8, normal_source (0 shortest axis, 1 stored), pairs
    vec4 occluder;     // the host's depth (OCCLUDED): convention (0 camera z, 1 Vulkan [0, 1], 2 reversed-Z), near, far, 0
    uvec2 means;            // scene inputs, by device address (low, high)
    uvec2 log_scales;
    uvec2 rotations;
    uvec2 opacity_logits;
    uvec2 sh;
    uvec2 normals;          // 0 when the scene has none
    uvec2 albedo;
    uvec2 roughness;
    uvec2 metallic;
    uvec2 ao;
    uvec2 visibility;
    uvec2 splats;           // working buffers
    uvec2 features;
    uvec2 tile_counts;      // offsets after the scan
    uvec2 keys;
    uvec2 values;
    uvec2 ranges;
    uvec2 g_rgb;            // G-buffer outputs; 0 where a channel is not kept
    uvec2 pair_tiles;       // tile id of each unsorted pair
    uvec2 occluder_depth;   // the host's depth per pixel (OCCLUDED)
    uvec2 g_alpha;
    uvec2 g_depth;
    uvec2 g_median_depth;
    uvec2 g_normal;
    uvec2 g_albedo;
    uvec2 g_roughness;
    uvec2 g_metallic;
    uvec2 g_ao;
    uvec2 g_visibility;
    uvec2 g_top_gaussian;   // uint per pixel: the Gaussian with the largest blend weight
    uvec2 tile_mask;        // uint per tile, non-zero where pairs are wanted (TILE_MASK)
    uvec2 visible_slots;    // compacted records (preprocess COMPACT): per Gaussian (n + 1) its
                            // flag, then, scanned, its record's slot; 0 once the records exist
    uvec2 slot_gaussians;   // compacted records: each record's Gaussian
    uvec2 wanted_rows;      // TILE_MASK: uvec2 per tile row, its wanted columns [x0, x1) (their hull)
    uvec4 cull_tiles;       // tiles [x0, y0) to [x1, y1) the position cull keeps splats for:
                            // the image's, or (TILE_MASK) the bounds of the wanted tiles
} frame;

// The chunks a tile's list (`range` of the sorted pairs) splits into for
// the split blend (splat_blend_body.glsl `CHUNK_PASS`): none where it holds
// at most 2·chunk_length entries or chunk_length is 0, else
// ceil(length / chunk_length). Host mirror: engine/src/splat/mod.rs `list_chunks`.
uint list_chunks(uvec2 range, uint chunk_length) {
    uint n = range.y - range.x;
    return chunk_length == 0u || n <= 2u * chunk_length ? 0u : (n - 1u) / chunk_length + 1u;
}

// Whether tile `tile` gets pairs (every tile without a mask).
bool tile_wanted(uint tile) {
    return UintsIn(frame.tile_mask).v[tile] != 0u;
}

// The per-splat part of `tile_row_span`, computed once per splat: r² (≤ 0:
// the splat reaches no pixel), the conic's a and b, det Q (0 where too
// ill-conditioned: whole rows), the half-height and y_side.
struct TileEllipse { float r2, a, b, det, y_max, y_side; };

// `tile_ellipse` with a given r² (a larger one gives a larger ellipse).
TileEllipse tile_ellipse_of(float r2, vec3 conic) {
    TileEllipse e;
    e.r2 = r2;
    e.a = conic.x;
    e.b = conic.y;
    float c = conic.z;
    e.det = e.a * c - e.b * e.b;
    if (!(e.det > 1e-4 * e.a * c)) e.det = 0.0;
    e.y_max = sqrt(e.r2 * e.a / e.det);
    e.y_side = e.b * sqrt(e.r2 / (c * e.det));
    return e;
}

// The splat's ellipse of α ≥ 1/255: r² = 2·ln(255·o), widened by 1% and 0.01.
TileEllipse tile_ellipse(vec4 head, vec3 conic) {
    return tile_ellipse_of(2.02 * log(255.0 * head.w) + 0.01, conic);
}

// Tiles of tile row `ty` whose square can see the splat at α ≥ 1/255, as
// columns [x0, x1) within `rect` (`e` from `tile_ellipse`). α ≥ 1/255 ⇔
// dᵀQd ≤ 2·ln(255·o) with Q the conic, an ellipse; a row's squares meeting a
// convex set form one run. The
// bound is widened (r² by 1% + 0.01, squares by 0.01 px) so f32 rounding never
// drops a pixel the blend would take, and rows where Q is too ill-conditioned
// for f32 keep their whole rectangle row. Only meaningful for `rect` from the
// same splat. Keep in sync with engine/src/splat/cpu.rs `tile_row_span`.
// Columns and rows as floats (whole numbers; `tile_row_span` converts).
vec2 tile_row_span_f(TileEllipse e, vec2 mean, vec4 rect, float ty, float tile) {
    if (!(e.r2 > 0.0)) return rect.xx;
    if (!(e.det > 0.0)) return rect.xz;
    float t = tile;
    float lo = max(ty * t - 0.01 - mean.y, -e.y_max);
    float hi = min(ty * t + t + 0.01 - mean.y, e.y_max);
    if (!(lo <= hi)) return rect.xx;
    // The ellipse's right edge x(y) = (−b·y + sqrt(r²·a − det·y²)) / a is concave,
    // largest at y = −y_side; its left edge is convex, smallest at y = +y_side.
    float yr = clamp(-e.y_side, lo, hi), yl = clamp(e.y_side, lo, hi);
    float xr = (-e.b * yr + sqrt(max(e.r2 * e.a - e.det * yr * yr, 0.0))) / e.a;
    float xl = (-e.b * yl - sqrt(max(e.r2 * e.a - e.det * yl * yl, 0.0))) / e.a;
    if (!(xl <= xr)) return rect.xz;
    float first = ceil((mean.x + xl - 0.01) / t - 1.0);
    float last = floor((mean.x + xr + 0.01) / t);
    float x0 = clamp(first, rect.x, rect.z);
    float x1 = clamp(last + 1.0, x0, rect.z);
    return vec2(x0, x1);
}

// `tile_row_span_f` as tile columns (`whole_to_uint`: rect's columns are
// under 2^23).
uvec2 tile_row_span(TileEllipse e, vec2 mean, uvec4 rect, uint ty, uint tile) {
    return whole_to_uint(tile_row_span_f(e, mean, uint_to_whole(rect), uint_to_whole(ty), float(tile)));
}

// The rows of the ellipse of `e` (det > 0) as three numbers (slope, q, r), so
// that a row's span costs one square root and no division
// (`ellipse_row_span`): at dy = mean.y − centre y, d = mean − centre spans
// dx ∈ (−b·dy ± sqrt(r²a − det·dy²)) / a, a run centred on
// x = mean.x + slope·dy of half width sqrt(max(q − r·dy², 0)).
vec3 ellipse_rows(TileEllipse e) {
    return vec3(e.b / e.a, e.r2 / e.a, (e.det / e.a) / e.a);
}

// The pixel-centre x range [x.x, x.y] where the row at dy = mean.y − centre
// y meets the ellipse (`rows` from `ellipse_rows`), widened by 0.01 px
// (empty where `rows` has a NaN slope).
vec2 ellipse_row_span(vec3 rows, vec2 mean, float dy) {
    float mid = mean.x + rows.x * dy;
    float half_width = sqrt(max(rows.y - rows.z * dy * dy, 0.0));
    return vec2(mid - half_width - 0.01, mid + half_width + 0.01);
}

// Which blocks of tile (tx, ty) the splat reaches at α ≥ 1/255: the tile
// is cut into two halves of tile/2 columns and pairs of rows, bit
// h·(tile/2) + r/2 for half h and row r (`tile` bits, `tile` ≤ 32); a block
// is reached if some pixel centre of it lies within the ellipse of
// `tile_ellipse` (`e`, widened) and 0.01 px more. Every block where Q is too
// ill-conditioned for f32; both halves of a reached row without `check_x`
// (panoramas). The texel blend skips a splat for subgroups whose blocks it
// misses (splat_keys.comp stores the mask with each pair). `origin`: the
// tile's first pixel (tx·tile, ty·tile), as floats.
uint tile_block_mask(TileEllipse e, vec2 mean, vec2 origin, uint tile, bool check_x) {
    if (!(e.r2 > 0.0)) return 0u;
    if (!(e.det > 0.0)) return tile >= 32u ? ~0u : (1u << tile) - 1u;
    float lo = ceil(mean.y - e.y_max - origin.y - 0.5 - 0.01);
    float hi = floor(mean.y + e.y_max - origin.y - 0.5 + 0.01);
    if (!(lo <= hi) || hi < 0.0 || lo > float(tile) - 1.0) return 0u;
    float first_row = max(lo, 0.0);
    uint r0 = whole_to_uint(first_row), r1 = whole_to_uint(min(hi, float(tile) - 1.0));
    uint half_cols = tile / 2u;
    float split = origin.x + float(half_cols);
    vec3 rows = ellipse_rows(e);
    uint mask = 0u;
    // The row's centre as a float counter: exact, and no integer conversion a row.
    float row_centre = origin.y + first_row + 0.5;
    for (uint r = r0; r <= r1; r++, row_centre += 1.0) {
        bool left = true, right = true;
        if (check_x) {
            // d = mean − centre; at this row's dy the ellipse spans dx ∈ (−b·dy ± sqrt(r²a − det·dy²)) / a.
            vec2 x = ellipse_row_span(rows, mean, mean.y - row_centre);
            left = x.y >= origin.x + 0.5 && x.x <= split - 0.5;
            right = x.y >= split + 0.5 && x.x <= origin.x + float(tile) - 0.5;
        }
        uint bit = r / 2u;
        mask |= (left ? 1u << bit : 0u) | (right ? 1u << (half_cols + bit) : 0u);
    }
    return mask;
}

// A (Gaussian, tile) pair's sort key, 64 bits as (low, high): the tile id
// above `depth_bits` bits of depth key (the depth's float bits less the near
// plane's: depth > near > 0, so they order like the depths), and `rows` (a
// row mask already in place, or 0) in the high word's top bits, above every
// bit the sort orders. Keep in sync with engine/src/splat/forward.rs
// (`depth_key_bits`, the row-mask room check).
uvec2 pair_key(uint tile, uint depth_key, uint depth_bits, uint rows) {
    if (depth_bits >= 32u) return uvec2(depth_key, tile | rows);
    return uvec2(depth_key | (tile << depth_bits), (tile >> (32u - depth_bits)) | rows);
}

// The tile id of a `pair_key` for an image of `tiles` tiles (ids 0..=tiles).
uint pair_key_tile(uvec2 key, uint depth_bits, uint tiles) {
    uint id = depth_bits >= 32u ? key.y : (key.x >> depth_bits) | (key.y << (32u - depth_bits));
    uint bits = uint(findMSB(tiles)) + 1u;
    return bits >= 32u ? id : id & ((1u << bits) - 1u);
}

#endif
