#version 460
// Splat backward, step 1: one workgroup per tile, one invocation per pixel.
// Each pixel replays its forward blend (the same splat_alpha, so the same
// contributors, final transmittance and median splat), then walks its splats
// back to front (docs/conventions.md §4): T ← T / (1 − α); dL/dx = α·T·dL/dC;
// dL/dα = Σ dL/dC·(x·T − S/(1 − α)) + (dL/dA − bg·dL/dC_rgb)·T_final/(1 − α);
// S ← S + x·α·T; α clamped at 0.99 passes no geometric gradient. With
// surface depths a pixel's depth gradient also moves the splat's centre and
// slope (z = z₀/(1 + s·Δ), orthographic z₀ + s·Δ, Δ = centre − mean). The tile's
// pixels are summed per splat in pixel order (deterministic) into that
// (tile, splat) pair's record, where the keys kernel put the pair (found by
// binary search in the splat's run of pair tiles, which is in tile order), so
// step 2 can sum each Gaussian's records in order without atomics.
// CPU twin: engine/src/splat/cpu_backward.rs `blend_backward_cpu`.
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#define TILE_WORKGROUP
#include "common.glsl"
#include "splat.glsl"
#include "splat_backward.glsl"

// Splats per barrier, set by the host so every pixel's terms for a batch fit
// shared memory (BATCH × STRIDE × TILE_PIXELS floats) and BATCH × STRIDE ≤ TILE_PIXELS.
layout(constant_id = 1) const uint BATCH = 3;
// The transmittance at which the forward blend read the median depth (splat_blend_body.glsl `MEDIAN_T`).
layout(constant_id = 3) const float MEDIAN_T = 0.5;
// Every pixel's terms per (splat of the batch, component); summed in pixel
// order by one invocation per (splat, component): deterministic and cheap
// (on lavapipe a subgroupAdd costs ~100 ns, a shared load ~1 ns).
shared float terms[BATCH * STRIDE * TILE_PIXELS];
shared uint tile_end;

// Whether blended value k (rgb, depth, ten features) has a gradient.
bool value_used(uint k) {
    if (k < 3u) return GRAD_RGB;
    if (k == 3u) return (GRADS & 1u) != 0u;
    if (k < 7u) return (GRADS & 4u) != 0u;
    if (k == 7u) return (GRADS & 16u) != 0u;
    if (k < 11u) return (GRADS & 8u) != 0u;
    if (k == 11u) return (GRADS & 32u) != 0u;
    if (k == 12u) return (GRADS & 64u) != 0u;
    return (GRADS & 128u) != 0u;
}

float grad_in(uvec2 addr, uint i) { return FloatsIn(addr).v[i]; }

