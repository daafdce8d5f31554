// Body of splat_preprocess*.comp (see their headers). Splatting stage 1, one
// invocation per Gaussian: activation, culling, EWA projection, conic,
// radius, SH colour, tile rectangle and count, and (when asked) the
// per-splat features. Culled Gaussians get a tile count of 0 and no splat
// record: every reader of the records reaches them through a pair, or (the
// backward pass) only where the tile count is not 0. Compacted records
// (COMPACT): a first dispatch flags the Gaussians the position cull keeps, a
// scan gives each its slot, and a second writes their records at those slots.
// CPU twin: engine/src/splat/cpu.rs `preprocess_one`.
#extension GL_EXT_control_flow_attributes : require
// 256 invocations a workgroup, one per Gaussian: fewer workgroups for a CPU
// implementation to launch (docs/bench/splat.md, "Larger workgroups").
#define WORKGROUP_SIZE_X 256
#include "common.glsl"
#include "splat.glsl"
#include "sh.glsl"
#include "surface_slope.glsl"

#ifdef TEXEL_INPUTS
// The scene's Gaussian arrays as R32F texel-buffer views (bindings 1-5): on
// lavapipe a texelFetch is one vector gather, a device-address load a loop
// over the lanes.
layout(set = 0, binding = 1) uniform textureBuffer mean_texels;
layout(set = 0, binding = 2) uniform textureBuffer log_scale_texels;
layout(set = 0, binding = 3) uniform textureBuffer rotation_texels;
layout(set = 0, binding = 4) uniform textureBuffer opacity_texels;
layout(set = 0, binding = 5) uniform textureBuffer sh_texels;
// Rotations viewed as RGBA32F (one fetch per Gaussian) and, where the SH
// coefficients of a Gaussian fill whole vec4s (degrees 1 and 3), the SH too.
layout(constant_id = 6) const bool ROTATION_VEC4 = false;
layout(constant_id = 7) const bool SH_VEC4 = false;
// Means and log-scales viewed as RGB32F (one fetch per Gaussian each).
layout(constant_id = 8) const bool TRIPLES_VEC3 = false;
#define MEAN3(i) (TRIPLES_VEC3 ? texelFetch(mean_texels, int(i)).xyz : vec3(MEAN(3 * (i)), MEAN(3 * (i) + 1), MEAN(3 * (i) + 2)))
#define LOG_SCALE3(i) (TRIPLES_VEC3 ? texelFetch(log_scale_texels, int(i)).xyz \
                                    : vec3(LOG_SCALE(3 * (i)), LOG_SCALE(3 * (i) + 1), LOG_SCALE(3 * (i) + 2)))
#define MEAN(k) texelFetch(mean_texels, int(k)).x
#define LOG_SCALE(k) texelFetch(log_scale_texels, int(k)).x
#define ROTATION(k) texelFetch(rotation_texels, int(k)).x
#define ROTATION4(i) texelFetch(rotation_texels, int(i))
#define OPACITY_LOGIT(k) texelFetch(opacity_texels, int(k)).x
#define SH(k) texelFetch(sh_texels, int(k)).x
#define SH4(q) texelFetch(sh_texels, int(q))
#else
const bool ROTATION_VEC4 = false;
const bool SH_VEC4 = false;
#define ROTATION4(i) vec4(0.0)
#define SH4(q) vec4(0.0)
#define MEAN3(i) vec3(MEAN(3 * (i)), MEAN(3 * (i) + 1), MEAN(3 * (i) + 2))
#define LOG_SCALE3(i) vec3(LOG_SCALE(3 * (i)), LOG_SCALE(3 * (i) + 1), LOG_SCALE(3 * (i) + 2))
#define MEAN(k) FloatsIn(frame.means).v[k]
#define LOG_SCALE(k) FloatsIn(frame.log_scales).v[k]
#define ROTATION(k) FloatsIn(frame.rotations).v[k]
#define OPACITY_LOGIT(k) FloatsIn(frame.opacity_logits).v[k]
#define SH(k) FloatsIn(frame.sh).v[k]
#endif

