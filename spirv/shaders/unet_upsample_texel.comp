#version 460
// unet_upsample.comp reading its source through a texel-buffer view (binding
// 0; R32F or R16F) instead of a device address, writing fp32.
// CPU twin: engine/src/indirect/cpu.rs `upsample_cpu`.
#define TEXEL_INPUT 1
#include "unet_upsample_body.glsl"
