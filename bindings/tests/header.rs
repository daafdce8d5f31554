//! The committed C header must match what cbindgen generates from the source.
//! `SRUG_BLESS=1 cargo test -p srug-bindings --test header` rewrites it.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "test code: a failure should stop the test")]

use std::path::PathBuf;

#[test]
fn committed_header_is_current() {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_crate(&crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen could not generate the header");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    let path = crate_dir.join("include").join("srug.h");
    if std::env::var_os("SRUG_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    if committed != generated {
        let first = committed.lines().zip(generated.lines()).position(|(a, b)| a != b);
        panic!(
            "{} is stale (first difference at line {}); regenerate it with \
             `SRUG_BLESS=1 cargo test -p srug-bindings --test header` and commit it",
            path.display(),
            first.map_or_else(|| committed.lines().count().min(generated.lines().count()) + 1, |i| i + 1)
        );
    }
}
