#version 460
// Shadow backward, gather: one invocation per shadow-map texel sums
// the dL/dz it gets from each receiver pixel whose bilinear footprint holds it
// (w_k·dL/dz_s for the depth test, k·dL/dx_k for PCF; the backward kernel
// records them) —
// those binned at this texel and at its left, upper and upper-left
// neighbours — in a fixed order (deterministic, no atomics). Then the texel's
// depth z_s goes back to the map's channels: median depth directly,
// z_s = Σwz / alpha (empty texels, at the empty depth, pass nothing), or
// z_s = Σwz + (1 − alpha)·(empty depth).
// CPU twin: engine/src/shadow/cpu.rs `sigmoid_backward_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shadow.glsl"
#include "shadow_backward.glsl"

void main() {
    uint texel = linear_index();
    if (texel >= sbw.counts.y) return;
    uint mw = shadow.size.z;
    ivec2 tt = ivec2(int(texel % mw), int(texel / mw));
    Uvec2sIn ranges = Uvec2sIn(sbw.bin_ranges);
    UintsIn order = UintsIn(sbw.bin_pixels);
    Vec4s records = Vec4s(sbw.records);
    float sum = 0.0;
    for (int dy = 0; dy < 2; dy++) {
        for (int dx = 0; dx < 2; dx++) {
            ivec2 b = tt - ivec2(dx, dy);
            if (b.x < 0 || b.y < 0) continue;
            uvec2 range = ranges.v[uint(b.y) * mw + uint(b.x)];
            for (uint j = range.x; j < range.y; j++) {
                uint q = order.v[j];
                ivec2 t[4];
                vec4 w;
                bilinear(records.v[2u * q].xy, t, w);
                vec4 grads = records.v[2u * q + 1u];
                for (int i = 0; i < 4; i++) {
                    if (t[i] == tt) sum += grads[i];
                }
            }
        }
    }
    FloatsOut(sbw.texel_depth).v[texel] = sum;
    float g_depth = 0.0, g_alpha = 0.0;
    float z;
    if (sum != 0.0 && shadow.modes.x == 2u) {
        // z_s = Σwz + (1 − alpha)·empty depth.
        g_depth = sum;
        g_alpha = -sum * shadow.params.w;
    } else if (sum != 0.0 && resolve_depth(shadow.modes.x, shadow.map_depth, shadow.map_alpha, texel, z)) {
        if (shadow.modes.x == 1u) {
            g_depth = sum;
        } else {
            float a = FloatsIn(shadow.map_alpha).v[texel];
            g_depth = sum / a;
            g_alpha = -sum * FloatsIn(shadow.map_depth).v[texel] / (a * a);
        }
    }
    FloatsOut(sbw.d_map_depth).v[texel] = g_depth;
    if (shadow.modes.x != 1u) FloatsOut(sbw.d_map_alpha).v[texel] = g_alpha;
}
