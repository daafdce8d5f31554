//! Emits the static link directives that shaderc needs on Debian 12.
//!
//! Debian's `libshaderc_combined.a` holds shaderc alone; glslang and
//! SPIRV-Tools come as separate static archives. A build script that calls
//! shaderc links through this crate, so the directives reach its own link.

fn main() {
    let dir = std::env::var("SHADERC_LIB_DIR").unwrap_or_else(|_| "/usr/lib/x86_64-linux-gnu".to_string());
    println!("cargo:rerun-if-env-changed=SHADERC_LIB_DIR");
    println!("cargo:rustc-link-search=native={dir}");
    // Order matters for static archives: users before what they use.
    for lib in [
        "glslang",
        "MachineIndependent",
        "OSDependent",
        "GenericCodeGen",
        "OGLCompiler",
        "SPIRV",
        "glslang-default-resource-limits",
        "SPIRV-Tools-opt",
        "SPIRV-Tools",
    ] {
        println!("cargo:rustc-link-lib=static={lib}");
    }
    println!("cargo:rustc-link-lib=dylib=stdc++");
}
