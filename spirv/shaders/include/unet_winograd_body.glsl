// The body of unet_winograd_texel.comp and unet_winograd_texel_half.comp (see there).
#extension GL_EXT_control_flow_attributes : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "unet_storage.glsl"

// 0: none, 1: ReLU, 2: leaky ReLU (slope 0.01).
layout(constant_id = 1) const uint ACT = 1;
// 2 × 2 output tiles per invocation along x, 1 to 8 (even with VEC4): every
// weight fetch serves TT tiles (engine/src/indirect/winograd.rs `WINOGRAD_TILES`).
layout(constant_id = 2) const uint TT = 8;
// Output channels per invocation: 4 or 8 (engine/src/indirect/mod.rs `channel_block`).
layout(constant_id = 3) const uint OCB = 8;
// Input channels fetched and transformed before their multiply-adds, 1 to 4
// (engine/src/indirect/winograd.rs `WINOGRAD_CHUNK`).
layout(constant_id = 4) const uint CH = 2;
// The input views hold four pixels per texel (RGBA32F/RGBA16F); needs the
// input width to be a multiple of 4, so every row segment starts one pixel
// before a texel boundary.
layout(constant_id = 5) const bool VEC4 = false;

// U = G·g·Gᵀ per (output block of 4, input channel, k = 4·row + column) as
// one RGBA32F texel (4 output channels), output blocks padded to a multiple
// of OCB: engine/src/indirect/winograd.rs `pack_winograd` (keep in sync).
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

// An invocation covers output rows oy0, oy0 + 1 and columns ox0 .. ox0 + 2·TT − 1;
// its input patch is rows oy0 − 1 .. oy0 + 2, columns ox0 − 1 .. ox0 + 2·TT
// (SPAN columns; NT texels per row with VEC4).
#define SPAN (2u * TT + 2u)
#define NT (TT / 2u + 2u)

// Fills rows[r][0 .. SPAN) from channel plane BASE of VIEW (zero outside
// the image and where OK is false).
#define FILL_ROWS(VIEW, BASE, OK)                                                  \
    [[unroll]] for (uint r = 0u; r < 4u; ++r) {                                    \
        if (VEC4) {                                                                \
            vec4 seg[6];                                                           \
            [[unroll]] for (uint t = 0u; t < NT; ++t) seg[t] = texelFetch(VIEW, int((BASE) / 4u) + tex_at[r][t]); \
            [[unroll]] for (uint k = 0u; k < SPAN; ++k) rows[r][k] = tap_in[r][k] && OK ? seg[(k + 3u) / 4u][(k + 3u) % 4u] : 0.0; \
        } else {                                                                   \
            [[unroll]] for (uint k = 0u; k < SPAN; ++k) {                          \
                rows[r][k] = tap_in[r][k] && OK ? texelFetch(VIEW, int(BASE) + tap_at[r][k]).r : 0.0; \
            }                                                                      \
        }                                                                          \
    }

// Adds input channels IC .. IC + CH − 1 of a view holding COUNT channels
// (OFFSET + its own index in the layer's input) to the accumulators: every
// fetch and transform first, then the multiply-adds. On lavapipe every fetch
// is a call that clobbers the vector registers; with none inside the
// multiply-add loop each (tile, k)'s accumulators stay in registers across
// the CH channels, and each weight fetch serves TT tiles.
#define ACCUMULATE_CHUNK(VIEW, IC, COUNT, OFFSET)                                  \
    {                                                                              \
        float v[4][8][16]; /* [c][t][k] */                                         \
        vec4 wt[4][32];    /* [c][k·Q + q] */                                      \
        [[unroll]] for (uint c = 0u; c < CH; ++c) {                                \
            uint ch = min((IC) + c, (COUNT) - 1u);                                 \
            bool ok = (IC) + c < (COUNT);                                          \
            float rows[4][18];                                                     \
            FILL_ROWS(VIEW, ch * plane, ok)                                        \
            [[unroll]] for (uint t = 0u; t < TT; ++t) {                            \
                float d[16];                                                       \
                [[unroll]] for (uint j = 0u; j < 16u; ++j) d[j] = rows[j / 4u][2u * t + j % 4u]; \
                float vt[16];                                                      \
                input_transform(d, vt);                                            \
                [[unroll]] for (uint k = 0u; k < 16u; ++k) v[c][t][k] = vt[k];     \
            }                                                                      \
            [[unroll]] for (uint q = 0u; q < Q; ++q) {                             \
                int wb = int(((ob * Q + q) * cin + (OFFSET) + ch) * 16u);          \
                [[unroll]] for (uint k = 0u; k < 16u; ++k) wt[c][k * Q + q] = texelFetch(weight_texels, wb + int(k)); \
            }                                                                      \
        }                                                                          \
        [[unroll]] for (uint t = 0u; t < TT; ++t) {                                \
            [[unroll]] for (uint k = 0u; k < 16u; ++k) {                           \
                [[unroll]] for (uint c = 0u; c < CH; ++c) {                        \
                    [[unroll]] for (uint q = 0u; q < Q; ++q) {                     \
                        m[(t * 16u + k) * Q + q] = fma(vec4(v[c][t][k]), wt[c][k * Q + q], m[(t * 16u + k) * Q + q]); \
                    }                                                              \
                }                                                                  \
            }                                                                      \
        }                                                                          \
    }

