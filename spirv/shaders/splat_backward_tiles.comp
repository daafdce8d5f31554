#version 460
// Splat backward, step 1: one workgroup per tile, one invocation per pixel.
// Each pixel replays its forward blend (the same splat_alpha, so the same
// contributors, final transmittance and median splat), then walks its splats
// back to front (NOTES.md §4): T ← T / (1 − α); dL/dx = α·T·dL/dC;
// dL/dα = Σ dL/dC·(x·T − S/(1 − α)) + (dL/dA − bg·dL/dC_rgb)·T_final/(1 − α);
// S ← S + x·α·T; α clamped at 0.99 passes no geometric gradient. The tile's
// pixels are summed per splat (subgroupAdd, then the subgroups in a fixed
// order: deterministic) into that (tile, splat) pair's record, at
// pair_offsets[g] + its tile's place in the splat's rectangle, so step 2 can
// sum each Gaussian's records in order without atomics.
// CPU twin: engine/src/splat/cpu_backward.rs `blend_backward_cpu`.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define WORKGROUP_SIZE_X 256
#include "common.glsl"
#include "splat.glsl"
#include "splat_backward.glsl"

// Partial sums of each subgroup, double-buffered so one barrier per splat
// suffices. At most 64 subgroups (the host requires a subgroup size ≥ 4).
shared float partial[2][64][MAX_STRIDE];
shared uint tile_end;

float grad_in(uvec2 addr, uint i) { return FloatsIn(addr).v[i]; }

void main() {
    uint tile = block_index();
    uint tiles_x = frame.size.z;
    uint local = gl_LocalInvocationID.x;
    uvec2 tile_xy = uvec2(tile % tiles_x, tile / tiles_x);
    uvec2 pix = tile_xy * TILE + uvec2(local % TILE, local / TILE);
    bool inside = pix.x < frame.size.x && pix.y < frame.size.y;
    uint p = pix.y * frame.size.x + pix.x;
    vec2 centre = vec2(pix) + 0.5;
    uvec2 range = Uvec2s(frame.work2.xy).v[tile];
    Uints order = Uints(frame.work1.zw);
    Splats splats = Splats(frame.scene5.zw);
    Features features = Features(frame.work0.xy);

    // This pixel's loss gradients: values (rgb, depth, ten features), alpha, median.
    float dv[14];
    for (uint k = 0u; k < 14u; k++) dv[k] = 0.0;
    float d_alpha_out = 0.0, d_median = 0.0;
    if (inside) {
        if (GRAD_RGB) for (uint c = 0u; c < 3u; c++) dv[c] = grad_in(bwd.in0.xy, 3u * p + c);
        if ((GRADS & 512u) != 0u) d_alpha_out = grad_in(bwd.in0.zw, p);
        if ((GRADS & 1u) != 0u) dv[3] = grad_in(bwd.in1.xy, p);
        if ((GRADS & 2u) != 0u) d_median = grad_in(bwd.in1.zw, p);
        if ((GRADS & 4u) != 0u) for (uint c = 0u; c < 3u; c++) dv[4u + c] = grad_in(bwd.in2.xy, 3u * p + c);
        if ((GRADS & 16u) != 0u) dv[7] = grad_in(bwd.in3.xy, p);
        if ((GRADS & 8u) != 0u) for (uint c = 0u; c < 3u; c++) dv[8u + c] = grad_in(bwd.in2.zw, 3u * p + c);
        if ((GRADS & 32u) != 0u) dv[11] = grad_in(bwd.in3.zw, p);
        if ((GRADS & 64u) != 0u) dv[12] = grad_in(bwd.in4.xy, p);
        if ((GRADS & 128u) != 0u) dv[13] = grad_in(bwd.in4.zw, p);
    }

    // Replay the forward blend: where it stopped, the final T and the median splat.
    float T = 1.0;
    uint end = range.x, median_j = 0xffffffffu;
    if (inside) {
        for (uint j = range.x; j < range.y; j++) {
            uint g = order.v[j];
            float alpha, gauss;
            vec2 d;
            if (!splat_alpha(splats.v[g].head, splats.v[g].conic, centre, alpha, gauss, d)) continue;
            float next_T = T * (1.0 - alpha);
            if (next_T < 1e-4) break;
            if (T > 0.5 && next_T <= 0.5) median_j = j;
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
    uint subgroup = gl_SubgroupID;

    for (uint j = last; j > range.x; ) {
        j--;
        uint g = order.v[j];
        vec4 head = splats.v[g].head;
        vec4 conic = splats.v[g].conic;
        float r[MAX_STRIDE];
        for (uint c = 0u; c < MAX_STRIDE; c++) r[c] = 0.0;
        float alpha, gauss;
        vec2 d;
        if (j < end && splat_alpha(head, conic, centre, alpha, gauss, d)) {
            T /= 1.0 - alpha;
            float x[14];
            vec3 color = splats.v[g].color.rgb;
            x[0] = color.r; x[1] = color.g; x[2] = color.b; x[3] = head.z;
            if (GRAD_FEATURES) {
                vec4 f0 = features.v[3u * g], f1 = features.v[3u * g + 1u], f2 = features.v[3u * g + 2u];
                x[4] = f0.x; x[5] = f0.y; x[6] = f0.z; x[7] = f0.w;
                x[8] = f1.x; x[9] = f1.y; x[10] = f1.z; x[11] = f1.w;
                x[12] = f2.x; x[13] = f2.y;
            } else {
                for (uint k = 4u; k < 14u; k++) x[k] = 0.0;
            }
            float w = alpha * T;
            float d_alpha = bg_term * t_final / (1.0 - alpha);
            for (uint k = 0u; k < 14u; k++) {
                d_alpha += dv[k] * (x[k] * T - behind[k] / (1.0 - alpha));
                behind[k] += x[k] * w;
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
            r[6] = w * dv[3];
            if (GRAD_RGB) { r[8] = w * dv[0]; r[9] = w * dv[1]; r[10] = w * dv[2]; }
            if (GRAD_FEATURES) {
                uint o = GRAD_RGB ? 12u : 8u;
                for (uint k = 0u; k < 10u; k++) r[o + k] = w * dv[4u + k];
            }
        }
        if (j == median_j) r[6] += d_median;

        // Sum over the tile: within subgroups, then subgroups in order.
        uint buf = j & 1u;
        for (uint c = 0u; c < STRIDE; c++) {
            float s = subgroupAdd(r[c]);
            if (subgroupElect()) partial[buf][subgroup][c] = s;
        }
        barrier();
        if (local < STRIDE) {
            float s = 0.0;
            for (uint k = 0u; k < gl_NumSubgroups; k++) s += partial[buf][k][local];
            uvec4 rect = splats.v[g].rect;
            uint slot = Uints(frame.work0.zw).v[g] + (tile_xy.y - rect.y) * (rect.z - rect.x) + (tile_xy.x - rect.x);
            Floats(bwd.pairs.xy).v[slot * STRIDE + local] = s;
        }
    }
}
