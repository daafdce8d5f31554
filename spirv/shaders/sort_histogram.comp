#version 460
// Radix sort pass, step 1: per-invocation histogram of one 4-bit digit over
// the invocation's ITEMS consecutive keys, digit-major (see sort_common.glsl),
// so one exclusive scan of hist gives every (digit, invocation) its output
// start. No subgroup operations, no shared memory and no cross-workgroup
// waiting: correct for any subgroup size and without forward-progress
// guarantees.
// CPU reference: std sort (tests), engine/src/splat/sort.rs.
#include "sort_histogram_body.glsl"