void main() {
    uint tile = block_index();
    // Grids past 65,535 workgroups may hold a few spare ones (`grid_1d`): the whole workgroup leaves.
    if (tile >= frame.size.z * frame.size.w) return;
    uint tiles_x = frame.size.z;
    uint local = gl_LocalInvocationIndex;
    uvec2 tile_xy = uvec2(tile % tiles_x, tile / tiles_x);
    uvec2 pix = tile_xy * TILE + gl_LocalInvocationID.xy;
    bool inside = pix.x < frame.size.x && pix.y < frame.size.y;
    uint p = pix.y * frame.size.x + pix.x;
    vec2 centre = vec2(pix) + 0.5;
    uvec2 range = Uvec2s(frame.ranges).v[tile];
    Uints order = Uints(frame.values);
    Splats splats = Splats(frame.splats);
    Features features = Features(frame.features);

    // This pixel's loss gradients: values (rgb, depth, ten features), alpha, median.
    float dv[14];
    for (uint k = 0u; k < 14u; k++) dv[k] = 0.0;
    float d_alpha_out = 0.0, d_median = 0.0;
    if (inside) {
        if (GRAD_RGB) for (uint c = 0u; c < 3u; c++) dv[c] = grad_in(bwd.d_rgb, 3u * p + c);
        if ((GRADS & 512u) != 0u) d_alpha_out = grad_in(bwd.d_alpha, p);
        if ((GRADS & 1u) != 0u) dv[3] = grad_in(bwd.d_depth, p);
        if ((GRADS & 2u) != 0u) d_median = grad_in(bwd.d_median_depth, p);
        if ((GRADS & 4u) != 0u) for (uint c = 0u; c < 3u; c++) dv[4u + c] = grad_in(bwd.d_normal, 3u * p + c);
        if ((GRADS & 16u) != 0u) dv[7] = grad_in(bwd.d_roughness, p);
        if ((GRADS & 8u) != 0u) for (uint c = 0u; c < 3u; c++) dv[8u + c] = grad_in(bwd.d_albedo, 3u * p + c);
        if ((GRADS & 32u) != 0u) dv[11] = grad_in(bwd.d_metallic, p);
        if ((GRADS & 64u) != 0u) dv[12] = grad_in(bwd.d_ao, p);
        if ((GRADS & 128u) != 0u) dv[13] = grad_in(bwd.d_visibility, p);
    }

    // Replay the forward blend: where it stopped, the final T and the median
    // splat (with surface depths, a later half-opaque splat nearer at the pixel
    // takes the median over, as the blend's `accumulate_select`).
    bool ortho = frame.camera.position.w != 0.0;
    float T = 1.0, median_z = 0.0;
    uint end = range.x, median_j = 0xffffffffu;
    if (inside) {
        for (uint j = range.x; j < range.y; j++) {
            vec4 head = vec4(0.0), conic = vec4(0.0), color = vec4(0.0);
            if (subgroupElect()) {
                uint g = order.v[j];
                head = splats.v[g].head;
                conic = splats.v[g].conic;
                if (SURFACE_DEPTH) color = splats.v[g].color;
            }
            head = subgroupBroadcastFirst(head);
            conic = subgroupBroadcastFirst(conic);
            if (SURFACE_DEPTH) color = subgroupBroadcastFirst(color);
            float alpha, gauss;
            vec2 d;
            if (!splat_alpha(head, conic, centre, alpha, gauss, d)) continue;
            float next_T = T * (1.0 - alpha);
            if (next_T < 1e-4) break;
            float z = depth_at(head.z, stored_slope(conic, color), d, ortho);
            if ((T > MEDIAN_T && next_T <= MEDIAN_T) ||
                (SURFACE_DEPTH && T <= MEDIAN_T && alpha >= 1.0 - MEDIAN_T && z < median_z)) {
                median_j = j;
                median_z = z;
            }
            T = next_T;
            end = j + 1u;
        }
    }
    if (local == 0u) tile_end = range.x;
    barrier();
    atomicMax(tile_end, end);
    barrier();
    uint last = tile_end;

    float t_final = T;
    float bg_term = d_alpha_out;
    for (uint c = 0u; c < 3u; c++) bg_term -= frame.background[c] * dv[c];
    float behind[14];
    for (uint k = 0u; k < 14u; k++) behind[k] = 0.0;

    uint count = last - range.x;  // splats walked, back to front
    for (uint base = 0u; base < count; base += BATCH) {
        for (uint b = 0u; b < BATCH; b++) {
            if (base + b >= count) break;  // uniform across the workgroup
            uint j = last - 1u - (base + b);
            // One lane loads, the subgroup shares (per-lane loads are slow on lavapipe).
            uint g = 0u;
            vec4 head = vec4(0.0), conic = vec4(0.0), color = vec4(0.0);
            vec4 f0 = vec4(0.0), f1 = vec4(0.0), f2 = vec4(0.0);
            if (subgroupElect()) {
                g = order.v[j];
                head = splats.v[g].head;
                conic = splats.v[g].conic;
                if (GRAD_RGB || SURFACE_DEPTH) color = splats.v[g].color;
                if (GRAD_FEATURES) {
                    f0 = features.v[3u * g];
                    f1 = features.v[3u * g + 1u];
                    f2 = features.v[3u * g + 2u];
                }
            }
            g = subgroupBroadcastFirst(g);
            head = subgroupBroadcastFirst(head);
            conic = subgroupBroadcastFirst(conic);
            if (GRAD_RGB || SURFACE_DEPTH) color = subgroupBroadcastFirst(color);
            if (GRAD_FEATURES) {
                f0 = subgroupBroadcastFirst(f0);
                f1 = subgroupBroadcastFirst(f1);
                f2 = subgroupBroadcastFirst(f2);
            }
            float r[MAX_STRIDE];
            for (uint c = 0u; c < MAX_STRIDE; c++) r[c] = 0.0;
            float alpha, gauss;
            vec2 d;
            if (j < end && splat_alpha(head, conic, centre, alpha, gauss, d)) {
                T /= 1.0 - alpha;
                vec2 slope = stored_slope(conic, color);
                float z = depth_at(head.z, slope, d, ortho);
                float x[14] = float[14](color.r, color.g, color.b, z, f0.x, f0.y, f0.z, f0.w,
                                        f1.x, f1.y, f1.z, f1.w, f2.x, f2.y);
                float w = alpha * T;
                float d_alpha = bg_term * t_final / (1.0 - alpha);
                [[unroll]] for (uint k = 0u; k < 14u; k++) {
                    if (value_used(k)) {
                        d_alpha += dv[k] * (x[k] * T - behind[k] / (1.0 - alpha));
                        behind[k] += x[k] * w;
                    }
                }
                if (head.w * gauss <= 0.99) {
                    float d_power = alpha * d_alpha;
                    r[0] = -(conic.x * d.x + conic.y * d.y) * d_power;
                    r[1] = -(conic.y * d.x + conic.z * d.y) * d_power;
                    r[2] = -0.5 * d.x * d.x * d_power;
                    r[3] = -d.x * d.y * d_power;
                    r[4] = -0.5 * d.y * d.y * d_power;
                    r[5] = gauss * d_alpha;
                }
                float d_z = w * dv[3] + (j == median_j ? d_median : 0.0);
                if (SURFACE_DEPTH) {
                    // Δ = centre − mean = −d.
                    float inv = ortho ? 1.0 : 1.0 / (1.0 - dot(slope, d));
                    float dz_du = ortho ? 1.0 : -head.z * inv * inv;
                    r[6] = d_z * inv;
                    r[0] -= d_z * dz_du * slope.x;
                    r[1] -= d_z * dz_du * slope.y;
                    r[SLOPE_AT] = -d_z * dz_du * d.x;
                    r[SLOPE_AT + 1u] = -d_z * dz_du * d.y;
                } else {
                    r[6] = d_z;
                }
                if (GRAD_RGB) { r[8] = w * dv[0]; r[9] = w * dv[1]; r[10] = w * dv[2]; }
                if (GRAD_FEATURES) {
                    uint o = GRAD_RGB ? 12u : 8u;
                    for (uint k = 0u; k < 10u; k++) r[o + k] = w * dv[4u + k];
                }
            }
            for (uint c = 0u; c < STRIDE; c++) terms[(b * STRIDE + c) * TILE_PIXELS + local] = r[c];
        }
        barrier();
        // One invocation per (splat of the batch, component) sums the pixels in order.
        uint b = local / STRIDE, c = local % STRIDE;
        if (b < BATCH && base + b < count) {
            float s = 0.0;
            uint at = (b * STRIDE + c) * TILE_PIXELS;
            for (uint k = 0u; k < TILE_PIXELS; k++) s += terms[at + k];
            uint g = order.v[last - 1u - (base + b)];
            // The splat's pairs start at its offset, in increasing tile order: find this tile's.
            Uints pair_tiles = Uints(frame.pair_tiles);
            uint slot = Uints(frame.tile_counts).v[g], end = Uints(frame.tile_counts).v[g + 1u];
            while (slot < end) {
                uint mid = (slot + end) / 2u;
                if (pair_tiles.v[mid] < tile) slot = mid + 1u; else end = mid;
            }
            Floats(bwd.pairs).v[slot * STRIDE + c] = s;
        }
        barrier();
    }
}
