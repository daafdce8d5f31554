// The body of unet_winograd_texel.comp, unet_winograd2_texel.comp and their
// _half variants (see there). WT × WT output tiles from E × E input patches:
// F(4×4, 3×3), or F(2×2, 3×3) where the including file defines WT 2 (keep in
// sync with engine/src/indirect/winograd.rs `WinogradTile::edge`, `patch`).
#ifndef WT
#define WT 4
#endif
#define E (WT + 2)
#define EE (E * E)
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "unet_storage.glsl"

// 0: none, 1: ReLU, 2: leaky ReLU (slope 0.01).
layout(constant_id = 1) const uint ACT = 1;
// WT × WT output tiles per invocation along x, 1 to 8: every
// weight fetch serves TT tiles; WT·TT a multiple of 4 with VEC4
// (engine/src/indirect/winograd.rs `WinogradTile::tiles_per_invocation`).
layout(constant_id = 2) const uint TT = 8;
// Output channels per invocation: 4 or 8 (engine/src/indirect/mod.rs `channel_block`).
layout(constant_id = 3) const uint OCB = 8;
// Input channels fetched and transformed before their multiply-adds, 1 or 2
// (engine/src/indirect/winograd.rs `WinogradTile::channels_per_step`).
layout(constant_id = 4) const uint CH = 2;
// The input views hold four pixels per texel (RGBA32F/RGBA16F); needs the
// input width to be a multiple of 4, so every row segment starts one pixel
// before a texel boundary.
layout(constant_id = 5) const bool VEC4 = false;
// The subgroup's size where its lanes fetch a weight block's texels side by
// side and broadcast them (0: every lane fetches every texel). The weights
// are the same in every lane (the workgroup's output block); where a texel
// fetch is a call (lavapipe from Mesa 25) this is 1/WEIGHT_LANES of the
// calls (engine/src/indirect/mod.rs `weight_lanes`).
layout(constant_id = 6) const uint WEIGHT_LANES = 0u;
#define WEIGHT_STEP max(WEIGHT_LANES, 1u)
#define WEIGHT_ROUNDS ((EE + WEIGHT_STEP - 1u) / WEIGHT_STEP)

// U = G·g·Gᵀ per (output block of 4, input channel, k = E·row + column) as
// one RGBA32F texel (4 output channels), output blocks padded to a multiple
// of OCB: engine/src/indirect/winograd.rs `pack_winograd` (keep in sync).
layout(set = 0, binding = 0) uniform textureBuffer weight_texels;
layout(std430, set = 0, binding = 1) readonly buffer Bias { vec4 bias[]; };
layout(set = 0, binding = 2) uniform textureBuffer input_a;
layout(set = 0, binding = 3) uniform textureBuffer input_b;

