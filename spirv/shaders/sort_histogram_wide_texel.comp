#version 460
// sort_histogram_texel.comp with wide digits (WIDE_DIGITS: up to 11 bits a
// pass, counted in an array indexed by the digit) and the keys spread evenly
// over the dispatched invocations: fewer passes where invocations are CPU
// lanes and such an array is cheap (engine/src/primitives/sort.rs
// `wide_digits`). CPU reference: std sort (tests).
#define TEXEL_INPUT 1
#define WIDE_DIGITS 1
#include "sort_histogram_body.glsl"
