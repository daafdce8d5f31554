//! The `srug` binary: the main job, `info`, and clear errors with a non-zero exit.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn srug(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_srug")).args(args).env("RUST_LOG", "srug=info").output().expect("srug runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// `srug demo` of `gaussians` into `dir`/demo: its scene and cameras files.
fn demo_files(dir: &Path, gaussians: &str) -> (PathBuf, PathBuf) {
    let demo = dir.join("demo");
    let o = srug(&["demo", "--gaussians", gaussians, "--out", demo.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    (demo.join("demo_city.ply"), demo.join("cameras.json"))
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
        "relit street",
    ] {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
    let ply = dir.path().join("demo_city.ply");
    assert!(ply.is_file() && dir.path().join("cameras.json").is_file());
    let png = image::open(dir.path().join("demo_city.png")).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (704, 192));
    let distinct: std::collections::HashSet<[u8; 3]> = png.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 100, "the render is nearly flat: {} colours", distinct.len());
    let relit = image::open(dir.path().join("demo_relit.png")).unwrap().to_rgb8();
    assert_eq!(relit.dimensions(), (704, 192));
    let distinct: std::collections::HashSet<[u8; 3]> = relit.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 100, "the relit street is nearly flat: {} colours", distinct.len());

    // Render every default camera as EXR with G-buffer channels, and one as PNG at another size.
    let cams = dir.path().join("cameras.json");
    let exr_out = dir.path().join("frame.exr");
    let o = srug(&[
        "render",
        ply.to_str().unwrap(),
        "--cameras",
        cams.to_str().unwrap(),
        "--out",
        exr_out.to_str().unwrap(),
        "--channels",
        "rgb,depth,normal,materials",
        "--size",
        "176x48",
        "--validation",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    // Without a terminal every written file is still logged on stdout.
    let log = String::from_utf8_lossy(&o.stdout);
    assert!((0..4).all(|i| log.contains(&format!("frame_{i:03}.exr"))), "{log}");
    for i in 0..4 {
        let path = dir.path().join(format!("frame_{i:03}.exr"));
        let image = exr::prelude::read_all_flat_layers_from_file(&path).unwrap();
        let names: Vec<String> = image.layer_data[0].channel_data.list.iter().map(|c| c.name.to_string()).collect();
        for want in ["R", "G", "B", "A", "Z", "normal.X", "albedo.R", "roughness.Y", "visibility.Y"] {
            assert!(names.iter().any(|n| n == want), "{path:?} lacks {want}: {names:?}");
        }
        assert_eq!(image.layer_data[0].size.0, 176);
    }
    // Without rgb in the list the EXR holds alpha and the channels named, no colour.
    let depth_out = dir.path().join("depth.exr");
    let o = srug(&[
        "render",
        ply.to_str().unwrap(),
        "--cameras",
        cams.to_str().unwrap(),
        "--index",
        "1",
        "--out",
        depth_out.to_str().unwrap(),
        "--channels",
        "depth",
        "--size",
        "176x48",
    ]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("depth.exr"), "{}", text(&o));
    let image = exr::prelude::read_all_flat_layers_from_file(&depth_out).unwrap();
    let mut names: Vec<String> = image.layer_data[0].channel_data.list.iter().map(|c| c.name.to_string()).collect();
    names.sort();
    assert_eq!(names, ["A", "Z"], "{depth_out:?}");
    let png_out = dir.path().join("one.png");
    let o = srug(&[
        "render",
        ply.to_str().unwrap(),
        "--cameras",
        cams.to_str().unwrap(),
        "--index",
        "2",
        "--out",
        png_out.to_str().unwrap(),
    ]);
    assert!(o.status.success() && png_out.is_file(), "{}", text(&o));
    // A size of another aspect ratio stretches the camera, and says so.
    let (p, c, out) = (ply.to_str().unwrap(), cams.to_str().unwrap(), png_out.to_str().unwrap());
    let o = srug(&["render", p, "--cameras", c, "--index", "0", "--size", "64x64", "--out", out]);
    assert!(
        o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--size 64x64 stretches camera"),
        "{}",
        text(&o)
    );
    // A run that fails part-way removes what it had written: no partial result.
    let batch = dir.path().join("batch.png");
    std::fs::create_dir(dir.path().join("batch_001.png")).unwrap();
    let o = srug(&["render", p, "--cameras", c, "--size", "88x24", "--out", batch.to_str().unwrap()]);
    assert!(!o.status.success() && text(&o).contains("batch_001.png"), "{}", text(&o));
    assert!(!dir.path().join("batch_000.png").exists(), "the first frame of a failed run is removed");
    let o = srug(&[
        "render",
        ply.to_str().unwrap(),
        "--eye",
        "-40,-2,1.6",
        "--target",
        "0,0,1",
        "--size",
        "64x32",
        "--out",
        png_out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(image::open(&png_out).unwrap().width(), 64);
    // The median depth read at another coverage; out of (0, 1) refused, nothing written.
    let exr_out = dir.path().join("median.exr");
    let median_at = |coverage: &str| {
        let e = exr_out.to_str().unwrap();
        let args = ["render", p, "--eye", "-40,-2,1.6", "--target", "0,0,1", "--size", "64x32", "--out", e];
        srug(&[&args[..], &["--channels", "median_depth", "--median-coverage", coverage]].concat())
    };
    let o = median_at("1");
    assert!(!o.status.success() && text(&o).contains("median coverage 1: must lie strictly"), "{}", text(&o));
    assert!(!exr_out.exists(), "nothing written");
    let o = median_at("0.7");
    assert!(o.status.success() && exr_out.is_file(), "{}", text(&o));

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
    assert!(t.contains("error:") && t.contains("notes.ply") && t.contains("not a scene file"), "{t}");
    assert!(!t.contains("panicked"), "{t}");

    let o = srug(&["info", dir.path().join("absent.ply").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("absent.ply"));

    let o = srug(&["demo", "--gaussians", "5", "--out", dir.path().to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("at least 1000"), "{}", text(&o));
    // A device choice that matches nothing is named in the option's words, not as a Rust value.
    let o = srug(&["demo", "--device", "no-such-gpu", "--gaussians", "1000", "--out", dir.path().to_str().unwrap()]);
    let t = text(&o);
    assert!(t.contains("device name \"no-such-gpu\" matches none of") && !t.contains("Name("), "{t}");
    assert!(!dir.path().join("demo_city.ply").exists(), "nothing written on failure");

    let png = dir.path().join("depth.png");
    let (p, n) = (png.to_str().unwrap(), not_ply.to_str().unwrap());
    let o = srug(&["render", n, "--eye", "1,2,3", "--size", "8x8", "--channels", "depth", "--out", p]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("--channels depth: needs an .exr output"), "{}", text(&o));
    assert!(!png.exists(), "nothing written");
    let o = srug(&["render", not_ply.to_str().unwrap(), "--eye", "1,2,3", "--size", "8x8", "--out", "x.jpg"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains(".png or .exr"), "{}", text(&o));
    let o = srug(&["render", not_ply.to_str().unwrap(), "--eye", "1,2", "--size", "8x8", "--out", "x.png"]);
    assert!(text(&o).contains("three"), "{}", text(&o));
    let o = srug(&[
        "render",
        not_ply.to_str().unwrap(),
        "--eye",
        "1,2,3",
        "--size",
        "8x8",
        "--channels",
        "rgb,shiny",
        "--out",
        "x.png",
    ]);
    assert!(text(&o).contains("channel \"shiny\": is unknown"), "{}", text(&o));
}

#[test]
fn bench_splat_prints_its_tables() {
    let bench = |sizes: &str, floor_pairs: &str, sh_degree: &str, row_floors: &str| {
        let args = ["--gaussians", "2000", "--sizes", sizes, "--repeats", "1", "--sort-keys", "5000"];
        let floors = ["--floor-pairs", floor_pairs, "--row-floors", row_floors];
        srug(&[&["bench", "splat"][..], &args, &floors, &["--sh-degree", sh_degree]].concat())
    };
    // A column of the first row.
    let first_row = |t: &str, name: &str| -> f64 {
        let cells = |l: &str| l.split('|').map(|c| c.trim().to_string()).collect::<Vec<_>>();
        let header = t.lines().find(|l| l.starts_with("| Gaussians |")).map(cells).unwrap_or_default();
        let row = t.lines().find(|l| l.starts_with("| 2000 | 64x32 |")).map(cells).unwrap_or_default();
        let column = header.iter().position(|c| c == name).unwrap_or_else(|| panic!("no {name}:\n{t}"));
        row.get(column).and_then(|c| c.parse().ok()).unwrap_or_else(|| panic!("no 64x32 row:\n{t}"))
    };
    let scene_mib = |t: &str| first_row(t, "scene MiB");
    let o = bench("64x32,48x16", "6000", "1", "true");
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let sh1_mib = scene_mib(&t);
    assert!(t.contains("measured FMA peak"), "{t}");
    // The peak measured again after the rows; the columns take the better.
    assert!(t.contains("after them; the columns take the better, "), "{t}");
    // The host CPU that ran it (on lavapipe, the device): model, CPUs and vector ISA.
    let host = t.lines().find(|l| l.starts_with("host: ")).unwrap_or_else(|| panic!("no host line:\n{t}"));
    // x86 names its vector ISA; other hosts name their architecture.
    let isa = host.contains("AVX") || host.contains("SSE") || host.ends_with(std::env::consts::ARCH);
    assert!(host.contains(" CPUs, ") && isa, "{host}");
    assert!(t.contains("the demo city (seed 7) at SH degree 1"), "{t}");
    for want in [
        "| 2000 | 64x32 |",
        "| 2000 | 48x16 |",
        "preprocess ms",
        "sort ms",
        "blend ms",
        "GPU",
        "sort_unstable",
        "ceiling % |",
        "| longest walk | split chunks |",
        "blend ceiling",
        "pair-move floor, 6000 pairs",
        "memory bandwidth (",
        "MiB read once, and copied once; the fastest of reading through an RGBA32F texel view or as uvec4s by device address",
        "preprocess % of floor | sort floor ms | sort % of floor | blend % of ceiling |",
        "at a pair-move floor measured at the row's own pairs right after its frames",
    ] {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
    // Each row's own floor, in its column and its line: the same bound, and a time.
    let own_floor = first_row(&t, "sort floor ms");
    let line = t.lines().find(|l| l.starts_with("- floor of 2000 Gaussians at 64x32 (")).unwrap_or_default();
    assert!(own_floor > 0.0 && line.contains(&format!("LSD bound {own_floor:.1} ms")), "{own_floor} ms:\n{t}");
    // And its own memory bandwidth, which its "preprocess % of floor" takes.
    assert!(line.contains("memory read ") && line.contains(" GB/s moved; LSD bound"), "{line}");
    // The blend ceiling is the better of a probe before the rows and one after them.
    assert!(
        t.contains("; the better of a probe before the rows, ") && t.contains(" GFLOP/s, and one after them, "),
        "{t}"
    );
    // The bandwidth line names the read that won.
    assert!(t.contains("here texel fetches ") || t.contains("here device-address loads "), "{t}");
    // The split blend's setting: the default splits no list on CPU devices, lists over 2048 entries on GPUs.
    assert!(t.contains("and no list was split (--chunk-length 0)") || t.contains("in chunks of 1024"), "{t}");
    // A floor measured on one pair (all launch, scaled to thousands) is far above the sort:
    // the column passes 100 and the bench says what that means.
    let o = bench("64x32", "1", "3", "false");
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("note: sort % of floor above 100 in some rows"), "{t}");
    assert!(t.contains("scaled from the one pair-move floor below"), "{t}");
    // SH degree 3: 48 coefficients a Gaussian where degree 1 holds 12, 144 bytes more each.
    assert!(t.contains("the demo city (seed 7) at SH degree 3"), "{t}");
    let grown = scene_mib(&t) - sh1_mib;
    assert!((grown - 2000.0 * 144.0 / 1048576.0).abs() < 0.11, "{sh1_mib} -> {} MiB", scene_mib(&t));
    let o = bench("64x32", "6000", "4", "true");
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("--sh-degree 4: is not 0 to 3"), "{}", text(&o));
    // The A/B switches: the blend's per-window fetch and the texel reads off.
    let args = ["--gaussians", "2000", "--sizes", "64x32", "--repeats", "1", "--sort-keys", "5000"];
    let off =
        ["--floor-pairs", "6000", "--window-fetch", "false", "--texel-preprocess", "false", "--scan-tiles", "true"];
    let o = srug(&[&["bench", "splat"][..], &args, &off].concat());
    assert!(o.status.success() && text(&o).contains("| 2000 | 64x32 |"), "{}", text(&o));
    // Each sort kernel timed on its own: every pass of the frame's sort and of the comparison's.
    let o = srug(&[&["bench", "splat"][..], &args, &["--floor-pairs", "6000", "--sort-kernels"]].concat());
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in
        ["- 2000 Gaussians at 64x32 (", "- 5000 random keys on 43 bits: pass 1 (bits 0-", "scatter", "histogram"]
    {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
    let frame = t.lines().find(|l| l.starts_with("- 2000 Gaussians at 64x32 (")).unwrap_or_default();
    assert!(frame.contains("pass 1 (bits 0-") && frame.contains("scatter") && frame.ends_with('%'), "{frame}");
    // The sort's digits, named in the sort's line.
    for digits in ["4", "block"] {
        let o = srug(&[&["bench", "splat"][..], &args, &["--floor-pairs", "6000", "--sort-digits", digits]].concat());
        let t = text(&o);
        assert!(o.status.success() && t.contains(&format!("on 43 bits ({digits} digits)")), "{t}");
    }
    // `srug bench splat --alternate SPEC` on a small city, two rounds.
    let alternated = |spec: &str| {
        srug(&["bench", "splat", "--gaussians", "2000", "--sizes", "64x32", "--repeats", "2", "--alternate", spec])
    };
    // One choice's values alternated frame by frame: a row per value and the ratios to the first,
    // every cell a median with its range; the other tables are not printed.
    let o = alternated("scan-tiles=false,true");
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in ["| 2000 | 64x32 | scan-tiles=false |", "| 2000 | 64x32 | scan-tiles=true |", "2 rounds (A B, then B A"]
    {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
    let ratios = t.lines().find(|l| l.starts_with("| 2000 | 64x32 | scan-tiles=true / scan-tiles=false |"));
    let cells: Vec<&str> =
        ratios.unwrap_or_else(|| panic!("no ratio row in:\n{t}")).split('|').map(str::trim).collect();
    // Gaussians, size, choice, six stages and the total.
    assert_eq!(cells.len(), 1 + 3 + 7 + 1, "{cells:?}");
    for cell in &cells[4..11] {
        let (median, range) = cell.split_once(' ').unwrap_or_else(|| panic!("{cell:?}"));
        let (lo, hi) =
            range.trim_matches(|c| c == '(' || c == ')').split_once('-').unwrap_or_else(|| panic!("{cell:?}"));
        let [m, lo, hi]: [f64; 3] = [median, lo, hi].map(|v| v.parse().unwrap_or_else(|_| panic!("{cell:?}")));
        assert!(lo > 0.0 && lo <= m && m <= hi && hi.is_finite(), "{cell:?}");
    }
    assert!(!t.contains("sort_unstable") && !t.contains("pair-move floor"), "{t}");
    // Compacted records against a record per Gaussian: the cull stage gets a column, timed only
    // where it runs, and its ratio is left blank.
    let o = alternated("compact-splats=false,true");
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let cells = |prefix: &str| -> Vec<String> {
        let line = t.lines().find(|l| l.starts_with(prefix)).unwrap_or_else(|| panic!("no {prefix:?} in:\n{t}"));
        line.split('|').map(|c| c.trim().to_string()).collect()
    };
    let header = cells("| Gaussians | size | choice |");
    assert_eq!(header[4..6], ["cull ms", "preprocess ms"], "{header:?}");
    assert_eq!(cells("| 2000 | 64x32 | compact-splats=false |")[4], "-");
    let cull: f64 = cells("| 2000 | 64x32 | compact-splats=true |")[4].parse().unwrap_or_else(|_| panic!("{t}"));
    assert!(cull > 0.0, "{t}");
    let ratios = cells("| 2000 | 64x32 | compact-splats=true / compact-splats=false |");
    assert_eq!((ratios.len(), ratios[4].as_str()), (1 + 3 + 8 + 1, "-"), "{ratios:?}");
    // The demo city shuffled, as a trained scene's file holds its Gaussians: the same pairs.
    let quick = ["bench", "splat", "--gaussians", "2000", "--sizes", "64x32", "--repeats", "1", "--sort-keys", "5000"];
    let o = srug(&[&quick[..], &["--floor-pairs", "6000"]].concat());
    let s = srug(&[&quick[..], &["--floor-pairs", "6000", "--order", "shuffled", "--warm-up-ms", "50"]].concat());
    let (t, ts) = (text(&o), text(&s));
    assert!(o.status.success() && s.status.success() && ts.contains("its Gaussians shuffled"), "{ts}");
    // No warm-up on a CPU device unless asked for; asked for, the bench says so.
    assert!(!t.contains("warm-up") && ts.contains("warm-up: 50 ms of untimed frames"), "{t}\n{ts}");
    let pairs = |t: &str| -> String {
        let cells = |l: &str| l.split('|').map(|c| c.trim().to_string()).collect::<Vec<_>>();
        let header = t.lines().find(|l| l.starts_with("| Gaussians |")).map(cells).unwrap_or_default();
        let row = t.lines().find(|l| l.starts_with("| 2000 | 64x32 |")).map(cells).unwrap_or_default();
        header.iter().position(|c| c == "pairs").and_then(|c| row.get(c).cloned()).unwrap_or_else(|| panic!("{t}"))
    };
    assert_eq!(pairs(&t), pairs(&ts));
    // Refused: an unknown choice, a bad value, one value, no values.
    for spec in ["nonsense=1,2", "blend-pixels=3,8", "blend-pixels=8", "blend-pixels"] {
        let o = srug(&["bench", "splat", "--gaussians", "2000", "--sizes", "64x32", "--alternate", spec]);
        assert!(!o.status.success() && text(&o).contains("error:"), "--alternate {spec}: {}", text(&o));
    }
}

/// `srug bench batch` runs srug render and relight to PNG and EXR and the in-process
/// renders for each count, and prints a row of positive rates per count.
#[test]
fn bench_batch_prints_its_table() {
    let o = srug(&["bench", "batch", "--gaussians", "2000", "--sh-degree", "1", "--counts", "1,3", "--size", "88x24"]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("render PNG fps") && t.contains("relight to memory fps"), "{t}");
    for count in ["1", "3"] {
        let row = t
            .lines()
            .find(|l| l.starts_with(&format!("| {count} |")))
            .unwrap_or_else(|| panic!("no row {count}:\n{t}"));
        let values: Vec<f64> = row.split('|').filter_map(|c| c.trim().parse().ok()).collect();
        assert_eq!(values.len(), 9, "{row}");
        assert!(values[1..].iter().all(|v| *v > 0.0), "{row}");
    }
    let o = srug(&["bench", "batch", "--counts", "0"]);
    assert!(!o.status.success() && text(&o).contains("--counts"), "{}", text(&o));
}

/// `srug bench embed` renders into an image on srug's device and through the
/// host-copy path, and prints a row of positive times per size.
#[test]
fn bench_embed_prints_its_table() {
    let o =
        srug(&["bench", "embed", "--gaussians", "2000", "--sh-degree", "1", "--sizes", "88x24,64x32", "--frames", "1"]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("shared device ms/frame") && t.contains("host copy ms/frame"), "{t}");
    for size in ["88x24", "64x32"] {
        let row =
            t.lines().find(|l| l.starts_with(&format!("| {size} |"))).unwrap_or_else(|| panic!("no {size}:\n{t}"));
        let values: Vec<f64> = row.split('|').filter_map(|c| c.trim().parse().ok()).collect();
        assert_eq!(values.len(), 5, "{row}");
        assert!(values.iter().all(|v| *v > 0.0), "{row}");
    }
    let o = srug(&["bench", "embed", "--frames", "0"]);
    assert!(!o.status.success() && text(&o).contains("--frames"), "{}", text(&o));
}

/// Malformed values are refused by the argument parser before anything runs:
/// exit status 2, the flag and the reason named, no panic.
#[test]
fn malformed_values_are_usage_errors() {
    let cases: &[(&[&str], &[&str])] = &[
        (&["bench", "splat", "--sizes", "64by32"], &["--sizes", "size \"64by32\": is not WxH"]),
        (&["bench", "splat", "--gaussians", "10,x"], &["--gaussians", "x"]),
        (&["bench", "splat", "--sort-digits", "16"], &["--sort-digits", "sort digits \"16\": is not 4, block or wide"]),
        (&["bench", "shadow", "--ks", "5,fast"], &["--ks", "fast"]),
        (&["bench", "unet", "--inputs", "texels"], &["--inputs", "conv path \"texels\": is not winograd"]),
        (&["render", "a.ply", "--eye", "1,2", "--size", "8x8", "--out", "x.png"], &["--eye", "three"]),
        (&["render", "a.ply", "--eye", "1,2,3", "--size", "0x8", "--out", "x.png"], &["--size", "is not WxH"]),
        (
            &["render", "a.ply", "--channels", "rgb,shiny", "--eye", "1,2,3", "--size", "8x8", "--out", "x.png"],
            &["--channels", "channel \"shiny\": is unknown"],
        ),
        (
            &["relight", "a.ply", "--eye", "1,2,3", "--preset", "best", "--out", "x.png"],
            &["--preset", "preset \"best\""],
        ),
        (&["relight", "a.ply", "--eye", "1,2,3", "--tone-map", "filmic", "--out", "x.png"], &["--tone-map", "filmic"]),
        (
            &["relight", "a.ply", "--eye", "1,2,3", "--shadow-test", "exact", "--out", "x.png"],
            &["--shadow-test", "sigmoid or traced"],
        ),
        (
            &["relight", "a.ply", "--eye", "1,2,3", "--sun-path", "2026-06-21T06:00Z", "--out", "x.png"],
            &["--sun-path", "START..END"],
        ),
        (&["unet", "--weights", "w", "--input", "i", "--out", "o", "--precision", "fp8"], &["--precision", "fp8"]),
        (&["info", "a.ply", "--size", "704"], &["--size", "is not WxH"]),
        // Options that contradict each other are refused instead of one silently winning.
        (
            &["render", "a.ply", "--cameras", "c.json", "--eye", "1,2,3", "--out", "x.png"],
            &["--cameras", "--eye", "cannot be used with"],
        ),
        (
            &[
                "relight",
                "a.ply",
                "--eye",
                "1,2,3",
                "--sun-azimuth",
                "90",
                "--sun-time",
                "2026-06-21T12:00Z",
                "--out",
                "x.png",
            ],
            &["--sun-time", "--sun-azimuth", "cannot be used with"],
        ),
    ];
    for (args, wants) in cases {
        let o = srug(args);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}:\n{t}");
        for want in *wants {
            assert!(t.contains(want), "{args:?}: missing {want:?} in:\n{t}");
        }
        assert!(!t.contains("panicked"), "{args:?}:\n{t}");
    }
}

#[test]
fn shadow_fit_writes_its_images_scene_and_history() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let args = ["shadow-fit", "--gaussians", "8000", "--steps", "2", "--added", "300", "--size", "88x24"];
    let o = srug(&[&args[..], &["--resolution", "64", "--out", out, "--validation"]].concat());
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in ["step   0:", "step   2:", "shadow IoU:", "missing-shadow IoU", "validation messages: 0"] {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
    for name in ["target", "without", "before", "after"] {
        let png = image::open(dir.path().join(format!("visibility_{name}.png"))).unwrap();
        assert_eq!((png.width(), png.height()), (88, 24));
    }
    let scene = srug::io::read_ply(dir.path().join("completed.ply")).unwrap();
    assert!(scene.len() > 300);
    let history = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 4, "header and three steps:\n{history}");
    // The fixed visibility alone (L_Vf, nothing added): its images, no editable ones.
    let fixed = dir.path().join("fixed");
    let args = ["shadow-fit", "--gaussians", "8000", "--fixed-steps", "2", "--added", "0", "--size", "88x24"];
    let o = srug(&[&args[..], &["--out", fixed.to_str().unwrap()]].concat());
    let t = text(&o);
    assert!(o.status.success() && t.contains("fixed visibility IoU against the target"), "{t}");
    assert!(fixed.join("visibility_fixed_after.png").exists() && !fixed.join("visibility_after.png").exists());
    // A sun below the horizon casts no shadow: refused with a message.
    let o = srug(&["shadow-fit", "--sun-elevation", "-5", "--gaussians", "2000", "--out", out]);
    assert!(!o.status.success() && text(&o).contains("above the horizon"), "{}", text(&o));
}

#[test]
fn bench_shadow_prints_its_tables() {
    let o = srug(&[
        "bench",
        "shadow",
        "--gaussians",
        "5000",
        "--accuracy-gaussians",
        "5000",
        "--resolutions",
        "64,128",
        "--ks",
        "5",
        "--size",
        "88x24",
        "--repeats",
        "1",
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in [
        "| Gaussians | map | map pairs",
        "| map | depth | k | IoU",
        "| 128 | Median | 5 |",
        "| 64 | Expected | 5 |",
        "| splats | preset | IoU | false shadow",
        "| Ideal | balanced |",
        "| Rough | fast |",
    ] {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
}

#[test]
fn relight_renders_stills_time_lapses_and_prefiltered_environments() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = srug(&["demo", "--gaussians", "10000", "--out", out]);
    assert!(o.status.success(), "{}", text(&o));
    let ply = dir.path().join("demo_city.ply");
    let cams = dir.path().join("cameras.json");
    let (ply, cams) = (ply.to_str().unwrap(), cams.to_str().unwrap());
    // A still as EXR: linear radiance plus L_sun and L_sky.
    let exr_out = dir.path().join("still.exr");
    let common = ["--cameras", cams, "--index", "1", "--size", "176x48", "--shadow-resolution", "512", "--validation"];
    // The map fitted to the view, and surface depths for the shadow test.
    let mut args = vec!["relight", ply, "--out", exr_out.to_str().unwrap(), "--sun-elevation", "35"];
    args.extend(["--shadow-fit", "view", "--shadow-surface-depth"]);
    args.extend(common);
    let o = srug(&args);
    assert!(o.status.success(), "{}", text(&o));
    let image = exr::prelude::read_all_flat_layers_from_file(&exr_out).unwrap();
    let names: Vec<String> = image.layer_data[0].channel_data.list.iter().map(|c| c.name.to_string()).collect();
    for want in ["R", "G", "B", "sun.R", "sky.B", "visibility.Y"] {
        assert!(names.iter().any(|n| n == want), "{names:?} lacks {want}");
    }
    // V is the shadow test's: in [0, 1], partly shadowed, and 0 where L_sun is 0 on a surface.
    let channel = |name: &str| -> Vec<f32> {
        let c = image.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
        c.sample_data.values_as_f32().collect()
    };
    let (v, sun_r) = (channel("visibility.Y"), channel("sun.R"));
    assert!(v.iter().all(|x| (0.0..=1.0).contains(x)), "V out of [0, 1]");
    let shadowed = v.iter().filter(|x| **x < 0.5).count();
    assert!(shadowed > 0 && shadowed < v.len(), "{shadowed} of {} pixels shadowed", v.len());
    assert!(v.iter().zip(&sun_r).all(|(v, s)| *v > 1e-4 || *s < 1e-3), "sun light where V = 0");
    assert!(!names.iter().any(|n| n.starts_with("indirect")), "no weights: no indirect light");
    // Surface depths are the presets' for the receivers: `=false` gives centre depths,
    // `--shadow-map-surface-depth` takes them for the map too; each changes V.
    let visibility_with = |flags: &[&str]| -> Vec<f32> {
        let out = dir.path().join("surface.exr");
        let mut args = vec!["relight", ply, "--out", out.to_str().unwrap(), "--sun-elevation", "35"];
        args.extend(flags);
        args.extend(common);
        let o = srug(&args);
        assert!(o.status.success(), "{flags:?}: {}", text(&o));
        let image = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
        let c = image.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == "visibility.Y").unwrap();
        c.sample_data.values_as_f32().collect()
    };
    let default_v = visibility_with(&[]);
    assert_eq!(default_v, visibility_with(&["--shadow-surface-depth"]), "surface depths are the default");
    assert_ne!(default_v, visibility_with(&["--shadow-surface-depth=false"]), "centre depths change V");
    assert_ne!(default_v, visibility_with(&["--shadow-map-surface-depth"]), "the map's surface depths change V");
    // The map read at one half's coverage casts from more of each splat's outline: more shadow.
    let half = visibility_with(&["--shadow-map-coverage", "0.5"]);
    let dark = |v: &[f32]| v.iter().filter(|x| **x < 0.5).count();
    assert!(half != default_v && dark(&half) >= dark(&default_v), "map coverage 0.5 keeps V or lightens it");
    let receivers = visibility_with(&["--shadow-receiver-coverage", "0.5"]);
    assert_ne!(default_v, receivers, "the receivers' coverage changes V");
    let mut args = vec!["relight", ply, "--out", exr_out.to_str().unwrap(), "--shadow-map-coverage", "1.5"];
    args.extend(common);
    let o = srug(&args);
    let message = text(&o);
    assert!(!o.status.success() && message.contains("shadow map coverage 1.5: must lie strictly"), "{message}");
    let mut args = vec!["relight", ply, "--out", exr_out.to_str().unwrap(), "--shadow-surface-depth=maybe"];
    args.extend(common);
    let o = srug(&args);
    assert!(!o.status.success() && text(&o).contains("shadow-surface-depth"), "{}", text(&o));
    // With network weights the indirect light is computed and written.
    let config = srug::indirect::UNetConfig { widths: [8, 8, 16, 16, 32], ..Default::default() };
    let wpath = dir.path().join("unet.safetensors");
    std::fs::write(&wpath, srug::indirect::UNetWeights::random(config, 2).to_bytes().unwrap()).unwrap();
    let mut args = vec!["relight", ply, "--out", exr_out.to_str().unwrap(), "--indirect", wpath.to_str().unwrap()];
    args.extend(common);
    let o = srug(&args);
    assert!(o.status.success(), "{}", text(&o));
    let image = exr::prelude::read_all_flat_layers_from_file(&exr_out).unwrap();
    let names: Vec<String> = image.layer_data[0].channel_data.list.iter().map(|c| c.name.to_string()).collect();
    assert!(names.iter().any(|n| n == "indirect.R"), "{names:?} lacks indirect.R");
    // A time-lapse along the sun's path: night frames run no shadow pass.
    let tl = dir.path().join("tl").join("day.png");
    let mut args = vec![
        "relight",
        ply,
        "--out",
        tl.to_str().unwrap(),
        "--sun-path",
        "2026-06-21T00:00:00+02:00..2026-06-21T14:00:00+02:00",
        "--frames",
        "3",
        "--latitude",
        "48.85",
        "--longitude",
        "2.35",
    ];
    args.extend(common);
    let o = srug(&args);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("(no shadow pass)"), "the midnight frame needs no shadow pass:\n{t}");
    for i in 0..3 {
        assert!(dir.path().join("tl").join(format!("day_{i:03}.png")).is_file());
    }
    assert!(!t.contains("shadow map reused"), "every time-lapse frame has its own sun:\n{t}");
    // Every camera under one sun: the first frame splats the shadow map, the others reuse it.
    let all = dir.path().join("all").join("cam.png");
    let args = [
        "relight",
        ply,
        "--out",
        all.to_str().unwrap(),
        "--cameras",
        cams,
        "--size",
        "176x48",
        "--shadow-resolution",
        "512",
        "--sun-elevation",
        "35",
        "--validation",
    ];
    let o = srug(&args);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let frames: Vec<&str> = t.lines().filter(|l| l.contains(" ms GPU")).collect();
    assert!(frames.len() >= 2, "one line per camera:\n{t}");
    assert!(!frames[0].contains("reused"), "the first frame splats its map:\n{t}");
    assert!(frames[1..].iter().all(|l| l.contains("(shadow map reused)")), "the same sun reuses it:\n{t}");
    // An environment file, prefiltered once into KTX2 and reused.
    if let Some(data) = shared_data() {
        let env = data.join("hdri").join("sunset.exr");
        let pre = dir.path().join("sunset");
        let o =
            srug(&["prefilter", env.to_str().unwrap(), "--out", pre.to_str().unwrap(), "--zstd", "--samples", "32"]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(pre.join("specular.ktx2").is_file() && pre.join("irradiance.ktx2").is_file());
        let png = dir.path().join("sunset.png");
        let mut args = vec!["relight", ply, "--out", png.to_str().unwrap(), "--env", pre.to_str().unwrap()];
        args.extend(["--env-rotation", "90", "--brdf", "height-correlated", "--tone-map", "reinhard"]);
        args.extend(common);
        let o = srug(&args);
        assert!(o.status.success() && png.is_file(), "{}", text(&o));
    } else {
        println!("skipped the environment-file part: ../shared/data is absent");
    }
    // An environment map with a sun (a hot texel north-east, 42° up) far from the analytic sun
    // is reported; the same sun as the map's is not.
    let (ew, eh) = (64usize, 32usize);
    let mut rgb = vec![0.2f32; 3 * ew * eh];
    let (hx, hy) = (ew / 2 + ew / 8, eh / 4); // texel centre: azimuth 47.8°, elevation 42.2°
    rgb[3 * (hy * ew + hx)..3 * (hy * ew + hx) + 3].copy_from_slice(&[5000.0; 3]);
    let sunny = dir.path().join("sunny.exr");
    srug::io::write_exr_channels(&sunny, ew as u32, eh as u32, &[("rgb", &rgb, 3)]).unwrap();
    let png = dir.path().join("sunny.png");
    let base = ["relight", ply, "--cameras", cams, "--index", "0", "--size", "88x24", "--env", sunny.to_str().unwrap()];
    let o =
        srug(&[&base[..], &["--sun-azimuth", "250", "--sun-elevation", "30", "--out", png.to_str().unwrap()]].concat());
    let t = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && t.contains("environment map's sun") && t.contains("azimuth 47.8°"), "{t}");
    let o = srug(
        &[&base[..], &["--sun-azimuth", "47.8", "--sun-elevation", "42.2", "--out", png.to_str().unwrap()]].concat(),
    );
    let t = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !t.contains("environment map's sun"), "{t}");
    // The map turned 90° toward east puts its sun at azimuth 137.8°; --sun-from-env takes it.
    let turned = [&base[..], &["--env-rotation", "90", "--out", png.to_str().unwrap()]].concat();
    let o = srug(&[&turned[..], &["--sun-azimuth", "137.8", "--sun-elevation", "42.2"]].concat());
    assert!(o.status.success() && !String::from_utf8_lossy(&o.stderr).contains("map's sun"), "{}", text(&o));
    let o = srug(&[&turned[..], &["--sun-from-env"]].concat());
    let t = text(&o);
    assert!(o.status.success() && t.contains("sun from the map 137.8°, 42.2°") && !t.contains("map's sun"), "{t}");
    let o = srug(&["info", ply, "--plan", "--sun-from-env"]);
    assert!(!o.status.success() && text(&o).contains("applies to `srug relight --env FILE` only"), "{}", text(&o));
    // Clear refusals.
    let bad = |args: &[&str], want: &str| {
        let o = srug(args);
        let t = text(&o);
        assert!(!o.status.success() && t.contains(want), "expected {want:?} in:\n{t}");
    };
    let png = dir.path().join("x.png");
    let png = png.to_str().unwrap();
    bad(&["relight", ply, "--cameras", cams, "--out", png, "--sun-time", "2026-06-21T12:00Z"], "--latitude");
    bad(&["relight", ply, "--cameras", cams, "--out", png, "--shadow-fit", "tight"], "is not scene, view or cascades");
    bad(&["relight", ply, "--cameras", cams, "--out", png, "--env", "/nonexistent/sky.exr"], "sky.exr");
    bad(&["relight", ply, "--cameras", cams, "--out", png, "--visibility", "sometimes"], "visibility");
    bad(&["relight", ply, "--cameras", cams, "--out", png, "--tone-map", "filmic"], "tone map");
    bad(&["relight", ply, "--cameras", cams, "--out", "x.jpg"], ".png or .exr");
    if let Some(data) = shared_data() {
        let trained = data.join("scenes").join("trained_iter7000.ply");
        bad(&["relight", trained.to_str().unwrap(), "--eye", "100,0,0", "--size", "8x8", "--out", png], "no albedo");
    }
}

fn shared_data() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("..").join("shared").join("data");
    root.is_dir().then_some(root)
}

#[test]
fn bench_shade_prints_its_tables() {
    let o = srug(&[
        "bench",
        "shade",
        "--gaussians",
        "5000",
        "--sizes",
        "64x32",
        "--env-sizes",
        "64x32",
        "--repeats",
        "1",
        "--validation",
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in ["| 64x32 |", "shade lights ms", "GGX prefilter ms", "BRDF table Karis", "BRDF table HeightCorrelated"]
    {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
}

#[test]
fn unet_runs_one_inference_between_safetensors_files() {
    use srug::indirect::cpu::{unet_cpu, Tensor};
    use srug::indirect::{read_tensor, tensor_bytes, UNetConfig, UNetWeights};
    let dir = tempfile::tempdir().unwrap();
    let config = UNetConfig { widths: [8, 8, 16, 16, 32], ..UNetConfig::default() };
    let weights = UNetWeights::random(config.clone(), 4);
    let wpath = dir.path().join("unet.safetensors");
    std::fs::write(&wpath, weights.to_bytes().unwrap()).unwrap();
    let (c, h, w) = (14, 23, 37);
    let input: Vec<f32> = (0..c * h * w).map(|i| ((i * 7919) % 1000) as f32 / 500.0 - 1.0).collect();
    let ipath = dir.path().join("in.safetensors");
    std::fs::write(&ipath, tensor_bytes("input", c, h, w, &input).unwrap()).unwrap();
    let opath = dir.path().join("out.safetensors");
    let args = ["unet", "--weights", wpath.to_str().unwrap(), "--input", ipath.to_str().unwrap()];
    let o = srug(&[&args[..], &["--out", opath.to_str().unwrap(), "--validation"]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let (oc, oh, ow, out) = read_tensor(&std::fs::read(&opath).unwrap(), "output", "out").unwrap();
    assert_eq!((oc, oh, ow), (3, h, w));
    let cpu = unet_cpu(&weights, &Tensor::from_f32(c, w, h, &input));
    let err = out.iter().zip(&cpu.data).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max);
    assert!(err <= 1e-4, "srug unet differs from the twin by {err:e}");
    // fp16 activation storage: within 1e-2 of the output scale.
    let o = srug(&[&args[..], &["--out", opath.to_str().unwrap(), "--precision", "fp16"]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let (_, _, _, out16) = read_tensor(&std::fs::read(&opath).unwrap(), "output", "out").unwrap();
    let peak = cpu.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let err = out16.iter().zip(&cpu.data).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max);
    assert!(err <= 1e-2 * peak, "fp16: {err:e} of {peak:e}");
    // Wrong channel count and a missing tensor are refused clearly.
    std::fs::write(&ipath, tensor_bytes("input", 5, h, w, &input[..5 * h * w]).unwrap()).unwrap();
    let o = srug(&[&args[..], &["--out", opath.to_str().unwrap()]].concat());
    assert!(!o.status.success() && text(&o).contains("5 channels"), "{}", text(&o));
    std::fs::write(&ipath, tensor_bytes("x", c, h, w, &input).unwrap()).unwrap();
    let o = srug(&[&args[..], &["--out", opath.to_str().unwrap()]].concat());
    assert!(!o.status.success() && text(&o).contains("\"input\" is missing"), "{}", text(&o));
    // A non-finite input is refused before anything runs, and no output is written.
    std::fs::remove_file(&opath).unwrap();
    let mut nan = input.clone();
    nan[7] = f32::NAN;
    std::fs::write(&ipath, tensor_bytes("input", c, h, w, &nan).unwrap()).unwrap();
    let o = srug(&[&args[..], &["--out", opath.to_str().unwrap()]].concat());
    assert!(!o.status.success() && text(&o).contains("tensor \"input\" element 7 is NaN"), "{}", text(&o));
    assert!(!opath.exists(), "nothing written");
    // A finite input of −3.4e38 overflows to NaN through a leaky-ReLU network: refused, nothing written.
    let leaky = UNetConfig { activation: srug::indirect::Activation::LeakyRelu, ..config };
    std::fs::write(&wpath, UNetWeights::random(leaky, 4).to_bytes().unwrap()).unwrap();
    std::fs::write(&ipath, tensor_bytes("input", c, h, w, &vec![-3.4e38f32; c * h * w]).unwrap()).unwrap();
    let o = srug(&[&args[..], &["--out", opath.to_str().unwrap()]].concat());
    assert!(!o.status.success() && text(&o).contains("overflow f32 through the layers"), "{}", text(&o));
    assert!(!opath.exists(), "nothing written");
}

#[test]
fn bench_unet_prints_its_table() {
    let args = ["bench", "unet", "--widths", "8,8,16,16,32", "--sizes", "37x23", "--repeats", "1", "--validation"];
    // Without --inputs: the device's default path, Winograd F(4×4) on a CPU device (lavapipe),
    // direct texel convolution on a GPU.
    let o = srug(&args);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let on_cpu = t.contains("(CPU)");
    let (default, other) = if on_cpu { ("winograd", "texel") } else { ("texel", "winograd") };
    assert!(t.contains(&format!("| 37x23 | fp32 | {default} |")) && !t.contains(&format!("| fp32 | {other} |")), "{t}");
    // Every path by name; Winograd F(4×4) only on a CPU device: NVIDIA's compiler spent
    // minutes on its pipelines (docs/bench/gpu.md).
    let inputs = if on_cpu { "vec4,texel,address,winograd,winograd2" } else { "vec4,texel,address,winograd2" };
    let o = srug(&[&args[..], &["--inputs", inputs]].concat());
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    for want in [
        "| 37x23 | fp32 | vec4 |",
        "| 37x23 | fp32 | texel |",
        "| 37x23 | fp32 | address |",
        "| 37x23 | fp32 | winograd2 |",
        "% of FMA peak",
        "after them; \"% of FMA peak\" takes the better, ",
        "texel per layer: inc",
        "winograd2 per layer: inc",
    ] {
        assert!(t.contains(want), "missing {want:?} in:\n{t}");
    }
    if on_cpu {
        assert!(t.contains("| 37x23 | fp32 | winograd |") && t.contains("winograd per layer: inc"), "{t}");
    }
    let o = srug(&[&args[..], &["--inputs", "texels"]].concat());
    let t = text(&o);
    assert!(
        !o.status.success() && t.contains("conv path \"texels\": is not winograd, winograd2, vec4, texel or address"),
        "{t}"
    );
}

#[test]
fn eval_reports_psnr_and_ssim_per_image_and_their_mean() {
    let dir = tempfile::tempdir().unwrap();
    let (refs, rendered) = (dir.path().join("ref"), dir.path().join("out"));
    std::fs::create_dir_all(&refs).unwrap();
    std::fs::create_dir_all(&rendered).unwrap();
    let (w, h) = (32u32, 24u32);
    let base: Vec<f32> = (0..w * h * 3).map(|i| ((i * 7919) % 251) as f32 / 250.0).collect();
    // 16/255 higher everywhere (in 8 bits, after clamping at 1): PSNR about 24 dB.
    let brighter: Vec<f32> = base.iter().map(|v| (v + 16.0 / 255.0).min(1.0)).collect();
    srug::io::write_png(refs.join("a.png"), w, h, &base).unwrap();
    srug::io::write_png(refs.join("b.png"), w, h, &base).unwrap();
    srug::io::write_png(rendered.join("a.png"), w, h, &base).unwrap();
    srug::io::write_png(rendered.join("b.png"), w, h, &brighter).unwrap();
    srug::io::write_png(rendered.join("c.png"), w, h, &base).unwrap();
    let csv = dir.path().join("eval.csv");
    let o = srug(&["eval", refs.to_str().unwrap(), rendered.to_str().unwrap(), "--csv", csv.to_str().unwrap()]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("| a | inf | 1.0000 |"), "{t}");
    assert!(t.contains("c.png has no reference"), "{t}");
    let csv = std::fs::read_to_string(&csv).unwrap();
    let b: Vec<&str> = csv.lines().find(|l| l.starts_with("b,")).unwrap().split(',').collect();
    let (p, s): (f64, f64) = (b[1].parse().unwrap(), b[2].parse().unwrap());
    assert!(p > 20.0 && p < 26.0 && s < 1.0 && s > 0.5, "b: PSNR {p}, SSIM {s}");

    // Different sizes are an error naming both files.
    srug::io::write_png(rendered.join("a.png"), w, h + 1, &vec![0.5; (w * (h + 1) * 3) as usize]).unwrap();
    let o = srug(&["eval", refs.join("a.png").to_str().unwrap(), rendered.join("a.png").to_str().unwrap()]);
    let t = text(&o);
    assert!(!o.status.success() && t.contains("differ in size") && t.contains("a.png"), "{t}");
}

#[test]
fn bench_trade_writes_csv_markdown_and_a_plot_with_the_pareto_front() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("trade");
    let o = srug(&[
        "bench",
        "trade",
        "--gaussians",
        "2000",
        "--size",
        "48x16",
        "--repeats",
        "1",
        "--network",
        "random",
        "--out",
        out.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let csv = std::fs::read_to_string(out.join("trade.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (knob, value, psnr, pareto, median) =
        (col("knob"), col("value"), col("psnr_db"), col("pareto"), col("median_ms"));
    // The presets, every knob and the fp16 network row.
    for want in ["fast", "balanced", "reference"] {
        assert!(rows.iter().any(|r| r[knob] == "preset" && r[value] == want), "no preset {want}:\n{csv}");
    }
    for want in [
        "shadow resolution",
        "k",
        "receiver depth",
        "map depth",
        "shadow test",
        "SH degree",
        "render scale",
        "tile size",
    ] {
        assert!(rows.iter().any(|r| r[knob] == want), "no knob {want}:\n{csv}");
    }
    assert!(rows.iter().any(|r| r[knob] == "U-Net storage" && r[value] == "fp16") || t.contains("16-bit"));
    // The reference is exact against itself and, being the most accurate, on the front.
    let reference = rows.iter().find(|r| r[knob] == "preset" && r[value] == "reference").unwrap();
    assert_eq!(reference[psnr], "inf");
    assert_eq!(reference[pareto], "true");
    // Every setting's shadows against the analytic block's truth: a real IoU, rates, edge error.
    let (block_iou, block_false, block_edge) = (col("block_iou"), col("block_false_shadow"), col("block_edge_px"));
    for r in &rows {
        let (iou, false_shadow, edge): (f64, f64, f64) =
            (r[block_iou].parse().unwrap(), r[block_false].parse().unwrap(), r[block_edge].parse().unwrap());
        assert!(iou > 0.5 && iou <= 1.0 && (0.0..0.5).contains(&false_shadow) && edge >= 0.0, "{r:?}");
    }
    let balanced = rows.iter().find(|r| r[knob] == "preset" && r[value] == "balanced").unwrap();
    let fast = rows.iter().find(|r| r[knob] == "preset" && r[value] == "fast").unwrap();
    let iou_of = |r: &Vec<&str>| r[block_iou].parse::<f64>().unwrap();
    assert!(iou_of(balanced) > iou_of(fast), "the balanced preset's shadows beat the fast one's");
    for r in &rows {
        let ms: f64 = r[median].parse().unwrap();
        assert!(ms > 0.0 && ms.is_finite(), "{r:?}");
        if r[psnr] != "inf" {
            let p: f64 = r[psnr].parse().unwrap();
            assert!(p.is_finite() && p > 5.0, "{r:?}");
        }
    }
    // The splatted colour still compared (frames are timed without it): SH degree 0 is a
    // finite PSNR against the reference's degree 3, which matches itself.
    let colour = col("colour_psnr_db");
    assert_eq!(reference[colour], "inf");
    let sh0 = rows.iter().find(|r| r[knob] == "SH degree" && r[value] == "0").unwrap();
    let p: f64 = sh0[colour].parse().unwrap();
    assert!(p.is_finite() && p > 5.0, "{sh0:?}");
    // The fastest row is always on the front.
    let fastest = rows.iter().min_by(|a, b| a[median].parse::<f64>().unwrap().total_cmp(&b[median].parse().unwrap()));
    assert_eq!(fastest.unwrap()[pareto], "true");
    let md = std::fs::read_to_string(out.join("trade.md")).unwrap();
    assert!(md.contains("| knob | value | frame ms"), "{md}");
    let png = image::open(out.join("trade.png")).unwrap();
    assert_eq!((png.width(), png.height()), (1100, 700));
    assert!(t.contains("trade.png"), "{t}");
}

#[test]
fn relight_presets_and_quality_options() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, cams) = demo_files(dir.path(), "3000");
    for (preset, extra) in [
        ("fast", vec![]),
        ("reference", vec![]),
        ("balanced", vec!["--render-scale", "0.25", "--sh-degree", "0", "--shadow-test", "traced"]),
        ("balanced", vec!["--tile", "8"]),
        ("fast", vec!["--tile", "32"]),
    ] {
        let out = dir.path().join(format!("{preset}.png"));
        let mut args = vec![
            "relight",
            scene.to_str().unwrap(),
            "--cameras",
            cams.to_str().unwrap(),
            "--index",
            "0",
            "--size",
            "64x24",
            "--preset",
            preset,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = srug(&args);
        assert!(o.status.success(), "{preset}: {}", text(&o));
        let img = image::open(&out).unwrap();
        assert_eq!((img.width(), img.height()), (64, 24), "{preset}: written at the camera's size");
    }
    // Refused settings: (option, value, what the message says).
    for (option, value, want) in [
        ("--preset", "best", "preset \"best\""),
        ("--render-scale", "1.5", "--render-scale 1.5: is not a number in (0, 1]"),
        ("--render-scale", "0", "--render-scale 0: is not a number in (0, 1]"),
        ("--tile", "12", "tile size 12: is not one of [8, 16, 32]"),
    ] {
        let args = ["relight", scene.to_str().unwrap(), "--cameras", cams.to_str().unwrap(), option, value];
        let o = srug(&[&args[..], &["--out", "x.png"]].concat());
        assert!(!o.status.success() && text(&o).contains(want), "{option} {value}: {}", text(&o));
    }
}

/// `srug convert` between formats: a file another tool wrote in, every
/// format out and read back by `info`; unbundled SOG, unknown extensions and
/// formats refused with nothing written.
#[test]
fn convert_writes_every_format_and_refuses_what_it_cannot() {
    let fixtures = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/formats");
    let dir = tempfile::tempdir().unwrap();
    let input = fixtures.join("st.v4.spz");
    for name in ["a.ply", "a.compressed.ply", "a.splat", "a.spz", "a.sog", "a.glb"] {
        let out = dir.path().join(name);
        let o = srug(&["convert", input.to_str().unwrap(), out.to_str().unwrap()]);
        let t = text(&o);
        assert!(o.status.success(), "{name}: {t}");
        assert!(t.contains("400 Gaussians (SH degree 3)"), "{t}");
        if name == "a.splat" {
            assert!(t.contains("does not store SH bands 1 to 3"), "{t}");
        }
        let o = srug(&["info", out.to_str().unwrap()]);
        let t = text(&o);
        assert!(o.status.success() && t.contains("Gaussians: 400"), "{name}: {t}");
    }
    // In Morton order: the same Gaussians, in another order (the same bytes a Gaussian).
    let (file_order, morton) = (dir.path().join("file.ply"), dir.path().join("morton.ply"));
    let o = srug(&["convert", input.to_str().unwrap(), file_order.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let o = srug(&["convert", input.to_str().unwrap(), morton.to_str().unwrap(), "--order", "morton"]);
    assert!(o.status.success() && text(&o).contains("400 Gaussians (SH degree 3)"), "{}", text(&o));
    let (a, b) = (std::fs::read(&file_order).unwrap(), std::fs::read(&morton).unwrap());
    assert!(a.len() == b.len() && a != b, "the order changed nothing, or the size");
    let rows = |bytes: &[u8]| -> Vec<Vec<u8>> {
        let body = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let mut rows: Vec<Vec<u8>> = bytes[body..].chunks((bytes.len() - body) / 400).map(<[u8]>::to_vec).collect();
        rows.sort();
        rows
    };
    assert_eq!(rows(&a), rows(&b), "the same Gaussians");
    // `srug info` says how far apart consecutive centres lie, and where srug rearranges them on loading.
    let hint = "in no spatial order: runs of 8 frames or more put them on the device along a Morton curve";
    let t = text(&srug(&["info", file_order.to_str().unwrap()]));
    assert!(t.contains("order: consecutive centres a median ") && t.contains(hint), "{t}");
    let t = text(&srug(&["info", morton.to_str().unwrap()]));
    assert!(t.contains("order: consecutive centres a median ") && !t.contains(hint), "{t}");
    let o = srug(&["convert", input.to_str().unwrap(), morton.to_str().unwrap(), "--order", "hilbert"]);
    assert!(!o.status.success() && text(&o).contains("hilbert"), "{}", text(&o));
    // An explicit format under a misleading extension is written, with a warning.
    let odd = dir.path().join("b.ply");
    let o = srug(&["convert", input.to_str().unwrap(), odd.to_str().unwrap(), "--format", "glb"]);
    assert!(o.status.success() && text(&o).contains("under an extension that says PLY"), "{}", text(&o));
    let o = srug(&["info", odd.to_str().unwrap()]);
    assert!(text(&o).contains("the extension says PLY but the content is GLB"), "{}", text(&o));
    for (out, args, words) in [
        ("meta.json", vec![], "writes SOG bundled"),
        ("c.xyz", vec![], "extension names no format srug writes"),
        ("c.ply", vec!["--format", "webp"], "format \"webp\": is unknown"),
    ] {
        let path = dir.path().join(out);
        let mut all = vec!["convert", input.to_str().unwrap(), path.to_str().unwrap()];
        all.extend(args);
        let o = srug(&all);
        assert_eq!(o.status.code(), if out == "c.ply" { Some(2) } else { Some(1) }, "{}", text(&o));
        assert!(text(&o).contains(words), "{}", text(&o));
        assert!(!path.exists(), "nothing written for {out}");
    }
}

/// `--cameras` takes a COLMAP model or a transforms.json (detected), with any scene format.
#[test]
fn render_takes_colmap_and_nerfstudio_cameras() {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data");
    let scene = data.join("formats/st.v4.spz");
    let dir = tempfile::tempdir().unwrap();
    for (i, cameras) in
        ["cameras/colmap/bin", "cameras/colmap/text/images.txt", "cameras/transforms.json"].iter().enumerate()
    {
        let out = dir.path().join(format!("v{i}.png"));
        let cams = data.join(cameras);
        let args = ["render", scene.to_str().unwrap(), "--cameras", cams.to_str().unwrap(), "--index", "3"];
        let o = srug(&[&args[..], &["--size", "40x30", "--out", out.to_str().unwrap()]].concat());
        assert!(o.status.success(), "{cameras}: {}", text(&o));
        assert!(out.is_file(), "{cameras}");
    }
    // Distorted and fisheye COLMAP cameras render and relight through their lenses.
    let cams = data.join("cameras/colmap_distorted/text");
    for index in ["0", "1"] {
        let out = dir.path().join(format!("d{index}.png"));
        let o = srug(&[
            "render",
            scene.to_str().unwrap(),
            "--cameras",
            cams.to_str().unwrap(),
            "--index",
            index,
            "--size",
            "40x30",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(out.is_file());
    }
    let (relightable, _) = demo_files(dir.path(), "1000");
    let out = dir.path().join("r.png");
    let o = srug(&[
        "relight",
        relightable.to_str().unwrap(),
        "--cameras",
        cams.to_str().unwrap(),
        "--index",
        "0",
        "--size",
        "40x30",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(out.is_file());
}

/// `--shard I/N` renders the I-th of N contiguous runs of the cameras; outputs keep
/// each camera's number in the whole list, so the shards together write exactly
/// the files (byte for byte) one unsharded run writes, and never overwrite each other.
#[test]
fn shards_split_a_camera_list_without_collisions() {
    let dir = tempfile::tempdir().unwrap();
    let (ply, cams) = demo_files(dir.path(), "2000");
    let run = |sub: &str, extra: &[&str]| {
        let folder = dir.path().join(sub);
        std::fs::create_dir_all(&folder).unwrap();
        let out = folder.join("f.png");
        let args = ["render", ply.to_str().unwrap(), "--cameras", cams.to_str().unwrap(), "--size", "88x24"];
        let o = srug(&[&args[..], extra, &["--out", out.to_str().unwrap()]].concat());
        assert!(o.status.success(), "{extra:?}: {}", text(&o));
        folder
    };
    let whole = run("whole", &[]);
    let mut names: Vec<String> =
        std::fs::read_dir(&whole).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, ["f_000.png", "f_001.png", "f_002.png", "f_003.png"]);
    let sharded = dir.path().join("sharded");
    for shard in ["0/3", "1/3", "2/3"] {
        let part = run(&format!("s{}", &shard[..1]), &["--shard", shard]);
        for e in std::fs::read_dir(&part).unwrap() {
            let e = e.unwrap();
            std::fs::create_dir_all(&sharded).unwrap();
            let to = sharded.join(e.file_name());
            assert!(!to.exists(), "shard {shard} wrote {} again", e.file_name().to_string_lossy());
            std::fs::copy(e.path(), to).unwrap();
        }
    }
    for name in &names {
        let (a, b) = (std::fs::read(whole.join(name)).unwrap(), std::fs::read(sharded.join(name)).unwrap());
        assert!(a == b, "{name} differs between the sharded and the whole run");
    }
    let args = ["render", ply.to_str().unwrap(), "--cameras", cams.to_str().unwrap(), "--size", "88x24", "--out"];
    let out = dir.path().join("x.png");
    let o = srug(&[&args[..], &[out.to_str().unwrap(), "--shard", "4/8"]].concat());
    assert!(!o.status.success() && text(&o).contains("--shard 4/8") && text(&o).contains("4 cameras"), "{}", text(&o));
    let o = srug(&[&args[..], &[out.to_str().unwrap(), "--shard", "2/2"]].concat());
    assert!(!o.status.success() && text(&o).contains("I/N"), "{}", text(&o));
}

/// The same inputs give the same bytes whatever lavapipe's thread count: PNG
/// and EXR from `srug render`, and relit PNG from `srug relight`, with 1 and 3
/// rasterizer threads.
#[test]
fn outputs_are_byte_identical_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let (ply, cams) = demo_files(dir.path(), "3000");
    let run = |threads: &str, command: &str, name: &str, extra: &[&str]| -> Vec<u8> {
        let out = dir.path().join(format!("{threads}_{name}"));
        let mut args = vec![command, ply.to_str().unwrap(), "--cameras", cams.to_str().unwrap(), "--index", "1"];
        args.extend(extra);
        args.extend(["--size", "176x48", "--out", out.to_str().unwrap()]);
        let o = Command::new(env!("CARGO_BIN_EXE_srug")).args(&args).env("LP_NUM_THREADS", threads).output().unwrap();
        assert!(o.status.success(), "{}", text(&o));
        std::fs::read(&out).unwrap()
    };
    for (command, name, extra) in [
        ("render", "a.png", &[][..]),
        ("render", "a.exr", &["--channels", "rgb,depth,normal"][..]),
        ("relight", "r.png", &[][..]),
    ] {
        let (one, three) = (run("1", command, name, extra), run("3", command, name, extra));
        assert!(one == three, "{command} {name}: bytes differ between 1 and 3 threads");
    }
}

/// `--writers N`: a batch's files encoded and written by N threads are the
/// same files, logged in camera order, as one writer's.
#[test]
fn files_are_the_same_whatever_the_writer_count() {
    let dir = tempfile::tempdir().unwrap();
    let (ply, cams) = demo_files(dir.path(), "3000");
    let run = |writers: &str, command: &str, name: &str, extra: &[&str]| -> (Vec<Vec<u8>>, Vec<String>) {
        let out_dir = dir.path().join(format!("{writers}_{command}_{name}"));
        std::fs::create_dir_all(&out_dir).unwrap();
        let out = out_dir.join(name);
        let mut args = vec![command, ply.to_str().unwrap(), "--cameras", cams.to_str().unwrap()];
        args.extend(extra);
        args.extend(["--size", "176x48", "--writers", writers, "--out", out.to_str().unwrap()]);
        let o = srug(&args);
        assert!(o.status.success(), "{}", text(&o));
        let mut files: Vec<_> = std::fs::read_dir(&out_dir).unwrap().map(|e| e.unwrap().path()).collect();
        files.sort();
        assert!(files.len() >= 4, "{command}: {} files", files.len());
        let lines = String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter_map(|l| l.split_whitespace().next().map(|p| p.rsplit('/').next().unwrap_or(p).to_string()))
            .collect();
        (files.iter().map(|f| std::fs::read(f).unwrap()).collect(), lines)
    };
    for (command, name, extra) in [
        ("render", "a.png", &[][..]),
        ("render", "a.exr", &["--channels", "rgb,depth"][..]),
        ("relight", "r.png", &[][..]),
    ] {
        let (one, one_log) = run("1", command, name, extra);
        let (three, three_log) = run("3", command, name, extra);
        assert!(one == three, "{command} {name}: files differ between 1 and 3 writers");
        assert_eq!(one_log, three_log, "{command} {name}: the log lists the files in camera order");
    }
    let o = srug(&["render", ply.to_str().unwrap(), "--writers", "0", "--out", "x.png"]);
    assert!(!o.status.success() && text(&o).contains("--writers"), "{}", text(&o));
}

/// `--panorama W`: each camera becomes a 360° × 180° equirectangular panorama
/// W × W/2 whose depth is the distance (so range equals depth); a Gaussian
/// ahead lands at the centre column, one behind at the left and right edges.
#[test]
fn render_writes_panoramas() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("two.ply");
    let mut text_ply = String::from("ply\nformat ascii 1.0\nelement vertex 2\n");
    for p in ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2"] {
        text_ply += &format!("property float {p}\n");
    }
    text_ply += "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n";
    // Ahead (+y) at 3 m, behind at 5 m; opaque, 0.3 m across.
    text_ply += "0 3 0 0.5 0.5 0.5 8 -1.2 -1.2 -1.2 1 0 0 0\n0 -5 0 0.5 0.5 0.5 8 -1.2 -1.2 -1.2 1 0 0 0\n";
    std::fs::write(&ply, text_ply).unwrap();
    let out = dir.path().join("pano.exr");
    let args = ["render", ply.to_str().unwrap(), "--eye", "0,0,0", "--target", "0,1,0", "--panorama", "64"];
    let o = srug(&[&args[..], &["--channels", "depth,range", "--out", out.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let image = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
    assert_eq!(image.attributes.display_window.size.0, 64);
    assert_eq!(image.attributes.display_window.size.1, 32);
    let floats = |name: &str| -> Vec<f32> {
        let c = image.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
        match &c.sample_data {
            exr::prelude::FlatSamples::F32(v) => v.clone(),
            other => panic!("{name} is not a float channel: {other:?}"),
        }
    };
    let (depth, range, alpha) = (floats("Z"), floats("range.Y"), floats("A"));
    assert_eq!(depth, range, "a panorama's depth is already the distance");
    for (x, distance) in [(32usize, 3.0f32), (31, 3.0), (0, 5.0), (63, 5.0)] {
        let p = 16 * 64 + x;
        assert!(alpha[p] > 0.5, "column {x}: alpha {}", alpha[p]);
        let z = depth[p] / alpha[p];
        assert!((z - distance).abs() < 0.01 * distance, "column {x}: depth {z}, want {distance}");
    }
    assert!(alpha[16 * 64 + 16] < 1e-3 && alpha[16 * 64 + 48] < 1e-3, "nothing to the sides");
    let o = srug(&[&args[..6], &["--panorama", "1", "--out", out.to_str().unwrap()]].concat());
    assert!(!o.status.success() && text(&o).contains("--panorama 1"), "{}", text(&o));
}

/// The header of a little-endian PLY of `count` Gaussians (INRIA's float properties, SH degree 0,
/// then `extra` property lines).
fn gaussians_ply_header(count: usize, extra: &str) -> Vec<u8> {
    let mut header = format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\n");
    for p in [
        "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1",
        "rot_2", "rot_3",
    ] {
        header += &format!("property float {p}\n");
    }
    header += extra;
    header += "end_header\n";
    header.into_bytes()
}

/// `srug render --ids`: integer PLY properties become exact 32-bit integer EXR
/// channels holding each pixel's top Gaussian's id; −1 and empty pixels read 4294967295.
#[test]
fn render_writes_exact_id_channels() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("labelled.ply");
    // Two opaque Gaussians side by side, with semantic ids 70000 and -1 and instance ids 3 and 250.
    let mut bytes = gaussians_ply_header(2, "property int semantic\nproperty uchar instance\n");
    for (x, semantic, instance) in [(-1.0f32, 70_000i32, 3u8), (1.0, -1, 250)] {
        for v in [x, 0.0, 0.0, 0.5, 0.5, 0.5, 5.0, -1.2, -1.2, -1.2, 1.0, 0.0, 0.0, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.extend_from_slice(&semantic.to_le_bytes());
        bytes.push(instance);
    }
    std::fs::write(&ply, bytes).unwrap();
    let out = dir.path().join("ids.exr");
    let args =
        ["render", ply.to_str().unwrap(), "--eye", "0,-6,0", "--target", "0,0,0", "--size", "64x32", "--fov", "60"];
    let o = srug(
        &[&args[..], &["--ids", "semantic,instance", "--channels", "range", "--out", out.to_str().unwrap()]].concat(),
    );
    assert!(o.status.success(), "{}", text(&o));
    let image = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
    // The range channel is depth times each pixel's ray length per unit depth.
    let floats = |name: &str| -> Vec<f32> {
        let c = image.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
        match &c.sample_data {
            exr::prelude::FlatSamples::F32(v) => v.clone(),
            other => panic!("{name} is not a float channel: {other:?}"),
        }
    };
    let (depth, range) = (floats("Z"), floats("range.Y"));
    let cam =
        srug::scene::Camera::look_at(glam::Vec3::new(0.0, -6.0, 0.0), glam::Vec3::ZERO, glam::Vec3::Z, 60.0, 64, 32)
            .unwrap();
    let mut checked = 0;
    for p in (0..64 * 32).filter(|p| depth[*p] > 0.1) {
        let s = cam.ray_length_per_depth([(p % 64) as f64 + 0.5, (p / 64) as f64 + 0.5]).unwrap();
        assert!((f64::from(range[p]) - f64::from(depth[p]) * s).abs() < 1e-5 * f64::from(range[p]), "pixel {p}");
        checked += 1;
    }
    assert!(checked > 20, "{checked} pixels with depth");
    let channel = |name: &str| -> Vec<u32> {
        let c = image.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
        match &c.sample_data {
            exr::prelude::FlatSamples::U32(v) => v.clone(),
            other => panic!("{name} is not a 32-bit integer channel: {other:?}"),
        }
    };
    let (semantic, instance, top) = (channel("semantic"), channel("instance"), channel("top_gaussian"));
    // The left Gaussian (x = −1) lands left of centre, the right one right of it (camera looking +y, x right).
    let (left, right, corner) = (16 * 64 + 21, 16 * 64 + 42, 0);
    assert_eq!((top[left], semantic[left], instance[left]), (0, 70_000, 3));
    assert_eq!((top[right], semantic[right], instance[right]), (1, u32::MAX, 250));
    assert_eq!((top[corner], semantic[corner], instance[corner]), (u32::MAX, u32::MAX, u32::MAX));
    // Ids need an EXR, a float property is refused, an unknown one is named.
    let png = dir.path().join("x.png");
    let o = srug(&[&args[..], &["--ids", "semantic", "--out", png.to_str().unwrap()]].concat());
    assert!(text(&o).contains("--ids semantic: needs an .exr output"), "{}", text(&o));
    let o = srug(&[&args[..], &["--ids", "opacity", "--out", out.to_str().unwrap()]].concat());
    assert!(text(&o).contains("ids must be integers"), "{}", text(&o));
    let o = srug(&[&args[..], &["--ids", "class", "--out", out.to_str().unwrap()]].concat());
    assert!(
        text(&o).contains("property class") && text(&o).contains("integer properties: semantic, instance"),
        "{}",
        text(&o)
    );
}

/// A PLY listing its Gaussians in no spatial order goes onto the device along a Morton curve
/// (said in the log) with `--scene-order morton`, and with `auto` for a run of eight frames or more
/// (not for one), and renders the same: the same top Gaussian (its file row) and ids in every pixel
/// as with `--scene-order file`.
#[test]
fn render_arranges_a_scrambled_scene_and_names_gaussians_by_file_row() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("scrambled.ply");
    // A 32 × 16 wall of small opaque Gaussians facing the camera, listed in a scrambled order,
    // each with its file row as its id.
    let mut bytes = gaussians_ply_header(512, "property int row\n");
    for row in 0..512i32 {
        let cell = (row * 97 + 5) % 512;
        let (x, z) = ((cell % 32) as f32 * 0.2 - 3.1, (cell / 32) as f32 * 0.2 - 1.5);
        let colour = (cell % 7) as f32 * 0.3 - 1.0;
        // Each a little deeper than the last cell's (no two depths tie: ties blend in listed order).
        let y = cell as f32 * 1e-3;
        for v in [x, y, z, colour, 0.2, -colour, 4.0, -2.8, -6.0, -2.8, 1.0, 0.0, 0.0, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.extend_from_slice(&row.to_le_bytes());
    }
    std::fs::write(&ply, bytes).unwrap();
    let args =
        ["render", ply.to_str().unwrap(), "--eye", "0,-8,0", "--target", "0,0,0", "--size", "96x48", "--fov", "50"];
    let mut images = Vec::new();
    for order in ["morton", "file", "auto"] {
        let out = dir.path().join(format!("{order}.exr"));
        let o = srug(
            &[
                &args[..],
                &["--scene-order", order, "--ids", "row", "--channels", "rgb", "--out", out.to_str().unwrap()],
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", text(&o));
        assert_eq!(text(&o).contains("along a Morton curve"), order == "morton", "{order}: {}", text(&o));
        images.push(exr::prelude::read_all_flat_layers_from_file(&out).unwrap());
    }
    // Eight cameras: auto moves the Gaussians.
    let camera =
        srug::scene::Camera::look_at(glam::Vec3::new(0.0, -8.0, 0.0), glam::Vec3::ZERO, glam::Vec3::Z, 50.0, 96, 48)
            .unwrap();
    let cameras = dir.path().join("cameras.json");
    srug::io::write_cameras_json(&cameras, &vec![camera; 8]).unwrap();
    let frames = dir.path().join("f.png");
    let o = srug(&[
        "render",
        ply.to_str().unwrap(),
        "--cameras",
        cameras.to_str().unwrap(),
        "--out",
        frames.to_str().unwrap(),
    ]);
    assert!(o.status.success() && text(&o).contains("along a Morton curve"), "{}", text(&o));
    let channel = |i: usize, name: &str| -> Vec<u32> {
        let c = images[i].layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
        match &c.sample_data {
            exr::prelude::FlatSamples::U32(v) => v.clone(),
            other => panic!("{name} is not a 32-bit integer channel: {other:?}"),
        }
    };
    let (top, row, listed) = (channel(0, "top_gaussian"), channel(0, "row"), channel(1, "top_gaussian"));
    let differ = |a: &[u32], b: &[u32]| a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert_eq!(differ(&top, &listed), 0, "the same file rows as in the file's order");
    assert_eq!(differ(&row, &top), 0, "each Gaussian's id is its file row");
    assert!(top.iter().filter(|t| **t != u32::MAX).count() > 96 * 48 / 3, "the wall covers the image");
    let o = srug(&[&args[..], &["--scene-order", "hilbert", "--out", "x.png"]].concat());
    assert!(!o.status.success() && text(&o).contains("hilbert"), "{}", text(&o));
}

/// The analytic block's completion from files on disk: the scene without its tallest building as
/// PLY, every camera as cameras.json, shadow masks written by the `image` crate (white = shadow;
/// PNG and JPEG, at twice the fit size) for three of the four cameras.
#[test]
fn shadow_fit_completes_a_scene_from_masks_on_disk() {
    use srug::scene::blocks::{block_completion, BlockOptions};
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let b = block_completion(&BlockOptions::default(), 352, 96).unwrap();
    srug::io::write_ply(p.join("scene.ply"), &b.without, srug::io::PlyFormat::BinaryLittleEndian).unwrap();
    srug::io::write_cameras_json(p.join("cameras.json"), &b.cameras).unwrap();
    let masks = p.join("masks");
    std::fs::create_dir_all(&masks).unwrap();
    for (i, ext) in [(0, "png"), (2, "png"), (3, "jpg")] {
        let c = &b.cameras[i];
        let bytes: Vec<u8> = b.city.shadow_target(c, b.sun).iter().map(|v| ((1.0 - v) * 255.0) as u8).collect();
        let img = image::GrayImage::from_raw(c.width, c.height, bytes).unwrap();
        img.save(masks.join(format!("{}.{ext}", c.name))).unwrap();
    }
    let sun = srug::shadow::Sun::from_direction(b.sun, [1.0; 3]).unwrap();
    let (azimuth, elevation) = sun.azimuth_elevation();
    let (az, el) = (format!("{azimuth}"), format!("{elevation}"));
    let s = |name: &str| p.join(name).to_str().unwrap().to_string();
    let (scene, cams, mask_dir, out, report) = (s("scene.ply"), s("cameras.json"), s("masks"), s("done.ply"), s("rep"));
    let base = ["shadow-fit", &scene, "--cameras", &cams, "--masks", &mask_dir];
    let sun = ["--sun-azimuth", &az, "--sun-elevation", &el];
    let run = [&base[..], &sun[..], &["--size", "176x48", "--steps", "30", "--added", "2000", "--out", &out]].concat();
    let o = srug(&[&run[..], &["--report", &report, "--validation"]].concat());
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("camera \"street_1\": no mask"), "{t}");
    assert!(t.contains("step  30:") && t.contains("validation messages: 0"), "{t}");
    for name in ["street_0", "street_2", "street_3"] {
        let line = t.lines().find(|l| l.starts_with(&format!("camera \"{name}\": shadow IoU"))).expect(name);
        let nums: Vec<f64> = line.split(' ').filter_map(|w| w.parse().ok()).collect();
        let (before, after) = (nums[nums.len() - 2], nums[nums.len() - 1]);
        // Small and short here (176×48, 30 steps); the library's test holds ≥ 0.9 against the
        // truth at 352×96 (tests/tests/shadow_fit.rs).
        assert!(before < 0.4 && after >= 0.8, "{line} in:\n{t}");
        for when in ["before", "after"] {
            let png = image::open(p.join("rep").join(format!("agreement_{name}_{when}.png"))).unwrap();
            assert_eq!((png.width(), png.height()), (176, 48));
        }
    }
    let history = std::fs::read_to_string(p.join("rep").join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 32, "header and 31 steps:\n{history}");
    // The input's Gaussians unchanged and unflagged, the added ones flagged.
    let done = srug::io::read_ply(&out).unwrap();
    let n = b.without.len();
    assert!(done.len() > n && done.len() <= n + 2000, "{} Gaussians", done.len());
    assert_eq!(done.means[..n], b.without.means[..]);
    let flags = srug::io::read_ply_ids(&out, &["srug_added".into(), "srug_moved".into()]).unwrap();
    assert!(flags[0][..n].iter().all(|f| *f == 0) && flags[0][n..].iter().all(|f| *f == 1));
    assert!(flags[1].iter().all(|f| *f == 0), "nothing movable, nothing moved");

    // Bad input: a clear message, a failing exit, nothing written.
    let bad = |extra: &[&str], masks: &str, out: &str, want: &str| {
        let mut args: Vec<&str> = base.to_vec();
        args[5] = masks;
        args.extend(if extra.is_empty() { &sun[..] } else { extra });
        args.extend(["--out", out]);
        let o = srug(&args);
        let t = text(&o);
        assert!(!o.status.success() && t.contains(want), "{args:?}: wanted {want:?} in:\n{t}");
        assert!(!t.contains("panicked"), "{t}");
        assert!(!std::path::Path::new(out).exists(), "{args:?} wrote {out}");
    };
    let other = p.join("other");
    std::fs::create_dir_all(&other).unwrap();
    image::GrayImage::new(8, 8).save(other.join("elsewhere.png")).unwrap();
    let none = s("none.ply");
    bad(&[], other.to_str().unwrap(), &none, "match no camera");
    let white = p.join("white");
    std::fs::create_dir_all(&white).unwrap();
    image::GrayImage::from_pixel(8, 8, image::Luma([255])).save(white.join("street_0.png")).unwrap();
    bad(&[], white.to_str().unwrap(), &none, "all one value");
    bad(&["--sun-azimuth", &az, "--sun-elevation", "-5"], &mask_dir, &none, "above the horizon");
    bad(&[], &mask_dir, &s("done.spz"), "must be a .ply");
    let o = srug(&["shadow-fit", &scene, "--masks", &mask_dir, "--out", &none]);
    assert!(!o.status.success() && text(&o).contains("needs --cameras"), "{}", text(&o));
    bad(&[&sun[..], &["--fixed-steps", "3"]].concat(), &mask_dir, &none, "fixed-visibility attribute");

    // L_Vf alone on a relightable copy: only the fixed visibility changes, nothing is added.
    let mut relightable = b.without.clone();
    relightable.materials.albedo = Some(vec![[0.5; 3]; n]);
    relightable.materials.visibility = Some(vec![2.0; n]);
    srug::io::write_ply(p.join("relightable.ply"), &relightable, srug::io::PlyFormat::BinaryLittleEndian).unwrap();
    let (relit_in, fixed_out) = (s("relightable.ply"), s("fixed.ply"));
    let mut args = vec!["shadow-fit", &relit_in, "--cameras", &cams, "--masks", &mask_dir];
    args.extend(sun);
    args.extend(["--size", "176x48", "--fixed-steps", "8", "--added", "0", "--out", &fixed_out]);
    let o = srug(&args);
    let t = text(&o);
    assert!(o.status.success() && t.contains("fixed visibility step   8:"), "{t}");
    let line = t.lines().find(|l| l.starts_with("camera \"street_2\": fixed visibility IoU")).expect("a fixed line");
    let nums: Vec<f64> = line.split(' ').filter_map(|w| w.parse().ok()).collect();
    assert!(nums[nums.len() - 2] < 0.5 && nums[nums.len() - 1] >= 0.8, "{line}");
    let fixed = srug::io::read_ply(&fixed_out).unwrap();
    assert_eq!((fixed.len(), &fixed.means), (n, &relightable.means));
    assert_ne!(fixed.materials.visibility, relightable.materials.visibility);
}

/// Every `[preset: …]` claim in `srug relight --help` is what the presets set
/// (the help is written by hand; the presets move with measurements).
#[test]
fn relight_help_states_the_presets_values() {
    use clap::CommandFactory;
    use srug::frame::{Preset, RelightSettings};
    use srug::indirect::StoragePrecision;
    use srug::shadow::{DepthMode, ShadowFit, VisibilityKind};
    let command = srug_cli::Cli::command();
    let relight = command.find_subcommand("relight").unwrap();
    let help = |id: &str| {
        let arg = relight.get_arguments().find(|a| a.get_id() == id).unwrap_or_else(|| panic!("no argument {id}"));
        arg.get_help().map(ToString::to_string).unwrap_or_default()
    };
    let [fast, balanced, reference] = Preset::ALL.map(RelightSettings::preset);
    // A value every preset shares, as the help writes it.
    let shared = |get: &dyn Fn(&RelightSettings) -> String| {
        let value = get(&balanced);
        assert_eq!((get(&fast), get(&reference)), (value.clone(), value.clone()), "one value for every preset");
        value
    };
    assert_eq!((balanced.sh_degree, reference.sh_degree), (None, None));
    assert_eq!((balanced.render_scale, reference.render_scale), (0.0, 0.0), "0: full size");
    assert_eq!(balanced.visibility_kind, fast.visibility_kind);
    let precision = |p: Preset| if p.indirect_precision() == StoragePrecision::Fp16 { "fp16" } else { "fp32" };
    assert_eq!(precision(Preset::Balanced), precision(Preset::Reference));
    let fit = ["scene", "view", "cascades"].into_iter().find(|n| ShadowFit::parse(n).ok() == Some(balanced.shadow.fit));
    let depth =
        ["median", "expected"].into_iter().find(|n| DepthMode::parse(n).ok() == Some(balanced.shadow.receiver_depth));
    let test = |k: VisibilityKind| if k == VisibilityKind::Traced { "traced" } else { "sigmoid" };
    let claims = [
        (
            "shadow_resolution",
            format!(
                "fast {}, balanced {}, reference {}",
                fast.shadow.resolution, balanced.shadow.resolution, reference.shadow.resolution
            ),
        ),
        ("shadow_k", shared(&|s| s.shadow.k.to_string())),
        ("shadow_bias", shared(&|s| s.shadow.bias.to_string())),
        ("shadow_slope_bias", shared(&|s| s.shadow.slope_bias.to_string())),
        ("shadow_normal_offset", shared(&|s| s.shadow.normal_offset.to_string())),
        ("shadow_filter", shared(&|s| s.shadow.filter.name().to_string())),
        ("shadow_surface_depth", shared(&|s| s.shadow.surface_depth.to_string())),
        ("shadow_map_surface_depth", shared(&|s| s.shadow.map_surface_depth.to_string())),
        ("shadow_map_coverage", shared(&|s| s.shadow.map_coverage.to_string())),
        ("shadow_receiver_coverage", shared(&|s| s.shadow.receiver_coverage.to_string())),
        ("shadow_fit", fit.unwrap().to_string()),
        ("receiver_depth", depth.unwrap().to_string()),
        ("tile", shared(&|s| s.tile.to_string())),
        (
            "shadow_test",
            format!("reference {}, else {}", test(reference.visibility_kind), test(balanced.visibility_kind)),
        ),
        ("sh_degree", format!("fast {}, else the scene's", fast.sh_degree.unwrap())),
        ("render_scale", format!("fast {}, else 1", fast.render_scale)),
        ("indirect_precision", format!("fast {}, else {}", precision(Preset::Fast), precision(Preset::Balanced))),
    ];
    for (id, value) in claims {
        let text = help(id);
        assert!(text.contains(&format!("[preset: {value}]")), "--{id} says {text:?}; the presets set {value}");
    }
}
