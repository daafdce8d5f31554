#version 460
// sort_scatter.comp reading keys and values through texel-buffer views
// (bindings 0 and 1: RG32UI, R32UI) instead of device addresses; outputs
// are still written by address. Used when the keys fit
// maxTexelBufferElements. CPU reference: std sort (tests).
#define TEXEL_INPUT 1
#include "sort_scatter_body.glsl"
