#version 460
// unet_conv.comp reading its two inputs through texel-buffer views
// (textureBuffer, bindings 2 and 3) instead of device addresses: on lavapipe
// a texelFetch with per-lane indices is one vector gather, while a
// device-address load runs lane by lane. The views' format (R32F or R16F)
// decides the input precision; the output is fp32. The weights come through
// an RGBA32F view too (binding 0), all input channels in one pass. Used when
// both inputs and the weights fit maxTexelBufferElements. CPU twin: engine/src/indirect/cpu.rs `conv3x3_cpu`.
#define TEXEL_INPUT 1
#include "unet_conv_body.glsl"
