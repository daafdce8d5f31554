// The body of unet_winograd_texel.comp and unet_winograd_texel_half.comp (see there).
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "unet_storage.glsl"

// 0: none, 1: ReLU, 2: leaky ReLU (slope 0.01).
layout(constant_id = 1) const uint ACT = 1;

// U = G·g·Gᵀ per (output block of 4, input channel, k = 4·row + column) as
// one RGBA32F texel (4 output channels): engine/src/indirect/winograd.rs
// `pack_winograd` (keep in sync).
layout(set = 0, binding = 0) uniform samplerBuffer weight_texels;
layout(std430, set = 0, binding = 1) readonly buffer Bias { vec4 bias[]; };
layout(set = 0, binding = 2) uniform samplerBuffer input_a;
layout(set = 0, binding = 3) uniform samplerBuffer input_b;

// Keep in sync with engine/src/indirect/mod.rs `ConvPush` (the fields this
// kernel reads: o, ca, cb, oc, in_size, out_size).
layout(push_constant) uniform Push {
    uvec2 a;
    uvec2 b;
    uvec2 o;        // output, oc channels
    uvec2 partial;
    uint ca;        // channels of input A
    uint cb;        // channels of input B (skip)
    uint oc;
    uint ic0;
    uint ic1;
    uint flags;
    uvec2 in_size;  // width, height (equal to out_size: stride 1)
    uvec2 out_size;
} pc;

// V = Bᵀ·d·B of a 4 × 4 input patch d (row-major), Bᵀ = [1 0 −1 0; 0 1 1 0; 0 −1 1 0; 0 1 0 −1].
void input_transform(in float d[16], out float v[16]) {
    float t[16];
    for (int j = 0; j < 4; ++j) {
        t[j] = d[j] - d[8 + j];
        t[4 + j] = d[4 + j] + d[8 + j];
        t[8 + j] = d[8 + j] - d[4 + j];
        t[12 + j] = d[4 + j] - d[12 + j];
    }
    for (int i = 0; i < 4; ++i) {
        v[4 * i] = t[4 * i] - t[4 * i + 2];
        v[4 * i + 1] = t[4 * i + 1] + t[4 * i + 2];
        v[4 * i + 2] = t[4 * i + 2] - t[4 * i + 1];
        v[4 * i + 3] = t[4 * i + 1] - t[4 * i + 3];
    }
}

// Every input channel's patch transformed and multiplied by its U, summed.
#define ACCUMULATE_CHANNEL(VIEW, CHANNEL)                                   \
    {                                                                       \
        int base = int(CHANNEL * plane);                                    \
        float d[16];                                                        \
        for (int j = 0; j < 16; ++j) {                                      \
            d[j] = tap_in[j] ? texelFetch(VIEW, base + tap_at[j]).r : 0.0;  \
        }                                                                   \
        float v[16];                                                        \
        input_transform(d, v);                                              \
        int wbase = int((ob * cin + ic) * 16u);                             \
        for (int k = 0; k < 16; ++k) {                                      \
            m[k] += v[k] * texelFetch(weight_texels, wbase + k);            \
        }                                                                   \
    }

void main() {
    uint tiles_x = (pc.out_size.x + 1u) / 2u;
    uint tiles = tiles_x * ((pc.out_size.y + 1u) / 2u);
    uint p = (gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y) * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
    uint ob = gl_WorkGroupID.x;
    bool live = p < tiles;
    p = min(p, tiles - 1u);
    int ox0 = int(p % tiles_x) * 2, oy0 = int(p / tiles_x) * 2;
    int w = int(pc.in_size.x), h = int(pc.in_size.y);
    uint plane = pc.in_size.x * pc.in_size.y;
    uint cin = pc.ca + pc.cb;
    // The patch's element offsets within a channel plane (clamped into the
    // image) and whether each lies inside (else it reads the zero padding).
    int tap_at[16];
    bool tap_in[16];
    for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) {
            int iy = oy0 - 1 + r, ix = ox0 - 1 + c;
            tap_at[4 * r + c] = clamp(iy, 0, h - 1) * w + clamp(ix, 0, w - 1);
            tap_in[4 * r + c] = iy >= 0 && iy < h && ix >= 0 && ix < w;
        }
    }
    // M = Σ U ⊙ V for 4 output channels.
    vec4 m[16];
    for (int k = 0; k < 16; ++k) m[k] = vec4(0.0);
    // A's channels, then B's: each loop reads one view.
    for (uint ic = 0u; ic < pc.ca; ++ic) ACCUMULATE_CHANNEL(input_a, ic)
    for (uint ic = pc.ca; ic < cin; ++ic) ACCUMULATE_CHANNEL(input_b, (ic - pc.ca))
    if (!live) return;
    // Y = Aᵀ·M·A, Aᵀ = [1 1 1 0; 0 1 −1 −1].
    vec4 t[8];
    for (int j = 0; j < 4; ++j) {
        t[j] = m[j] + m[4 + j] + m[8 + j];
        t[4 + j] = m[4 + j] - m[8 + j] - m[12 + j];
    }
    vec4 b = bias[ob];
    vec4 y[4];
    for (int i = 0; i < 2; ++i) {
        y[2 * i] = t[4 * i] + t[4 * i + 1] + t[4 * i + 2] + b;
        y[2 * i + 1] = t[4 * i + 1] - t[4 * i + 2] - t[4 * i + 3] + b;
    }
    int ow = int(pc.out_size.x), oh = int(pc.out_size.y);
    uint out_plane = pc.out_size.x * pc.out_size.y;
    for (int i = 0; i < 4; ++i) {
        int ox = ox0 + (i & 1), oy = oy0 + (i >> 1);
        if (ox >= ow || oy >= oh) continue;
        vec4 a = y[i];
        if (ACT == 1u) {
            a = max(a, 0.0);
        } else if (ACT == 2u) {
            a = mix(a * 0.01, a, greaterThanEqual(a, vec4(0.0)));
        }
        for (uint j = 0u; j < 4u; ++j) {
            uint c = ob * 4u + j;
            if (c < pc.oc) store_output(pc.o, c * out_plane + uint(oy * ow + ox), a[j]);
        }
    }
}