// V = Bᵀ·d·B of a 4 × 4 input patch d (row-major), Bᵀ = [1 0 −1 0; 0 1 1 0; 0 −1 1 0; 0 1 0 −1].
void input_transform(in float d[16], out float v[16]) {
    float t[16];
    [[unroll]] for (int j = 0; j < 4; ++j) {
        t[j] = d[j] - d[8 + j];
        t[4 + j] = d[4 + j] + d[8 + j];
        t[8 + j] = d[8 + j] - d[4 + j];
        t[12 + j] = d[4 + j] - d[12 + j];
    }
    [[unroll]] for (int i = 0; i < 4; ++i) {
        v[4 * i] = t[4 * i] - t[4 * i + 2];
        v[4 * i + 1] = t[4 * i + 1] + t[4 * i + 2];
        v[4 * i + 2] = t[4 * i + 2] - t[4 * i + 1];
        v[4 * i + 3] = t[4 * i + 1] - t[4 * i + 3];
    }
}

void main() {
    const uint Q = OCB / 4u;
    uint tiles_x = (pc.out_size.x + 1u) / 2u;
    uint blocks_x = (tiles_x + TT - 1u) / TT;
    uint blocks = blocks_x * ((pc.out_size.y + 1u) / 2u);
    uint p = (gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y) * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
    uint ob = gl_WorkGroupID.x;
    bool live = p < blocks;
    p = min(p, blocks - 1u);
    int ox0 = int((p % blocks_x) * TT * 2u), oy0 = int(p / blocks_x) * 2;
    int w = int(pc.in_size.x), h = int(pc.in_size.y);
    uint plane = pc.in_size.x * pc.in_size.y;
    uint cin = pc.ca + pc.cb;
    // The patch's element offsets within a channel plane (clamped into the
    // image, so every fetch is in range) and whether each lies inside (else
    // it reads the zero padding); with VEC4, each row's texels. The same for
    // every input channel.
    int tap_at[4][18];
    bool tap_in[4][18];
    int tex_at[4][6];
    int m4 = ox0 / 4;
    int plane_texels = int(plane / 4u);
    [[unroll]] for (int r = 0; r < 4; ++r) {
        int iy = oy0 - 1 + r;
        [[unroll]] for (uint k = 0u; k < SPAN; ++k) {
            int ix = ox0 - 1 + int(k);
            tap_at[r][k] = clamp(iy, 0, h - 1) * w + clamp(ix, 0, w - 1);
            tap_in[r][k] = iy >= 0 && iy < h && ix >= 0 && ix < w;
        }
        [[unroll]] for (uint t = 0u; t < NT; ++t) {
            tex_at[r][t] = clamp(clamp(iy, 0, h - 1) * (w / 4) + m4 - 1 + int(t), 0, max(plane_texels - 1, 0));
        }
    }
    // m[(t·16 + k)·Q + q]: M = Σ U ⊙ V of tile t, element k, channels (ob·Q + q)·4 .. + 3.
    // Every loop over it is unrolled (a dynamic index would put it in scratch memory).
    vec4 m[256];
    [[unroll]] for (uint i = 0u; i < TT * 16u * Q; ++i) m[i] = vec4(0.0);
    // A's channels, then B's: each loop reads one view.
    for (uint ic = 0u; ic < pc.ca; ic += CH) ACCUMULATE_CHUNK(input_a, ic, pc.ca, 0u)
    for (uint ic = 0u; ic < pc.cb; ic += CH) ACCUMULATE_CHUNK(input_b, ic, pc.cb, pc.ca)
    if (!live) return;
    int ow = int(pc.out_size.x), oh = int(pc.out_size.y);
    uint out_plane = pc.out_size.x * pc.out_size.y;
    // ys[t·Q + q][i]: tile t's output pixel i (row-major 2 × 2), channels (ob·Q + q)·4 .. + 3, activated.
    vec4 ys[16][4];
    [[unroll]] for (uint t = 0u; t < TT; ++t) {
        [[unroll]] for (uint q = 0u; q < Q; ++q) {
            // Y = Aᵀ·M·A, Aᵀ = [1 1 1 0; 0 1 −1 −1].
            vec4 tr[8];
            [[unroll]] for (uint j = 0u; j < 4u; ++j) {
                uint at = t * 16u + j;
                tr[j] = m[at * Q + q] + m[(at + 4u) * Q + q] + m[(at + 8u) * Q + q];
                tr[4u + j] = m[(at + 4u) * Q + q] - m[(at + 8u) * Q + q] - m[(at + 12u) * Q + q];
            }
            vec4 b = bias[ob * Q + q];
            [[unroll]] for (uint i = 0u; i < 2u; ++i) {
                ys[t * Q + q][2u * i] = tr[4u * i] + tr[4u * i + 1u] + tr[4u * i + 2u] + b;
                ys[t * Q + q][2u * i + 1u] = tr[4u * i + 1u] - tr[4u * i + 2u] - tr[4u * i + 3u] + b;
            }
            [[unroll]] for (uint i = 0u; i < 4u; ++i) {
                if (ACT == 1u) {
                    ys[t * Q + q][i] = max(ys[t * Q + q][i], 0.0);
                } else if (ACT == 2u) {
                    vec4 a = ys[t * Q + q][i];
                    ys[t * Q + q][i] = mix(a * 0.01, a, greaterThanEqual(a, vec4(0.0)));
                }
            }
        }
    }
    if (VEC4) {
        // Two tiles side by side are four pixels of a row starting at a multiple of 4 (the width is one):
        // one 16-byte store per channel and row instead of four lane-by-lane scalar stores.
        [[unroll]] for (uint tp = 0u; tp < TT / 2u; ++tp) {
            int tx = ox0 + 4 * int(tp);
            if (tx >= ow) break;
            [[unroll]] for (uint q = 0u; q < Q; ++q) {
                uint l = 2u * tp * Q + q, r = (2u * tp + 1u) * Q + q;
                [[unroll]] for (uint j = 0u; j < 4u; ++j) {
                    uint c = (ob * Q + q) * 4u + j;
                    if (c >= pc.oc) continue;
                    [[unroll]] for (uint row = 0u; row < 2u; ++row) {
                        int oy = oy0 + int(row);
                        if (oy >= oh) continue;
                        vec4 px = vec4(ys[l][2u * row][j], ys[l][2u * row + 1u][j], ys[r][2u * row][j], ys[r][2u * row + 1u][j]);
                        store_output4(pc.o, c * out_plane + uint(oy * ow + tx), px);
                    }
                }
            }
        }
    } else {
        [[unroll]] for (uint t = 0u; t < TT; ++t) {
            int tx = ox0 + 2 * int(t);
            if (tx >= ow) break;
            [[unroll]] for (uint q = 0u; q < Q; ++q) {
                [[unroll]] for (uint i = 0u; i < 4u; ++i) {
                    int ox = tx + int(i & 1u), oy = oy0 + int(i >> 1u);
                    if (ox >= ow || oy >= oh) continue;
                    [[unroll]] for (uint j = 0u; j < 4u; ++j) {
                        uint c = (ob * Q + q) * 4u + j;
                        if (c < pc.oc) store_output(pc.o, c * out_plane + uint(oy * ow + ox), ys[t * Q + q][i][j]);
                    }
                }
            }
        }
    }
}
