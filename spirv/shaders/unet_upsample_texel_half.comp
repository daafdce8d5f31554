#version 460
// unet_upsample_texel.comp writing fp16 activations (16-bit storage).
// CPU twin: engine/src/indirect/cpu.rs `upsample_cpu` on fp16-rounded values.
#define TEXEL_INPUT 1
#define HALF_STORAGE 1
#include "unet_upsample_body.glsl"
