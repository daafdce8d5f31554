#version 460
// sort_scatter_texel.comp with wide digits (see sort_histogram_wide_texel.comp):
// the next output slot of each digit lives in an array indexed by the digit.
// CPU reference: std sort (tests).
#define TEXEL_INPUT 1
#define WIDE_DIGITS 1
#include "sort_scatter_body.glsl"
