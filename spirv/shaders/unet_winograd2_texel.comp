#version 460
// unet_winograd_texel.comp by Winograd F(2×2, 3×3): per 2 × 2 output tile,
// each input channel's 4 × 4 patch d becomes V = Bᵀ·d·B and M accumulates
// U ⊙ V (16 multiplies instead of 36); fp32 output, fp32 accumulation. Its
// transforms' entries are 0, ±½, ±1: less fp32 rounding than F(4×4, 3×3).
// CPU twin: engine/src/indirect/cpu.rs `winograd_conv3x3_cpu` (the same
// transforms in f64) and `conv3x3_cpu`.
#define WT 2
#include "unet_winograd_body.glsl"
