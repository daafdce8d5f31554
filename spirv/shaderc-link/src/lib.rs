//! Carries the link directives for Debian's static shaderc dependencies.
//!
//! Depend on this crate (as a build-dependency of a crate whose build script
//! calls shaderc) and call [`linked`] once so the crate is not dropped as
//! unused; its build script then adds glslang and SPIRV-Tools to the link.

/// Returns true; calling it keeps this crate, and its link directives, in the link.
pub fn linked() -> bool {
    true
}
