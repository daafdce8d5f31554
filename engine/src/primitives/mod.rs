//! GPU primitives shared by the stages and the benchmarks: the exclusive
//! prefix sum ([`scan`]) and the stable radix sort ([`sort`]), each with its
//! CPU twin. They know the Vulkan core and nothing of Gaussians.

pub mod scan;
pub mod sort;
