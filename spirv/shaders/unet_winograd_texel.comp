#version 460
// A stride-1 3×3 conv (padding 1, fused bias and activation) by Winograd
// F(4×4, 3×3): per 4 × 4 output tile and 4 output channels, each input
// channel's 6 × 6 patch d becomes V = Bᵀ·d·B, M accumulates U ⊙ V with the
// transformed weights U = G·g·Gᵀ (36 multiplies instead of 144), and the tile
// is Y = Aᵀ·M·A. Inputs, weights through texel-buffer views like
// unet_conv_texel.comp; fp32 output. Accumulation in fp32.
// CPU twin: engine/src/indirect/cpu.rs `winograd_conv3x3_cpu` (the same
// transforms in f64) and `conv3x3_cpu`.
#include "unet_winograd_body.glsl"