layout(constant_id = 0) const bool WRITE_FEATURES = false;
// The feature channels the frame blends (engine/src/splat/channels.rs `Channel::bit`: normal 4,
// albedo 8, roughness 16, metallic 32, ao 64, visibility 128): only their attributes are read,
// and a material no channel takes is stored as 0 (the normal as the shortest axis).
layout(constant_id = 12) const uint FEATURE_CHANNELS = 252u;
// Features at 16 bits (`PackedFeatures` in splat_types.glsl), else as floats.
layout(constant_id = 9) const bool PACKED_FEATURES = false;
// Count only the tiles whose square can see the splat at α ≥ 1/255
// (`tile_row_span`), not its whole 3σ rectangle. The keys kernel must agree.
layout(constant_id = 1) const bool ELLIPSE_TILES = false;
// Surface depth: store how the depth where a pixel's ray meets the splat's
// plane changes across the image (surface_slope.glsl).
layout(constant_id = 2) const bool SURFACE_DEPTH = false;
// Tile edge in pixels (engine/src/splat/mod.rs `TILE_SPEC_IDS`; the blend's workgroup edge).
layout(constant_id = 15) const uint TILE = 16u;
// The SH degree used for colour (≤ the scene's, frame.counts.y >> 8): a
// constant, so the colour loop unrolls and each basis function is straight
// code (lavapipe would run every case of `sh_basis`'s switch under a mask).
layout(constant_id = 3) const uint SH_USED = 3u;
// Whether the frame blends the splats' colour: without it no SH coefficient is
// read and the records' colour is 0 (engine/src/splat/forward.rs, `SplatSettings::rgb`).
layout(constant_id = 11) const bool COLOUR = true;
// Count only the tiles the frame's tile mask wants (`tile_wanted`); the keys
// kernel must agree. Not for wrapping panoramas (the host refuses them).
layout(constant_id = 5) const bool TILE_MASK = false;
// Records (engine/src/splat/mod.rs `SplatSettings::compact_splats`): 0 one
// per Gaussian; 1 only flag (frame.visible_slots) the Gaussians the position
// cull keeps; 2 write each flagged Gaussian's id, and unless a later test
// culls it its record and tile count, at its scanned slot.
layout(constant_id = 10) const uint COMPACT = 0u;

float sigmoid(float x) {
    float e = exp(-abs(x));
    return x >= 0.0 ? 1.0 / (1.0 + e) : e / (1.0 + e);
}

bool finite(float x) { return !isnan(x) && !isinf(x); }

// `slot`: where the Gaussian's record goes (its index unless compacted).
// Every Gaussian writes its flag (COMPACT 1) or its record's tile count, so
// the host fills only the scan's total word.
void cull(uint slot) {
    if (COMPACT == 1u) Uints(frame.visible_slots).v[slot] = 0u;
    else Uints(frame.tile_counts).v[slot] = 0u;
}

