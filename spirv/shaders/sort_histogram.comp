#version 460
// Radix sort pass, step 1: per-block histogram of one 4-bit digit.
// hist[digit * blocks + block] = count (digit-major, so one exclusive scan of
// hist gives every (digit, block) its output start). No subgroup operations
// and no cross-workgroup waiting: correct for any subgroup size and without
// forward-progress guarantees. Per-thread counts come from unrolled
// compare-and-add in registers (see sort_scatter.comp), then 16 threads sum
// the rows.
// CPU reference: std sort (tests), engine/src/splat/sort.rs.
#include "sort_histogram_body.glsl"