// Keep in sync with engine/src/indirect/mod.rs `ConvPush` (the fields this
// kernel reads: o, ca, cb, oc, in_size, out_size).
layout(push_constant) uniform ConvPush {
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

// An invocation covers output rows oy0 .. oy0 + WT − 1 and columns ox0 .. ox0 + WT·TT − 1;
// its input patch is rows oy0 − 1 .. oy0 + WT, columns ox0 − 1 .. ox0 + WT·TT
// (SPAN columns; NT texels per row with VEC4).
#define SPAN (WT * TT + 2u)
#define NT (WT * TT / 4u + 2u)
// Array bounds for the largest TT, CH and OCB.
#define MAX_SPAN (WT * 8 + 2)
#define MAX_NT (WT * 2 + 2)
#define MAX_CH 2

// Fills rows[r][0 .. SPAN) from channel plane BASE of VIEW (zero outside
// the image and where OK is false).
#define FILL_ROWS(VIEW, BASE, OK)                                                  \
    [[unroll]] for (uint r = 0u; r < E; ++r) {                                     \
        if (VEC4) {                                                                \
            vec4 seg[MAX_NT];                                                      \
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
        float v[MAX_CH][8][EE]; /* [c][t][k] */                                    \
        vec4 wt[MAX_CH][EE * 2]; /* [c][k·Q + q] */                                \
        [[unroll]] for (uint c = 0u; c < CH; ++c) {                                \
            uint ch = min((IC) + c, (COUNT) - 1u);                                 \
            bool ok = (IC) + c < (COUNT);                                          \
            float rows[E][MAX_SPAN];                                               \
            FILL_ROWS(VIEW, ch * plane, ok)                                        \
            [[unroll]] for (uint t = 0u; t < TT; ++t) {                            \
                float d[EE];                                                       \
                [[unroll]] for (uint j = 0u; j < EE; ++j) d[j] = rows[j / E][WT * t + j % E]; \
                float vt[EE];                                                      \
                input_transform(d, vt);                                            \
                [[unroll]] for (uint k = 0u; k < EE; ++k) v[c][t][k] = vt[k];      \
            }                                                                      \
            [[unroll]] for (uint q = 0u; q < Q; ++q) {                             \
                int wb = int(((ob * Q + q) * cin + (OFFSET) + ch) * EE);           \
                if (WEIGHT_LANES > 0u) {                                                   \
                    vec4 lane_wt[EE];                                                      \
                    [[unroll]] for (uint r = 0u; r < WEIGHT_ROUNDS; ++r) {                 \
                        uint at = min(r * WEIGHT_LANES + gl_SubgroupInvocationID, EE - 1u); \
                        lane_wt[r] = texelFetch(weight_texels, wb + int(at));              \
                    }                                                                      \
                    [[unroll]] for (uint k = 0u; k < EE; ++k) {                            \
                        wt[c][k * Q + q] = subgroupBroadcast(lane_wt[k / WEIGHT_STEP], k % WEIGHT_STEP); \
                    }                                                                      \
                } else {                                                                   \
                    [[unroll]] for (uint k = 0u; k < EE; ++k) wt[c][k * Q + q] = texelFetch(weight_texels, wb + int(k)); \
                }                                                                          \
            }                                                                      \
        }                                                                          \
        [[unroll]] for (uint t = 0u; t < TT; ++t) {                                \
            [[unroll]] for (uint k = 0u; k < EE; ++k) {                            \
                [[unroll]] for (uint c = 0u; c < CH; ++c) {                        \
                    [[unroll]] for (uint q = 0u; q < Q; ++q) {                     \
                        m[(t * EE + k) * Q + q] = fma(vec4(v[c][t][k]), wt[c][k * Q + q], m[(t * EE + k) * Q + q]); \
                    }                                                              \
                }                                                                  \
            }                                                                      \
        }                                                                          \
    }

#if WT == 2
// Bᵀ·x of one column or row, Bᵀ = [1 0 −1 0; 0 1 1 0; 0 −1 1 0; 0 1 0 −1].
void bt(in float x[E], out float y[E]) {
    y[0] = x[0] - x[2];
    y[1] = x[1] + x[2];
    y[2] = x[2] - x[1];
    y[3] = x[1] - x[3];
}

// Aᵀ·x, Aᵀ = [1 1 1 0; 0 1 −1 −1].
void at(in vec4 x[E], out vec4 y[WT]) {
    y[0] = x[0] + x[1] + x[2];
    y[1] = x[1] - x[2] - x[3];
}
#else
// Bᵀ·x of one column or row, Bᵀ = [4 0 −5 0 1 0; 0 −4 −4 1 1 0; 0 4 −4 −1 1 0;
// 0 −2 −1 2 1 0; 0 2 −1 −2 1 0; 0 4 0 −5 0 1].
void bt(in float x[E], out float y[E]) {
    float a = x[4] - 4.0 * x[2], b = x[3] - 4.0 * x[1];
    float c = x[4] - x[2], d = 2.0 * (x[3] - x[1]);
    y[0] = 4.0 * x[0] - 5.0 * x[2] + x[4];
    y[1] = a + b;
    y[2] = a - b;
    y[3] = c + d;
    y[4] = c - d;
    y[5] = 4.0 * x[1] - 5.0 * x[3] + x[5];
}

// Aᵀ·x, Aᵀ = [1 1 1 1 1 0; 0 1 −1 2 −2 0; 0 1 1 4 4 0; 0 1 −1 8 −8 1].
void at(in vec4 x[E], out vec4 y[WT]) {
    vec4 s12 = x[1] + x[2], d12 = x[1] - x[2], s34 = x[3] + x[4], d34 = x[3] - x[4];
    y[0] = x[0] + s12 + s34;
    y[1] = d12 + 2.0 * d34;
    y[2] = s12 + 4.0 * s34;
    y[3] = d12 + 8.0 * d34 + x[5];
}
#endif

// V = Bᵀ·d·B of an E × E input patch d (row-major).
void input_transform(in float d[EE], out float v[EE]) {
    float t[EE];
    [[unroll]] for (int j = 0; j < E; ++j) {
        float x[E], y[E];
        [[unroll]] for (int i = 0; i < E; ++i) x[i] = d[E * i + j];
        bt(x, y);
        [[unroll]] for (int i = 0; i < E; ++i) t[E * i + j] = y[i];
    }
    [[unroll]] for (int i = 0; i < E; ++i) {
        float x[E], y[E];
        [[unroll]] for (int j = 0; j < E; ++j) x[j] = t[E * i + j];
        bt(x, y);
        [[unroll]] for (int j = 0; j < E; ++j) v[E * i + j] = y[j];
    }
}

void main() {
    const uint Q = OCB / 4u;
    uint tiles_x = (pc.out_size.x + WT - 1u) / WT;
    uint blocks_x = (tiles_x + TT - 1u) / TT;
    uint blocks = blocks_x * ((pc.out_size.y + WT - 1u) / WT);
    uint p = (gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y) * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
    uint ob = gl_WorkGroupID.x;
    bool live = p < blocks;
    p = min(p, blocks - 1u);
    int ox0 = int((p % blocks_x) * TT * WT), oy0 = int(p / blocks_x) * WT;
    int w = int(pc.in_size.x), h = int(pc.in_size.y);
    uint plane = pc.in_size.x * pc.in_size.y;
    uint cin = pc.ca + pc.cb;
    // The patch's element offsets within a channel plane (clamped into the
    // image, so every fetch is in range) and whether each lies inside (else
    // it reads the zero padding); with VEC4, each row's texels. The same for
    // every input channel.
    int tap_at[E][MAX_SPAN];
    bool tap_in[E][MAX_SPAN];
    int tex_at[E][MAX_NT];
    int m4 = ox0 / 4;
    int plane_texels = int(plane / 4u);
    [[unroll]] for (int r = 0; r < E; ++r) {
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
    // m[(t·EE + k)·Q + q]: M = Σ U ⊙ V of tile t, element k, channels (ob·Q + q)·4 .. + 3.
    // Every loop over it is unrolled (a dynamic index would put it in scratch memory).
    vec4 m[8 * EE * 2];
    [[unroll]] for (uint i = 0u; i < TT * EE * Q; ++i) m[i] = vec4(0.0);
    // A's channels, then B's: each loop reads one view.
    for (uint ic = 0u; ic < pc.ca; ic += CH) ACCUMULATE_CHUNK(input_a, ic, pc.ca, 0u)
    for (uint ic = 0u; ic < pc.cb; ic += CH) ACCUMULATE_CHUNK(input_b, ic, pc.cb, pc.ca)
    if (!live) return;
    int ow = int(pc.out_size.x), oh = int(pc.out_size.y);
    uint out_plane = pc.out_size.x * pc.out_size.y;
    // ys[t·Q + q][i]: tile t's output pixel i (row-major WT × WT), channels (ob·Q + q)·4 .. + 3, activated.
    vec4 ys[16][WT * WT];
    [[unroll]] for (uint t = 0u; t < TT; ++t) {
        [[unroll]] for (uint q = 0u; q < Q; ++q) {
            // Y = Aᵀ·M·A: Aᵀ down each column, then along each row.
            vec4 tr[WT][E];
            [[unroll]] for (uint j = 0u; j < E; ++j) {
                vec4 x[E], y[WT];
                [[unroll]] for (uint i = 0u; i < E; ++i) x[i] = m[(t * EE + E * i + j) * Q + q];
                at(x, y);
                [[unroll]] for (uint i = 0u; i < WT; ++i) tr[i][j] = y[i];
            }
            vec4 b = bias[ob * Q + q];
            [[unroll]] for (uint i = 0u; i < WT; ++i) {
                vec4 y[WT];
                at(tr[i], y);
                [[unroll]] for (uint j = 0u; j < WT; ++j) {
                    vec4 a = y[j] + b;
                    if (ACT == 1u) {
                        a = max(a, 0.0);
                    } else if (ACT == 2u) {
                        a = mix(a * 0.01, a, greaterThanEqual(a, vec4(0.0)));
                    }
                    ys[t * Q + q][WT * i + j] = a;
                }
            }
        }
    }
    if (VEC4) {
        // Four pixels of a row start at a multiple of 4 (so does the row of tiles, and the width is one):
        // one 16-byte store per channel and row instead of four lane-by-lane scalar ones; with WT 2 they
        // come from two tiles.
        [[unroll]] for (uint g = 0u; g < TT * WT / 4u; ++g) {
            int gx = ox0 + 4 * int(g);
            [[unroll]] for (uint q = 0u; q < Q; ++q) {
                [[unroll]] for (uint j = 0u; j < 4u; ++j) {
                    uint c = (ob * Q + q) * 4u + j;
                    [[unroll]] for (uint row = 0u; row < WT; ++row) {
                        int oy = oy0 + int(row);
                        if (all(bvec3(gx < ow, c < pc.oc, oy < oh))) {
                            vec4 px;
                            [[unroll]] for (uint x = 0u; x < 4u; ++x) {
                                uint t = (4u * g + x) / WT;
                                px[x] = ys[t * Q + q][WT * row + (4u * g + x) % WT][j];
                            }
                            store_output4(pc.o, c * out_plane + uint(oy * ow + gx), px);
                        }
                    }
                }
            }
        }
    } else {
        [[unroll]] for (uint t = 0u; t < TT; ++t) {
            int tx = ox0 + WT * int(t);
            [[unroll]] for (uint q = 0u; q < Q; ++q) {
                [[unroll]] for (uint i = 0u; i < WT * WT; ++i) {
                    int ox = tx + int(i % WT), oy = oy0 + int(i / WT);
                    [[unroll]] for (uint j = 0u; j < 4u; ++j) {
                        uint c = (ob * Q + q) * 4u + j;
                        if (all(bvec3(ox < ow, oy < oh, c < pc.oc))) {
                            store_output(pc.o, c * out_plane + uint(oy * ow + ox), ys[t * Q + q][i][j]);
                        }
                    }
                }
            }
        }
    }
}
