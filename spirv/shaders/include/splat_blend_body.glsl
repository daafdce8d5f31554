// Body of the splat_blend*.comp variants (see their headers). One workgroup
// per TILE×TILE tile (the edge is specialized), one invocation per pixel
// (the texel variant: per PIXELS pixels, see its main below).
#define TILE_WORKGROUP
#include "common.glsl"
#include "splat.glsl"

// Bits: 1 depth, 2 median depth, 4 normal, 8 albedo, 16 roughness, 32 metallic, 64 ao, 128 visibility,
// 256 rgb, 512 top Gaussian. Keep in sync with engine/src/splat/mod.rs `Channels::bits`, `RGB_BIT`
// and `TOP_GAUSSIAN_BIT`.
layout(constant_id = 0) const uint CHANNELS = 256u;
// A full equirectangular panorama: offsets along x wrap at frame.clip.z (the width).
layout(constant_id = 3) const bool WRAP_X = false;
// Surface depth: each splat's depth at a pixel is where the pixel's ray meets
// its plane (the preprocess's slope), not its centre's.
layout(constant_id = 4) const bool SURFACE_DEPTH = false;
// The host's depth per pixel hides the splats behind it (compositing with a
// host's meshes; frame.occluder gives its convention).
layout(constant_id = 5) const bool OCCLUDED = false;
// The texel blend: each sorted key carries the tile blocks its splat reaches (splat_keys.comp `tile_block_mask`).
layout(constant_id = 6) const bool ROW_MASKS = false;
// The texel blend evaluates a splat only at the pixels of each lane's row it
// can reach (`row_span`); for drivers that jump over an `if` no lane
// enters (engine/src/splat/mod.rs `default_pixel_reach`).
layout(constant_id = 7) const bool PIXEL_REACH = false;
// Blend only the tiles the frame's tile mask wants (`tile_wanted`), as the
// keys kernel listed; the others' pixels are left unwritten. A constant, so
// frames without a mask carry no test.
layout(constant_id = 8) const bool TILE_MASK = false;
// The texel blend fetches each key window's wanted splats once, a splat per
// lane, and shuffles them to every lane splat by splat, where every lane would otherwise
// fetch each splat itself: for drivers whose texel fetch is a call (lavapipe
// from Mesa 25 compiles it as an out-of-line function, saving and restoring
// the caller's vector registers around it) and that jump over an `if` no lane
// enters (engine/src/splat/mod.rs `default_window_fetch`).
layout(constant_id = 9) const bool WINDOW_FETCH = false;
// With WINDOW_FETCH, each loop step takes the window's next two splats
// (their reads and exponentials independent, accumulated in order), so the
// step's liveness ballot and loop test serve two splats.
layout(constant_id = 10) const bool TWO_SPLATS = false;
// The split blend (texel blend only): a tile's list longer than
// 2·CHUNK_LENGTH (`list_chunks`) is cut into chunks of CHUNK_LENGTH entries,
// each walked by a workgroup of its own, so no pixel's walk is longer than
// the chunk. Pass 0 blends the other tiles whole; pass 1 takes each chunk's
// transmittance product per pixel (every splat that reaches the pixel, no
// stop but below 1e-4, where the pixel is surely done); pass 2 blends each
// chunk from its incoming transmittance (the earlier chunks' products) with
// the one-pass rules, so its weights, stop, median crossing and top weight
// are the one-pass ones; pass 3 adds each split tile's chunks up in order
// (engine/src/splat/forward.rs `ChunkPlan`). CHUNK_LENGTH 0: no list is split.
layout(constant_id = 11) const uint CHUNK_PASS = 0u;
layout(constant_id = 12) const uint CHUNK_LENGTH = 0u;
// The median depth is read where T first falls to MEDIAN_T, the coverage
// 1 − MEDIAN_T (engine/src/splat/mod.rs `SplatSettings::median_coverage`;
// 0.5: the median); with surface depths a later splat at least that opaque
// and nearer takes it over.
layout(constant_id = 13) const float MEDIAN_T = 0.5;
// Features at 16 bits (`PackedFeatures` in splat_types.glsl), else as floats.
layout(constant_id = 14) const bool PACKED_FEATURES = false;
// Without rgb (shadow maps) no colour is read, blended or stored.
const bool RGB = (CHANNELS & 256u) != 0u;
// The index of the splat with the largest weight wᵢ = αᵢ Tᵢ (the first of equal ones), per pixel.
const bool TOP = (CHANNELS & 512u) != 0u;
const uint NO_GAUSSIAN = 0xffffffffu;
const bool FEATURES = (CHANNELS & 252u) != 0u;

