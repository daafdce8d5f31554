//! GPU primitives shared by the stages and the benchmarks: the exclusive
//! prefix sum ([`scan`]) and the stable radix sort ([`sort`]), each with its
//! CPU twin. They know the Vulkan core and nothing of Gaussians.

pub mod scan;
pub mod sort;

#[cfg(test)]
mod layout_tests {
    use super::scan::ScanPush;
    use super::sort::SortPush;
    use crate::gpu::{check_layout, kernels};

    /// The push-constant structs match the GLSL blocks of every kernel that declares them.
    #[test]
    fn push_layouts_match_glsl() {
        // Reduce and apply, in runs and in tiles.
        assert_eq!(check_layout::<ScanPush>(kernels::ALL), Ok(4));
        // Histogram and scatter: by address, through texel views, with wide and with block digits.
        let sort = check_layout::<SortPush>(kernels::ALL);
        assert!(sort.as_ref().is_ok_and(|n| *n == 8), "{sort:?}");
    }
}