void main() {
    uint i = linear_index();
    if (i >= frame.counts.x) return;
    uint slot = i;
    if (COMPACT == 2u) {
        UintsIn visible = UintsIn(frame.visible_slots);
        slot = visible.v[i];
        if (visible.v[i + 1u] == slot) return;
        // Every slot names its Gaussian, even one a later test culls.
        Uints(frame.slot_gaussians).v[slot] = i;
    }
    vec3 p = MEAN3(i);
    mat3 W = world_to_camera_rotation(frame.camera);
    vec3 t = W * (p - frame.camera.position.xyz);
    bool ortho = frame.camera.position.w != 0.0;
    // Equirectangular cameras see all around: depth is the distance, and a
    // full panorama (clip.z: its width) wraps at its left and right edges.
    bool equirect = frame.camera.lens2.x == 9.0;
    float near = frame.clip.x, far = frame.clip.y;
    float depth = equirect ? length(t) : t.z;
    if (!(depth > near && depth < far)) { cull(slot); return; }

    // Cull on the position and the largest scale before reading the rest
    // (pinhole and orthographic cameras): the radius 3·sqrt(λ) is at most
    // 3·sqrt(‖J‖²_F·σ_max² + 0.3 + 0.32) + 1 (the dilation, `lambda`'s floor
    // of 0.1 under its root, the ceil), with 1% and 1 px to spare for f32
    // rounding; a square of that half-width off the tiles the frame keeps
    // (`cull_tiles`: the grid, or the tile mask's wanted tiles' bounds, and
    // then each tile row's wanted columns) gets no tile there. NaN or Inf
    // never culls in the bounds test (the full test below decides); a NaN
    // position fails the rows' test, as it would the full one.
    vec3 log_s = LOG_SCALE3(i);
    if (!equirect && frame.camera.lens2.x == 0.0) {
        vec4 k = frame.camera.intrinsics;
        vec2 m = ortho ? vec2(k.x * t.x + k.z, k.y * t.y + k.w) : vec2(k.x * t.x / t.z + k.z, k.y * t.y / t.z + k.w);
        vec2 lim = frame.clip.zw;
        float j2 = ortho ? k.x * k.x + k.y * k.y
                         : (k.x * k.x * (1.0 + lim.x * lim.x) + k.y * k.y * (1.0 + lim.y * lim.y)) / (t.z * t.z);
        float sigma = exp(max(max(log_s.x, log_s.y), log_s.z));
        float bound = 1.01 * (3.0 * sqrt(j2 * sigma * sigma + 0.62) + 1.0) + 1.0;
        // The tiles the frame keeps splats for: the image's, or the wanted tiles' bounds (empty: none).
        vec2 lo = vec2(frame.cull_tiles.xy * TILE), hi = vec2(frame.cull_tiles.zw * TILE);
        if (any(lessThan(m + bound, lo)) || any(greaterThanEqual(m - bound, hi)) || any(greaterThanEqual(lo, hi))) {
            cull(slot);
            return;
        }
        if (TILE_MASK) {
            // A square that meets no tile row's wanted columns (their hull) gets no wanted tile.
            Uvec2sIn rows = Uvec2sIn(frame.wanted_rows);
            vec2 first = max(floor((m - bound) / float(TILE)), vec2(frame.cull_tiles.xy));
            vec2 last = min(floor((m + bound) / float(TILE)), vec2(frame.cull_tiles.zw) - 1.0);
            bool meets = false;
            for (float ty = first.y; ty <= last.y && !meets; ty += 1.0) {
                uvec2 span = rows.v[whole_to_uint(ty)];
                meets = last.x >= uint_to_whole(span.x) && first.x < uint_to_whole(span.y);
            }
            if (!meets) { cull(slot); return; }
        }
    }
    if (COMPACT == 1u) {
        Uints(frame.visible_slots).v[i] = 1u;
        return;
    }

    // 3D covariance.
    vec3 s = exp(log_s);
    vec4 q = ROTATION_VEC4 ? ROTATION4(i)
                           : vec4(ROTATION(4 * i), ROTATION(4 * i + 1), ROTATION(4 * i + 2), ROTATION(4 * i + 3));
    q /= max(max(abs(q.x), abs(q.y)), max(abs(q.z), abs(q.w)));
    q /= length(q);
    float qw = q.x, qx = q.y, qy = q.z, qz = q.w;
    mat3 R = mat3(
        1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy + qw * qz), 2.0 * (qx * qz - qw * qy),
        2.0 * (qx * qy - qw * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qw * qx),
        2.0 * (qx * qz + qw * qy), 2.0 * (qy * qz - qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy));
    mat3 M = R * mat3(s.x, 0.0, 0.0, 0.0, s.y, 0.0, 0.0, 0.0, s.z);
    mat3 cov_world = M * transpose(M);
    mat3 cov_cam = W * cov_world * transpose(W);

    // EWA: J Σ Jᵀ, Jacobian clamped beyond the image (pinhole), + 0.3 px² dilation.
    vec4 k = frame.camera.intrinsics;
    vec2 mean;
    mat3 J;  // only the first two rows are used
    if (ortho) {
        mean = vec2(k.x * t.x + k.z, k.y * t.y + k.w);
        J = mat3(k.x, 0.0, 0.0, 0.0, k.y, 0.0, 0.0, 0.0, 0.0);
    } else if (frame.camera.lens2.x != 0.0) {
        // Through the lens: the mean lands where the lens sends it, the
        // covariance follows the lens's local Jacobian (no clamp: the lens
        // bounds the image itself).
        vec2 dn;
        mat3 Jn;
        if (!lens_project(frame.camera, t, dn, Jn)) { cull(slot); return; }
        mean = k.xy * dn + k.zw;
        J = mat3(k.x * Jn[0][0], k.y * Jn[0][1], 0.0,
                 k.x * Jn[1][0], k.y * Jn[1][1], 0.0,
                 k.x * Jn[2][0], k.y * Jn[2][1], 0.0);
    } else {
        mean = vec2(k.x * t.x / t.z + k.z, k.y * t.y / t.z + k.w);
        float tx = clamp(t.x / t.z, -frame.clip.z, frame.clip.z) * t.z;
        float ty = clamp(t.y / t.z, -frame.clip.w, frame.clip.w) * t.z;
        // Column-major: J[c][r].
        J = mat3(k.x / t.z, 0.0, 0.0,
                 0.0, k.y / t.z, 0.0,
                 -k.x * tx / (t.z * t.z), -k.y * ty / (t.z * t.z), 0.0);
    }
    mat3 cov2 = J * cov_cam * transpose(J);
    float a = cov2[0][0] + 0.3, b = cov2[1][0], c = cov2[1][1] + 0.3;
    float det = a * c - b * b;
    if (!(det > 0.0) || !finite(det) || !finite(mean.x) || !finite(mean.y)) { cull(slot); return; }
    vec3 conic = vec3(c, -b, a) / det;
    float mid = 0.5 * (a + c);
    float lambda = mid + sqrt(max(0.1, mid * mid - det));
    float radius = ceil(3.0 * sqrt(lambda));
    if (!finite(radius) || !all(bvec3(finite(conic.x), finite(conic.y), finite(conic.z)))) { cull(slot); return; }

    // Tile rectangle [x0, x1) × [y0, y1).
    vec2 tiles = vec2(frame.size.zw);
    vec2 lo = clamp(floor((mean - radius) / float(TILE)), vec2(0.0), tiles);
    vec2 hi = clamp(floor((mean + radius) / float(TILE)) + 1.0, vec2(0.0), tiles);
    if (equirect && frame.clip.z > 0.0) {
        // Columns past the right edge continue at the left: x1 may exceed
        // tiles_x (the keys take x mod tiles_x); x0 < tiles_x, x1 − x0 ≤ tiles_x.
        float period = frame.clip.z;
        mean.x -= period * floor(mean.x / period);
        float a = mean.x - radius, b = mean.x + radius;
        if (a < 0.0) { a += period; b += period; }
        lo.x = floor(a / float(TILE));
        hi.x = b <= period ? min(floor(b / float(TILE)) + 1.0, tiles.x)
                           : tiles.x + floor((b - period) / float(TILE)) + 1.0;
        if (2.0 * radius >= period) { lo.x = 0.0; hi.x = tiles.x; }
        hi.x = min(hi.x, lo.x + tiles.x);
    }
    // Whole numbers in [0, 2^23) (`whole_to_uint`; the host keeps tile columns and rows below 2^22).
    uvec4 rect = whole_to_uint(vec4(lo, hi));
    uint count = (rect.z - rect.x) * (rect.w - rect.y);
    vec4 head = vec4(mean, depth, sigmoid(OPACITY_LOGIT(i)));
    if (ELLIPSE_TILES && count != 0u && rect.z <= frame.size.z) {
        TileEllipse e = tile_ellipse(head, conic);
        // Rows and spans in floats; each row's width (under 2^22) to uint with `whole_to_uint`.
        vec4 rect_f = vec4(lo, hi);
        count = 0u;
        for (float ty = rect_f.y; ty < rect_f.w; ty += 1.0) {
            vec2 span = tile_row_span_f(e, mean, rect_f, ty, float(TILE));
            count += whole_to_uint(span.y - span.x);
        }
    }
    if (TILE_MASK && count != 0u) {
        count = 0u;
        TileEllipse e = tile_ellipse(head, conic);
        for (uint ty = rect.y; ty < rect.w; ty++) {
            uvec2 span = ELLIPSE_TILES ? tile_row_span(e, mean, rect, ty, TILE) : rect.xz;
            for (uint tx = span.x; tx < span.y; tx++) count += tile_wanted(ty * frame.size.z + tx) ? 1u : 0u;
        }
    }
    if (count == 0u) { cull(slot); return; }

    // View-dependent colour, where the frame blends it.
    vec3 color = vec3(0.0);
    if (COLOUR) {
        vec3 dir = ortho ? frame.view_dir.xyz : normalize(p - frame.eye.xyz);
        uint stored = frame.counts.y & 255u;
        uint K = (stored + 1) * (stored + 1);
        const uint USED = (SH_USED + 1) * (SH_USED + 1);
        if (SH_VEC4) {
            // The used coefficients' floats in whole vec4s (within the Gaussian's own, K·3 being a multiple of 4).
            float c[(USED * 3 + 3) / 4 * 4];
            uint base = i * K * 3 / 4;
            [[unroll]] for (uint v = 0; v < (USED * 3 + 3) / 4; v++) {
                vec4 f = SH4(base + v);
                c[4 * v] = f.x;
                c[4 * v + 1] = f.y;
                c[4 * v + 2] = f.z;
                c[4 * v + 3] = f.w;
            }
            [[unroll]] for (uint j = 0; j < USED; j++) color += sh_basis(j, dir) * vec3(c[3 * j], c[3 * j + 1], c[3 * j + 2]);
        } else {
            [[unroll]] for (uint j = 0; j < USED; j++) {
                uint o = (i * K + j) * 3;
                color += sh_basis(j, dir) * vec3(SH(o), SH(o + 1), SH(o + 2));
            }
        }
        color = max(color + 0.5, vec3(0.0));
    }

    vec2 slope = vec2(0.0);
    if (SURFACE_DEPTH && !equirect && frame.camera.lens2.x == 0.0) {
        vec3 axis = s.x <= s.y && s.x <= s.z ? R[0] : (s.y <= s.z ? R[1] : R[2]);
        float extent = 3.0 * sqrt(max(cov_cam[2][2], 0.0));
        vec3 own = vec3(cov2[0][0], cov2[1][0], cov2[1][1]);
        slope = surface_slope(W * axis, t, k.xy, ortho, extent, own);
    }
    Splats(frame.splats).v[slot] = Splat(head, vec4(conic, slope.x), vec4(color, slope.y), rect);
    Uints(frame.tile_counts).v[slot] = count;

    if (WRITE_FEATURES) {
        // Normal: the stored one when asked for and non-zero, else the shortest axis; toward the camera.
        vec3 n = vec3(0.0);
        if ((FEATURE_CHANNELS & 4u) != 0u && frame.counts.z == 1u && frame.normals.x + frame.normals.y != 0u) {
            FloatsIn nb = FloatsIn(frame.normals);
            n = vec3(nb.v[3 * i], nb.v[3 * i + 1], nb.v[3 * i + 2]);
        }
        if (dot(n, n) == 0.0) {
            n = s.x <= s.y && s.x <= s.z ? R[0] : (s.y <= s.z ? R[1] : R[2]);
        }
        n = normalize(n);
        vec3 toward = ortho ? -frame.view_dir.xyz : frame.eye.xyz - p;
        if (dot(n, toward) < 0.0) n = -n;
        vec3 albedo = vec3(0.0);
        float rough = 0.0, metal = 0.0, ao = 0.0, vis = 0.0;
        if ((FEATURE_CHANNELS & 8u) != 0u && frame.albedo.x + frame.albedo.y != 0u) {
            FloatsIn al = FloatsIn(frame.albedo);
            albedo = vec3(sigmoid(al.v[3 * i]), sigmoid(al.v[3 * i + 1]), sigmoid(al.v[3 * i + 2]));
        }
        if ((FEATURE_CHANNELS & 16u) != 0u && frame.roughness.x + frame.roughness.y != 0u) {
            rough = sigmoid(FloatsIn(frame.roughness).v[i]);
        }
        if ((FEATURE_CHANNELS & 32u) != 0u && frame.metallic.x + frame.metallic.y != 0u) {
            metal = sigmoid(FloatsIn(frame.metallic).v[i]);
        }
        if ((FEATURE_CHANNELS & 64u) != 0u && frame.ao.x + frame.ao.y != 0u) ao = sigmoid(FloatsIn(frame.ao).v[i]);
        if ((FEATURE_CHANNELS & 128u) != 0u && frame.visibility.x + frame.visibility.y != 0u) {
            vis = sigmoid(FloatsIn(frame.visibility).v[i]);
        }
        if (PACKED_FEATURES) {
            PackedFeatures f = PackedFeatures(frame.features);
            pack_features(n, rough, albedo, metal, ao, vis, f.v[3 * slot], f.v[3 * slot + 1], f.v[3 * slot + 2]);
        } else {
            Features f = Features(frame.features);
            f.v[3 * slot] = vec4(n, rough);
            f.v[3 * slot + 1] = vec4(albedo, metal);
            f.v[3 * slot + 2] = vec4(ao, vis, 0.0, 0.0);
        }
    }
}