#ifdef TEXEL_SPLATS
// Splats (4 RGBA32F texels each: head, conic, color, rect) and features (3
// each: RG32UI when packed, else RGBA32UI holding the floats' bits) as
// texel-buffer views: a contribution's colour and features are read by the
// contributing lanes only, and on lavapipe a texelFetch is one vector gather
// where a device-address load is a loop over the lanes.
layout(set = 0, binding = 1) uniform textureBuffer splat_texels;
layout(set = 0, binding = 2) uniform utextureBuffer feature_texels;
// The sorted splat indices (R32UI), the tile's list.
layout(set = 0, binding = 3) uniform utextureBuffer value_texels;
// The sorted keys (R32UI, two words per pair): with ROW_MASKS the high
// word's top TILE bits are the blocks of its tile the pair's splat reaches.
layout(set = 0, binding = 4) uniform utextureBuffer key_texels;
#define SPLAT_COLOR(g) texelFetch(splat_texels, int(4u * (g) + 2u)).rgb
#define SPLAT_SLOPE_Y(g) texelFetch(splat_texels, int(4u * (g) + 2u)).w
#define FEATURE_WORDS(i) texelFetch(feature_texels, int(i))
#else
#define SPLAT_COLOR(g) Splats(frame.splats).v[g].color.rgb
#define SPLAT_SLOPE_Y(g) Splats(frame.splats).v[g].color.w
#define FEATURE_WORDS(i) (PACKED_FEATURES ? uvec4(PackedFeatures(frame.features).v[i], 0u, 0u) \
                                         : floatBitsToUint(Features(frame.features).v[i]))
#endif

// The splat's surface-depth slope (zero without SURFACE_DEPTH): x in its
// conic's w, y in its colour's w (splat_types.glsl).
vec2 splat_slope(uint g, vec4 conic) {
    return SURFACE_DEPTH ? vec2(conic.w, SPLAT_SLOPE_Y(g)) : vec2(0.0);
}

// The splat's depth at a pixel d = mean − centre away: its centre's, or with
// SURFACE_DEPTH where the pixel's ray meets its plane (`plane_depth`).
float splat_depth(vec4 head, vec2 slope, vec2 d) {
    if (!SURFACE_DEPTH) return head.z;
    return plane_depth(head.z, slope, d, frame.camera.position.w != 0.0);
}

// Whether this splat (centre depth z0) and every later one in the tile's
// order (centre depths ≥ z0) lie at or behind the host's depth `limit` at
// every pixel. Surface depths reach at most 1.56× nearer than the centre's:
// the preprocess limits the plane's relative inverse depth to 0.5 over the
// dilated 3σ footprint, α ≥ 1/255 reaches 3.33σ (0.555), plus rounding. Orthographic surface depths move by an absolute
// amount instead: no stop for them.
const float SURFACE_NEARER = 1.56;
bool behind_host(float z0, float limit) {
    if (!OCCLUDED) return false;
    if (!SURFACE_DEPTH) return !(z0 < limit);
    return frame.camera.position.w == 0.0 && !(z0 < SURFACE_NEARER * limit);
}

// The host's camera depth at pixel `pix` (infinity where it has nothing, or
// without OCCLUDED): its stored value as camera z, or linearized from a
// Vulkan [0, 1] depth (1: nothing) or a reversed-Z one (0: nothing; far may be
// infinite). CPU twin: engine/src/splat/cpu.rs `HostDepth::camera_z`.
float occluder_z(uvec2 pix) {
    if (!OCCLUDED) return 1.0 / 0.0;
    float d = FloatsIn(frame.occluder_depth).v[pix.y * frame.size.x + pix.x];
    float near = frame.occluder.y, far = frame.occluder.z;
    uint mode = uint(frame.occluder.x);
    if (mode == 1u) return d >= 1.0 ? 1.0 / 0.0 : near * far / (far - d * (far - near));
    if (mode == 2u) return d <= 0.0 ? 1.0 / 0.0 : (isinf(far) ? near / d : near * far / (near + d * (far - near)));
    return d > 0.0 ? d : 1.0 / 0.0;
}

// What one pixel has accumulated so far.
struct Accumulated {
    float T;
    vec3 rgb;
    float depth, median;
    vec3 normal, albedo;
    float rough, metal, ao, vis;
    float top_w;
    uint top_g;
};

// A contributing splat's colour and features (zero without FEATURES).
struct Contribution {
    vec3 color;
    vec4 f0, f1, f2;
};

// A splat's three feature words (`FEATURE_WORDS`) as values: unpacked, or the floats' bits.
void features_of(uvec4 w0, uvec4 w1, uvec4 w2, inout Contribution c) {
    if (PACKED_FEATURES) {
        unpack_features(w0.xy, w1.xy, w2.xy, c.f0, c.f1, c.f2);
    } else {
        c.f0 = uintBitsToFloat(w0);
        c.f1 = uintBitsToFloat(w1);
        c.f2 = uintBitsToFloat(w2);
    }
}

