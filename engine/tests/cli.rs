//! The `srug` binary: the main job, `info`, and clear errors with a non-zero exit.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use std::path::PathBuf;
use std::process::{Command, Output};

fn srug(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_srug")).args(args).env("RUST_LOG", "srug=info").output().expect("srug runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

#[test]
fn demo_generates_writes_and_checks_the_gpu() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = srug(&["demo", "--gaussians", "20000", "--out", out, "--validation"]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in [
        "Gaussians: 20000",
        "GPU self-test: passed",
        "scene activation on the GPU: matches",
        "validation messages: 0",
        "srug device #",
    ] {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
    let ply = dir.path().join("demo_city.ply");
    assert!(ply.is_file() && dir.path().join("cameras.json").is_file());

    // `info` on what the demo wrote.
    let o = srug(&["info", ply.to_str().unwrap()]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in [
        "Gaussians: 20000",
        "SH degree: 1",
        "attributes: normals, albedo, roughness, metallic, ao, visibility",
        "bounds:",
        "GPU memory:",
    ] {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
}

#[test]
fn info_reports_the_trained_scene() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/scenes/trained_iter7000.ply");
    if !path.is_file() {
        eprintln!("skipped: {} is absent", path.display());
        return;
    }
    let o = srug(&["info", path.to_str().unwrap()]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("Gaussians: 9080") && t.contains("SH degree: 3") && t.contains("attributes: normals\n"), "{t}");
}

#[test]
fn bad_input_fails_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let not_ply = dir.path().join("notes.ply");
    std::fs::write(&not_ply, "hello").unwrap();
    let o = srug(&["info", not_ply.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let t = text(&o);
    assert!(t.contains("error:") && t.contains("notes.ply") && t.contains("not a PLY file"), "{t}");
    assert!(!t.contains("panicked"), "{t}");

    let o = srug(&["info", dir.path().join("absent.ply").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("absent.ply"));

    let o = srug(&["demo", "--gaussians", "5", "--out", dir.path().to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("at least 1000"), "{}", text(&o));
    assert!(!dir.path().join("demo_city.ply").exists(), "nothing written on failure");
}
