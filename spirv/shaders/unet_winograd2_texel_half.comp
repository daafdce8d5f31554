#version 460
// unet_winograd2_texel.comp writing fp16 activations (16-bit storage; OUT_HALF
// per layer). Inputs come through the texel-buffer views, whose format (R16F
// or R32F) widens them to fp32; accumulation stays fp32.
// CPU twin: engine/src/indirect/cpu.rs `conv3x3_cpu` on fp16-rounded activations.
#define WT 2
#define HALF_STORAGE 1
#include "unet_winograd_body.glsl"
