#version 460
// unet_upsample.comp on fp16 activations (widened to fp32 for the arithmetic).
// CPU twin: engine/src/indirect/cpu.rs `upsample_cpu` on fp16-rounded values.
#define HALF_STORAGE 1
#include "unet_upsample_body.glsl"
