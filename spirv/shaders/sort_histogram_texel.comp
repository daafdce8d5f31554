#version 460
// sort_histogram.comp reading the keys through a texel-buffer view (binding
// 0, RG32UI) instead of a device address: on lavapipe a texelFetch is one
// vector gather, a device-address load a loop over the lanes. Used when the
// keys fit maxTexelBufferElements. CPU reference: std sort (tests).
#define TEXEL_INPUT 1
#include "sort_histogram_body.glsl"
