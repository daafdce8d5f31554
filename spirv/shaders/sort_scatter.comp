#version 460
// Radix sort pass, step 3 (after the histogram scan): stable scatter. Each
// invocation walks its ITEMS consecutive keys in order and sends each to its
// digit's next slot; the slots live in registers (fully unrolled selects,
// since dynamically indexed private arrays are loops over the lanes on CPU
// implementations such as lavapipe). Scanned digit-major, invocations in
// order, so equal digits keep their order.
#include "sort_scatter_body.glsl"