Contribution splat_contribution(uint g) {
    Contribution c = Contribution(vec3(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
    if (RGB) c.color = SPLAT_COLOR(g);
    if (FEATURES) features_of(FEATURE_WORDS(3 * g), FEATURE_WORDS(3 * g + 1), FEATURE_WORDS(3 * g + 2), c);
    return c;
}

// Adds a splat of opacity `alpha` and depth `z` to `acc` where `takes`
// (weight 0 and T kept otherwise), with no branch.
void accumulate_select(inout Accumulated acc, bool takes, float alpha, float next_T, float z, Contribution c, uint g) {
    float w = mix(0.0, alpha * acc.T, takes);
    if (TOP) {
        bool better = w > acc.top_w;
        acc.top_w = mix(acc.top_w, w, better);
        acc.top_g = better ? g : acc.top_g;
    }
    if (RGB) acc.rgb += w * c.color;
    if ((CHANNELS & 1u) != 0u) acc.depth += w * z;
    if ((CHANNELS & 2u) != 0u) acc.median = mix(acc.median, z, all(bvec3(takes, acc.T > MEDIAN_T, next_T <= MEDIAN_T)));
    // With surface depths a later splat (in centre order) can be nearer at this pixel:
    // one opaque enough there is the surface the ray meets first.
    if ((CHANNELS & 2u) != 0u && SURFACE_DEPTH) {
        acc.median = mix(acc.median, z, all(bvec4(takes, acc.T <= MEDIAN_T, alpha >= 1.0 - MEDIAN_T, z < acc.median)));
    }
    if (FEATURES) {
        acc.normal += w * c.f0.xyz;
        acc.rough += w * c.f0.w;
        acc.albedo += w * c.f1.xyz;
        acc.metal += w * c.f1.w;
        acc.ao += w * c.f2.x;
        acc.vis += w * c.f2.y;
    }
    acc.T = mix(acc.T, next_T, takes);
}

// Adds a splat of opacity `alpha` and depth `z` to `acc`; the caller has
// checked that the pixel is not done (T·(1−α) ≥ 1e-4).
void accumulate(inout Accumulated acc, float alpha, float z, Contribution c, uint g) {
    accumulate_select(acc, true, alpha, acc.T * (1.0 - alpha), z, c, g);
}

// The splat's head with its mean moved by whole periods to the copy nearest `centre` (WRAP_X).
vec4 nearest_copy(vec4 head, vec2 centre) {
    if (WRAP_X) {
        float period = frame.clip.z;
        head.x -= period * floor((head.x - centre.x) / period + 0.5);
    }
    return head;
}

// Blends splat g into `acc`; false once the pixel is done (T·(1−α) < 1e-4,
// that splat excluded). Colour and features are loaded only when it contributes.
bool blend_one(inout Accumulated acc, uint g, vec4 head, vec4 conic, vec2 centre, float limit) {
    float alpha, gauss;
    vec2 d;
    head = nearest_copy(head, centre);
    // A tile's splats come in order of centre depth: once one lies at or
    // behind the host's depth, so do the rest (`behind_host`).
    if (behind_host(head.z, limit)) return false;
    if (!splat_alpha(head, conic, centre, alpha, gauss, d)) return true;
    float z = splat_depth(head, splat_slope(g, conic), d);
    if (OCCLUDED && !(z < limit)) return true;
    if (acc.T * (1.0 - alpha) < 1e-4) return false;
    accumulate(acc, alpha, z, splat_contribution(g), g);
    return true;
}

#ifdef SHARED_BATCHES
// Splats staged per batch, at most TILE_PIXELS (the host keeps the batch
// within shared memory: 36 bytes each).
layout(constant_id = 1) const uint BLEND_BATCH = 256u;
shared uint batch_g[BLEND_BATCH];
shared vec4 batch_head[BLEND_BATCH];
shared vec4 batch_conic[BLEND_BATCH];
shared uint done_count;
#endif

// Writes one pixel's channels.
void store_pixel(uvec2 pix, Accumulated acc) {
    float T = acc.T;
    vec3 rgb = acc.rgb;
    float depth = acc.depth, median = acc.median;
    vec3 normal = acc.normal, albedo = acc.albedo;
    float rough = acc.rough, metal = acc.metal, ao = acc.ao, vis = acc.vis;
    uint p = pix.y * frame.size.x + pix.x;
    if (RGB) {
        vec3 color = rgb + T * frame.background.rgb;
        Floats out_rgb = Floats(frame.g_rgb);
        out_rgb.v[3 * p] = color.r;
        out_rgb.v[3 * p + 1] = color.g;
        out_rgb.v[3 * p + 2] = color.b;
    }
    Floats(frame.g_alpha).v[p] = 1.0 - T;
    if ((CHANNELS & 1u) != 0u) Floats(frame.g_depth).v[p] = depth;
    if ((CHANNELS & 2u) != 0u) Floats(frame.g_median_depth).v[p] = median;
    if ((CHANNELS & 4u) != 0u) {
        Floats o = Floats(frame.g_normal);
        o.v[3 * p] = normal.x;
        o.v[3 * p + 1] = normal.y;
        o.v[3 * p + 2] = normal.z;
    }
    if ((CHANNELS & 8u) != 0u) {
        Floats o = Floats(frame.g_albedo);
        o.v[3 * p] = albedo.r;
        o.v[3 * p + 1] = albedo.g;
        o.v[3 * p + 2] = albedo.b;
    }
    if ((CHANNELS & 16u) != 0u) Floats(frame.g_roughness).v[p] = rough;
    if ((CHANNELS & 32u) != 0u) Floats(frame.g_metallic).v[p] = metal;
    if ((CHANNELS & 64u) != 0u) Floats(frame.g_ao).v[p] = ao;
    if ((CHANNELS & 128u) != 0u) Floats(frame.g_visibility).v[p] = vis;
    if (TOP) Uints(frame.g_top_gaussian).v[p] = acc.top_g;
}

#ifdef TEXEL_SPLATS
// PIXELS pixels per invocation, TILE / PIXELS apart along x (the host sets
// local_size_x to TILE / PIXELS): every splat's index, position and conic
// are fetched once for all of them, and its colour and features once if
// any of them takes it.
layout(constant_id = 2) const uint PIXELS = 1u;
// Half-row lanes (PIXELS = TILE / 2): invocation l shades half l / TILE of
// row l % TILE, its pixels side by side, so consecutive invocations (a
// subgroup) cover one half of the tile; otherwise a lane's pixels lie
// TILE / PIXELS apart along its row.
const bool HALVES = 2u * PIXELS == TILE;
const uint STEP = HALVES ? 1u : TILE / PIXELS;

// The split blend's buffers (CHUNK_PASS 1-3), by device address: each
// tile's first chunk slot (`list_chunks` scanned; then the total), and per
// chunk slot and tile pixel its transmittance product (pass 1) and its
// partial sums (pass 2, PARTIAL_FLOATS each: `store_partial`).
layout(push_constant) uniform ChunkPush {
    uvec2 slots;
    uvec2 transmittance;
    uvec2 partials;
} chunks;
const uint PARTIAL_FLOATS = 19u;
const uint PARTIAL_TOP_G = 17u;
const uint PARTIAL_START_T = 18u;

// Where field `field` of tile pixel `px` of chunk slot `slot` lies in the partials.
uint partial_index(uint slot, uint field, uint px) {
    return (slot * PARTIAL_FLOATS + field) * TILE_PIXELS + px;
}

// Pass 2's result for one pixel: what its chunk accumulated from the
// incoming transmittance `start_T` (which pass 3 needs to know whether the
// pixel was done before the chunk, and whose median the chunk gives).
void store_partial(uint slot, uint px, Accumulated acc, float start_T) {
    float f[PARTIAL_FLOATS] = float[](acc.T, acc.rgb.r, acc.rgb.g, acc.rgb.b, acc.depth, acc.median, acc.normal.x,
        acc.normal.y, acc.normal.z, acc.albedo.r, acc.albedo.g, acc.albedo.b, acc.rough, acc.metal, acc.ao, acc.vis,
        acc.top_w, 0.0, start_T);
    FloatsOut o = FloatsOut(chunks.partials);
    [[unroll]] for (uint i = 0u; i < PARTIAL_FLOATS; i++) {
        if (i != PARTIAL_TOP_G) o.v[partial_index(slot, i, px)] = f[i];
    }
    UintsOut(chunks.partials).v[partial_index(slot, PARTIAL_TOP_G, px)] = acc.top_g;
}

// Pass 3: tile pixel `px`'s chunks (slots first..first + count) added up in
// list order as one walk over the whole list would have: sums add, T is the
// last live chunk's, the median the crossing chunk's unless a later one
// found a nearer, opaque enough splat (`accumulate_select`), the top Gaussian
// the first of the largest weights.
Accumulated merged_chunks(uint first, uint count, uint px) {
    Accumulated acc = Accumulated(1.0, vec3(0.0), 0.0, 0.0, vec3(0.0), vec3(0.0), 0.0, 0.0, 0.0, 0.0, 0.0, NO_GAUSSIAN);
    FloatsIn f = FloatsIn(chunks.partials);
    for (uint c = 0u; c < count; c++) {
        uint s = first + c;
        float start_T = f.v[partial_index(s, PARTIAL_START_T, px)];
        // Done before this chunk, so before every later one too.
        if (!(start_T >= 1e-4)) break;
        acc.T = f.v[partial_index(s, 0u, px)];
        if (RGB) {
            acc.rgb += vec3(f.v[partial_index(s, 1u, px)], f.v[partial_index(s, 2u, px)], f.v[partial_index(s, 3u, px)]);
        }
        if ((CHANNELS & 1u) != 0u) acc.depth += f.v[partial_index(s, 4u, px)];
        if ((CHANNELS & 2u) != 0u) {
            float m = f.v[partial_index(s, 5u, px)];
            acc.median = start_T > MEDIAN_T ? m : min(acc.median, m);
        }
        if (FEATURES) {
            acc.normal += vec3(f.v[partial_index(s, 6u, px)], f.v[partial_index(s, 7u, px)],
                               f.v[partial_index(s, 8u, px)]);
            acc.albedo += vec3(f.v[partial_index(s, 9u, px)], f.v[partial_index(s, 10u, px)],
                               f.v[partial_index(s, 11u, px)]);
            acc.rough += f.v[partial_index(s, 12u, px)];
            acc.metal += f.v[partial_index(s, 13u, px)];
            acc.ao += f.v[partial_index(s, 14u, px)];
            acc.vis += f.v[partial_index(s, 15u, px)];
        }
        if (TOP) {
            float w = f.v[partial_index(s, 16u, px)];
            if (w > acc.top_w) {
                acc.top_w = w;
                acc.top_g = UintsIn(chunks.partials).v[partial_index(s, PARTIAL_TOP_G, px)];
            }
        }
    }
    return acc;
}

// Invocation l's first pixel within the tile.
uvec2 lane_pixel(uint l) {
    return HALVES ? uvec2((l / TILE) * PIXELS, l % TILE) : uvec2(l % gl_WorkGroupSize.x, l / gl_WorkGroupSize.x);
}

// The blocks (`tile_block_mask`'s bits) invocation l's pixels lie in.
uint lane_blocks(uint l) {
    uvec2 p = lane_pixel(l);
    uint last = p.x + (PIXELS - 1u) * STEP;
    uint bit = p.y / 2u;
    return (p.x < TILE / 2u ? 1u << bit : 0u) | (last >= TILE / 2u ? 1u << (TILE / 2u + bit) : 0u);
}

// An upper bound of log2(x) for finite x > 0, in a few operations: with
// x = m·2^e, m ∈ [0.5, 1), log2(m) is concave and so lies below its tangent at
// m = 0.75 (by at most 0.104).
float log2_upper(float x) {
    int e;
    float m = frexp(x, e);
    return float(e) - 0.4150375 + 1.9235933 * (m - 0.75);
}

// A splat's reach along pixel rows (`ellipse_rows`), so that a row's span
// costs one square root (`row_span`): `tile_ellipse`'s widened ellipse, its
// r² from `log2_upper` (so a little wider still). Every pixel the blend would
// take lies inside the span, widened by 0.01 px as `tile_block_mask`'s. A NaN
// slope reaches no pixel; q = ∞ every pixel of every row: where Q is too
// ill-conditioned, where r² is not a number, and for panoramas. With
// WINDOW_FETCH each lane computes it once for its own splat of the window,
// not every lane for every splat.
vec3 row_reach_of(vec4 head, vec4 conic) {
    const float INF = 1.0 / 0.0;
    const vec3 EVERY_ROW = vec3(0.0, INF, 0.0);
    if (WRAP_X) return EVERY_ROW;
    TileEllipse e = tile_ellipse_of(2.02 * 0.6931472 * log2_upper(255.0 * head.w) + 0.01, conic.xyz);
    if (!(e.r2 > 0.0)) return e.r2 <= 0.0 ? vec3(uintBitsToFloat(0x7fc00000u), 0.0, 0.0) : EVERY_ROW;
    if (!(e.det > 0.0)) return EVERY_ROW;
    return ellipse_rows(e);
}

// The pixel centres x ∈ [span.x, span.y] of the row at centre y that a
// splat (its `row_reach_of`) can reach at α ≥ 1/255 (empty where none).
vec2 row_span(vec3 reach, vec4 head, float y) {
    return ellipse_row_span(reach, head.xy, head.y - y);
}

// Blends splat g into one pixel of a lane (centre `centre`, still `live`)
// with no branch: `live` turns false once the pixel is done (T·(1−α) < 1e-4,
// this splat excluded, as `blend_one`).
void blend_pixel(inout Accumulated acc, inout bool live, float limit, uint g, vec4 head, vec4 conic, vec2 slope,
                 Contribution c, vec2 centre) {
    float alpha, gauss;
    vec2 d;
    bool hit = all(bvec2(live, splat_alpha(nearest_copy(head, centre), conic, centre, alpha, gauss, d)));
    // A surface depth away from the splat can be infinite (the ray parallel
    // to its plane), and its weight 0 would make it NaN: 0 where it misses.
    float z = mix(0.0, splat_depth(head, slope, d), hit);
    if (OCCLUDED) hit = all(bvec2(hit, z < limit));
    float next_T = acc.T * (1.0 - alpha);
    bool stop = all(bvec2(hit, next_T < 1e-4));
    // The split blend's transmittance pass multiplies every splat in: a
    // product below 1e-4 says the pixel is done, whichever splat stopped it.
    bool takes = all(bvec2(hit, CHUNK_PASS == 1u || !stop));
    live = all(bvec2(live, !stop));
    accumulate_select(acc, takes, alpha, next_T, z, c, g);
}

// A splat as a blend step takes it: its index, head, conic, colour texel
// (rgb, and the surface slope's y in w), feature words (`FEATURE_WORDS`: xy
// alone when packed) and row reach; members the kernel's constants do not use stay zero.
struct StepSplat {
    uint g;
    vec4 head, conic, color;
    uvec4 f0, f1, f2;
    vec3 reach_of;
};

// The splat of the tile list's entry `index`.
StepSplat fetch_step_splat(uint index) {
    StepSplat s = StepSplat(0u, vec4(0.0), vec4(0.0), vec4(0.0), uvec4(0u), uvec4(0u), uvec4(0u), vec3(0.0));
    s.g = texelFetch(value_texels, int(index)).x;
    s.head = texelFetch(splat_texels, int(4u * s.g));
    s.conic = texelFetch(splat_texels, int(4u * s.g + 1u));
    if (RGB || SURFACE_DEPTH) s.color = texelFetch(splat_texels, int(4u * s.g + 2u));
    if (FEATURES) {
        s.f0 = FEATURE_WORDS(3u * s.g);
        s.f1 = FEATURE_WORDS(3u * s.g + 1u);
        s.f2 = FEATURE_WORDS(3u * s.g + 2u);
    }
    if (PIXEL_REACH) s.reach_of = row_reach_of(s.head, s.conic);
    return s;
}

// Lane `from`'s splat, in every lane: a shuffle from a uniform lane, not a
// broadcast (on lavapipe from Mesa 25 the shuffle is the faster of the two).
StepSplat shuffled(StepSplat s, uint from) {
    StepSplat t = s;
    t.g = subgroupShuffle(s.g, from);
    t.head = subgroupShuffle(s.head, from);
    t.conic = subgroupShuffle(s.conic, from);
    if (RGB || SURFACE_DEPTH) t.color = subgroupShuffle(s.color, from);
    if (FEATURES) {
        if (PACKED_FEATURES) {
            t.f0.xy = subgroupShuffle(s.f0.xy, from);
            t.f1.xy = subgroupShuffle(s.f1.xy, from);
            t.f2.xy = subgroupShuffle(s.f2.xy, from);
        } else {
            t.f0 = subgroupShuffle(s.f0, from);
            t.f1 = subgroupShuffle(s.f1, from);
            t.f2 = subgroupShuffle(s.f2, from);
        }
    }
    if (PIXEL_REACH) t.reach_of = subgroupShuffle(s.reach_of, from);
    return t;
}

// Step splat `s`'s colour and features, unpacked once for all of a lane's pixels.
Contribution step_contribution(StepSplat s) {
    Contribution c = Contribution(s.color.rgb, vec4(0.0), vec4(0.0), vec4(0.0));
    if (FEATURES) features_of(s.f0, s.f1, s.f2, c);
    return c;
}

// Blends step splat `s` into one pixel of a lane (centre `centre`, at the
// row span `reach`): with PIXEL_REACH a pixel outside the span is not
// evaluated (the same result: it would not take the splat), so a pixel
// column no lane of the vector reaches costs a compare. Splats come in order
// of centre depth: once one lies at or behind the host's depth, so do the
// rest (`behind_host`).
void blend_step(inout Accumulated acc, inout bool live, float limit, StepSplat s, Contribution c, vec2 reach,
                vec2 centre) {
    vec2 slope = SURFACE_DEPTH ? vec2(s.conic.w, s.color.w) : vec2(0.0);
    if (PIXEL_REACH) {
        if (all(bvec3(live, centre.x >= reach.x, centre.x <= reach.y))) {
            blend_pixel(acc, live, limit, s.g, s.head, s.conic, slope, c, centre);
        }
    } else {
        blend_pixel(acc, live, limit, s.g, s.head, s.conic, slope, c, centre);
    }
    live = all(bvec2(live, !behind_host(s.head.z, limit)));
}

void main() {
    // Split-blend passes 1 and 2 run a workgroup per chunk slot, the others
    // one per tile: pass 0 blends the tiles whose lists are not split, pass 3
    // merges those that are.
    uint tile, slot = 0u, first_slot = 0u;
    uvec2 range;
    if (CHUNK_PASS == 1u || CHUNK_PASS == 2u) {
        slot = block_index();
        UintsIn first = UintsIn(chunks.slots);
        uint tiles = frame.size.z * frame.size.w;
        if (slot >= first.v[tiles]) return;
        // The tile holding the slot: the last whose first slot is at or before it.
        uint lo = 0u, hi = tiles;
        while (hi - lo > 1u) {
            uint mid = (lo + hi) / 2u;
            if (first.v[mid] <= slot) lo = mid; else hi = mid;
        }
        tile = lo;
        first_slot = first.v[tile];
        range = Uvec2s(frame.ranges).v[tile];
        range.x += (slot - first_slot) * CHUNK_LENGTH;
        range.y = min(range.y, range.x + CHUNK_LENGTH);
    } else {
        tile = block_index();
        // Grids past 65,535 workgroups may hold a few spare ones (`grid_1d`).
        if (tile >= frame.size.z * frame.size.w) return;
        if (TILE_MASK && !tile_wanted(tile)) return;
        range = Uvec2s(frame.ranges).v[tile];
        bool split = list_chunks(range, CHUNK_LENGTH) != 0u;
        if (CHUNK_PASS == 0u ? split : !split) return;
    }
    uint tiles_x = frame.size.z;
    uvec2 in_tile = lane_pixel(gl_LocalInvocationIndex);
    uvec2 base = uvec2(tile % tiles_x, tile / tiles_x) * TILE + in_tile;
    if (CHUNK_PASS == 3u) {
        uint first = UintsIn(chunks.slots).v[tile];
        uint count = UintsIn(chunks.slots).v[tile + 1u] - first;
        [[unroll]] for (uint k = 0u; k < PIXELS; k++) {
            uvec2 pix = base + uvec2(k * STEP, 0u);
            uint px = in_tile.y * TILE + in_tile.x + k * STEP;
            if (pix.x < frame.size.x && pix.y < frame.size.y) store_pixel(pix, merged_chunks(first, count, px));
        }
        return;
    }
    Accumulated acc[PIXELS];
    bool live[PIXELS];
    float limit[PIXELS];
    float start_T[PIXELS];
    bool any_live = false;
    [[unroll]] for (uint k = 0u; k < PIXELS; k++) {
        acc[k] = Accumulated(1.0, vec3(0.0), 0.0, 0.0, vec3(0.0), vec3(0.0), 0.0, 0.0, 0.0, 0.0, 0.0, NO_GAUSSIAN);
        uvec2 pix = base + uvec2(k * STEP, 0u);
        live[k] = pix.x < frame.size.x && pix.y < frame.size.y;
        limit[k] = live[k] ? occluder_z(pix) : 0.0;
        start_T[k] = 1.0;
        if (CHUNK_PASS == 2u) {
            // The incoming transmittance, the earlier chunks' products: below
            // 1e-4 the one-pass walk stopped before this chunk.
            uint px = in_tile.y * TILE + in_tile.x + k * STEP;
            FloatsIn products = FloatsIn(chunks.transmittance);
            for (uint s = first_slot; s < slot; s++) start_T[k] *= products.v[s * TILE_PIXELS + px];
            acc[k].T = start_T[k];
            live[k] = all(bvec2(live[k], start_T[k] >= 1e-4));
            // Past the crossing only a nearer, opaque enough splat sets the median (pass 3 takes the least).
            if (start_T[k] <= MEDIAN_T) acc[k].median = 1.0 / 0.0;
        }
        any_live = any_live || live[k];
    }
    // The tile blocks this invocation's subgroup covers, exactly (a ballot
    // per block: its lanes need not be consecutive invocations): a splat
    // whose block mask (ROW_MASKS) misses them is skipped.
    uint own_blocks = lane_blocks(gl_LocalInvocationIndex);
    uint blocks = 0u;
    for (uint b = 0u; b < TILE; b++) {
        if (subgroupBallot(((own_blocks >> b) & 1u) != 0u) != uvec4(0u)) blocks |= 1u << b;
    }
    // Lanes (of the first 32) that take part in the key windows below, and how many.
    uint lanes = subgroupBallot(true).x;
    uint lane = gl_SubgroupInvocationID;
    bool windowed = lane < 32u && ((lanes >> min(lane, 31u)) & 1u) != 0u;
    uint rank = windowed ? bitCount(lanes & ((1u << lane) - 1u)) : 0u;
    uint width = bitCount(lanes);
    // Updates are selects and colour is fetched always: Mesa 22.3's lavapipe
    // runs both sides of every `if` under a mask (only loop exits jump), so
    // finding the next wanted splat is a loop of its own. From Mesa 25 it
    // jumps over an `if` no lane of the vector enters, which the per-pixel
    // reach below uses. Keys are tested a window at a time, one per lane (one
    // gather for the window, not one per key); `window` holds the lanes whose
    // keys the subgroup wants, in key order. Every lane stays in the loop
    // until all are done, so each window is whole.
    uint next = range.x, window_start = range.x, window = 0u;
    // WINDOW_FETCH: each lane's wanted splat of the current window.
    StepSplat lane_splat = StepSplat(0u, vec4(0.0), vec4(0.0), vec4(0.0), uvec4(0u), uvec4(0u), uvec4(0u), vec3(0.0));
    // The lane's first pixel centre, converted once: each pixel's is a constant step on (exact in float).
    vec2 first_centre = vec2(base) + 0.5;
    while (subgroupBallot(any_live) != uvec4(0u)) {
        if (!WINDOW_FETCH || window == 0u) {
            while (window == 0u && next < range.y) {
                uint key = next + rank;
                bool want = windowed && key < range.y
                    && (!ROW_MASKS || ((texelFetch(key_texels, int(2u * key + 1u)).x >> (32u - TILE)) & blocks) != 0u);
                window = subgroupBallot(want).x;
                window_start = next;
                next += width;
            }
            if (window == 0u) break;
            if (WINDOW_FETCH) {
                // One fetch per window serves every wanted key of it: lane
                // `l` holds the splat of key window_start + rank(l).
                lane_splat = fetch_step_splat(min(window_start + rank, range.y - 1u));
            }
        }
        uint first_lane = uint(findLSB(window));
        window &= window - 1u;
        // TWO_SPLATS: the window's next wanted splat too, where it has one.
        bool second = WINDOW_FETCH && TWO_SPLATS && window != 0u;
        uint second_lane = second ? uint(findLSB(window)) : first_lane;
        if (second) window &= window - 1u;
        // Every lane fetches the same texels without the window fetch: one
        // vector gather each, no election or broadcast.
        StepSplat s1 = WINDOW_FETCH ? shuffled(lane_splat, first_lane)
                                    : fetch_step_splat(window_start + bitCount(lanes & ((1u << first_lane) - 1u)));
        StepSplat s2 = s1;
        if (TWO_SPLATS) s2 = shuffled(lane_splat, second_lane);
        float row = first_centre.y;
        vec2 reach1 = PIXEL_REACH ? row_span(s1.reach_of, s1.head, row) : vec2(0.0);
        vec2 reach2 = PIXEL_REACH && TWO_SPLATS ? row_span(s2.reach_of, s2.head, row) : vec2(0.0);
        Contribution c1 = step_contribution(s1);
        Contribution c2 = TWO_SPLATS ? step_contribution(s2) : c1;
        [[unroll]] for (uint k = 0u; k < PIXELS; k++) {
            vec2 centre = vec2(first_centre.x + float(k * STEP), first_centre.y);
            blend_step(acc[k], live[k], limit[k], s1, c1, reach1, centre);
            if (TWO_SPLATS) {
                bool live2 = all(bvec2(live[k], second));
                blend_step(acc[k], live2, limit[k], s2, c2, reach2, centre);
                live[k] = second ? live2 : live[k];
            }
        }
        any_live = false;
        [[unroll]] for (uint k = 0u; k < PIXELS; k++) any_live = any(bvec2(any_live, live[k]));
    }
    [[unroll]] for (uint k = 0u; k < PIXELS; k++) {
        uvec2 pix = base + uvec2(k * STEP, 0u);
        uint px = in_tile.y * TILE + in_tile.x + k * STEP;
        // An `if`, not a `continue`: an unrolled loop must not leave early
        // (spirv/tests/unrolled_loops.rs says why).
        if (pix.x < frame.size.x && pix.y < frame.size.y) {
            if (CHUNK_PASS == 0u) store_pixel(pix, acc[k]);
            if (CHUNK_PASS == 1u) FloatsOut(chunks.transmittance).v[slot * TILE_PIXELS + px] = acc[k].T;
            if (CHUNK_PASS == 2u) store_partial(slot, px, acc[k], start_T[k]);
        }
    }
}
#else
void main() {
    uint tile = block_index();
    // Grids past 65,535 workgroups may hold a few spare ones (`grid_1d`).
    if (tile >= frame.size.z * frame.size.w) return;
    if (TILE_MASK && !tile_wanted(tile)) return;
    uint tiles_x = frame.size.z;
    uint local = gl_LocalInvocationIndex;
    uvec2 pix = uvec2(tile % tiles_x, tile / tiles_x) * TILE + gl_LocalInvocationID.xy;
    bool inside = pix.x < frame.size.x && pix.y < frame.size.y;
    vec2 centre = vec2(pix) + 0.5;
    uvec2 range = Uvec2s(frame.ranges).v[tile];
    Uints values = Uints(frame.values);
    Splats splats = Splats(frame.splats);
    Accumulated acc = Accumulated(1.0, vec3(0.0), 0.0, 0.0, vec3(0.0), vec3(0.0), 0.0, 0.0, 0.0, 0.0, 0.0, NO_GAUSSIAN);
    float limit = inside ? occluder_z(pix) : 0.0;

#ifdef SHARED_BATCHES
    // Batches of BLEND_BATCH splats staged in shared memory by the whole
    // workgroup; every invocation takes part in every barrier (pixels outside
    // the image and finished pixels only load), and the tile stops as soon as
    // all its pixels are done.
    bool done = !inside;
    for (uint start = range.x; start < range.y; start += BLEND_BATCH) {
        if (local == 0u) done_count = 0u;
        barrier();
        if (done) atomicAdd(done_count, 1u);
        barrier();
        if (done_count == TILE_PIXELS) break;
        uint j = start + local;
        if (local < BLEND_BATCH && j < range.y) {
            uint g = values.v[j];
            batch_g[local] = g;
            batch_head[local] = splats.v[g].head;
            batch_conic[local] = splats.v[g].conic;
        }
        barrier();
        if (!done) {
            uint n = min(BLEND_BATCH, range.y - start);
            for (uint k = 0u; k < n; k++) {
                if (!blend_one(acc, batch_g[k], batch_head[k], batch_conic[k], centre, limit)) {
                    done = true;
                    break;
                }
            }
        }
        barrier();
    }
    if (!inside) return;
#else
    if (!inside) return;
    for (uint j = range.x; j < range.y; j++) {
#if defined(SUBGROUP_LOADS)
        // Every active lane reads the same splat: one elected lane loads, the
        // subgroup shares (any subgroup size; per-lane loads are slow on lavapipe).
        uint g = 0u;
        vec4 head = vec4(0.0), conic = vec4(0.0);
        if (subgroupElect()) {
            g = values.v[j];
            head = splats.v[g].head;  // mean, depth, opacity
            conic = splats.v[g].conic;
        }
        g = subgroupBroadcastFirst(g);
        head = subgroupBroadcastFirst(head);
        conic = subgroupBroadcastFirst(conic);
#else
        uint g = values.v[j];
        vec4 head = splats.v[g].head;  // mean, depth, opacity
        vec4 conic = splats.v[g].conic;
#endif
        if (!blend_one(acc, g, head, conic, centre, limit)) break;
    }
#endif
    store_pixel(pix, acc);
}
#endif
