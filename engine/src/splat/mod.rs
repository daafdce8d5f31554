//! Tile-sorted splatting: the forward renderer and its G-buffers.
//!
//! Being built bottom-up: the prefix sum ([`scan`]) and the radix sort
//! ([`sort`]) the tile binning needs are here; preprocessing, key emission,
//! tile ranges and blending follow.

pub mod scan;
pub mod sort;
