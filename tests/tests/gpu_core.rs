//! The Vulkan core on the test device: kernels, constants, large buffers,
//! timestamps, memory accounting, deferred destruction — all with validation on.

use srug::gpu::selftest::{self, AffineAddressedPush, AffinePush};
use srug::gpu::{self, kernels, BindingKind, Kernel, KernelDecl, MemoryKind, SpecValue};
use srug_tests::{assert_no_validation_messages, device};

#[test]
fn selftest_matches_cpu_twin() {
    let d = device();
    let report = selftest::run(&d, 10_000).unwrap();
    assert!(report.passed(), "max relative error {}", report.max_rel_error);
    assert_no_validation_messages(&d);
}
