#version 460
// Radix sort pass, step 3 (after the histogram scan): stable scatter.
// Each thread owns ITEMS consecutive keys. Per-digit counts and each item's
// rank among earlier equal digits come from fully unrolled compare-and-add
// over the thread's own items (registers only: dynamically indexed private
// arrays are slow on CPU implementations such as lavapipe); per-digit counts
// are scanned across the workgroup's threads in shared memory, so equal
// digits keep their order.
#include "sort_scatter_body.glsl"
