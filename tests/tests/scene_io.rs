//! Scene I/O: PLY round trips, property order and spellings, every bad-input
//! case, cameras.json, the real trained scene, and the demo city.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use std::fmt::Write as _;

use glam::Vec3;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::io::{
    parse_cameras_json, read_cameras_json, read_ply, read_ply_bytes, write_cameras_json, write_ply, PlyFormat,
};
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::{Scene, SceneError};
use srug::Error;

fn small_demo(sh_degree: u32) -> Scene {
    demo_city(&DemoOptions { seed: 3, gaussians: 2_000, sh_degree }).unwrap().scene
}

fn bits_equal(a: &Scene, b: &Scene) -> bool {
    fn f(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }
    let flat3 = |v: &[[f32; 3]]| f(&v.concat());
    let m = (&a.materials, &b.materials);
    a.len() == b.len()
        && a.sh_degree == b.sh_degree
        && flat3(&a.means) == flat3(&b.means)
        && a.normals.as_deref().map(flat3) == b.normals.as_deref().map(flat3)
        && f(&a.sh) == f(&b.sh)
        && f(&a.opacity_logits) == f(&b.opacity_logits)
        && flat3(&a.log_scales) == flat3(&b.log_scales)
        && f(&a.rotations.concat()) == f(&b.rotations.concat())
        && m.0.albedo.as_deref().map(flat3) == m.1.albedo.as_deref().map(flat3)
        && m.0.roughness.as_deref().map(f) == m.1.roughness.as_deref().map(f)
        && m.0.metallic.as_deref().map(f) == m.1.metallic.as_deref().map(f)
        && m.0.ao.as_deref().map(f) == m.1.ao.as_deref().map(f)
        && m.0.visibility.as_deref().map(f) == m.1.visibility.as_deref().map(f)
}

#[test]
fn ply_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let mut plain = small_demo(0);
    plain.normals = None;
    plain.materials = Default::default();
    // Awkward values: subnormals, negative zero, extremes of f32.
    plain.means[0] = [f32::MIN_POSITIVE / 8.0, -0.0, f32::MAX];
    plain.log_scales[1] = [-87.0, 88.0, 1e-30];
    for (name, scene) in [("full_sh3", small_demo(3)), ("full_sh1", small_demo(1)), ("plain_sh0", plain)] {
        for format in [PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian, PlyFormat::Ascii] {
            let path = dir.path().join(format!("{name}_{format:?}.ply"));
            write_ply(&path, &scene, format).unwrap();
            let back = read_ply(&path).unwrap();
            assert!(bits_equal(&scene, &back), "{name} {format:?} round trip differs");
            assert!(back.extra_properties.is_empty());
            assert_eq!(back.attributes(), scene.attributes());
        }
    }
}

#[test]
fn flags_round_trip_as_uchar_properties() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_demo(1);
    let flags: Vec<bool> = (0..scene.len()).map(|i| i % 3 == 1).collect();
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian, PlyFormat::Ascii] {
        let path = dir.path().join(format!("flagged_{format:?}.ply"));
        srug::io::write_ply_with_flags(&path, &scene, format, &[("srug_added", &flags)]).unwrap();
        let text = std::fs::read(&path).unwrap();
        let want = b"property uchar srug_added\n";
        assert!(text.windows(want.len()).any(|w| w == want), "{format:?}: no uchar property");
        // The Gaussians read back unchanged, the flag as a property srug does not use.
        let back = read_ply(&path).unwrap();
        assert!(bits_equal(&scene, &back), "{format:?}: the Gaussians changed");
        assert_eq!(back.extra_properties, ["srug_added"]);
        let ids = srug::io::read_ply_ids(&path, &["srug_added".into()]).unwrap();
        assert_eq!(ids[0], flags.iter().map(|f| u32::from(*f)).collect::<Vec<_>>(), "{format:?}");
    }
    // A flag list of the wrong length or a clashing name writes nothing.
    let path = dir.path().join("bad.ply");
    let short = vec![true; scene.len() - 1];
    let e = srug::io::write_ply_with_flags(&path, &scene, PlyFormat::Ascii, &[("srug_added", &short)]).unwrap_err();
    assert!(e.to_string().contains("one value per Gaussian"), "{e}");
    let e = srug::io::write_ply_with_flags(&path, &scene, PlyFormat::Ascii, &[("opacity", &flags)]).unwrap_err();
    assert!(e.to_string().contains("srug_added") || e.to_string().contains("opacity"), "{e}");
    assert!(!path.exists());
}

/// Writes a binary little-endian PLY with properties in the given order.
fn ply_with(names: &[String], rows: &[Vec<f32>]) -> Vec<u8> {
    let mut header = format!("ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex {}\n", rows.len());
    for n in names {
        let _ = writeln!(header, "property float {n}");
    }
    header += "end_header\n";
    let mut bytes = header.into_bytes();
    for r in rows {
        for v in r {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    bytes
}

fn standard_names(rest: usize) -> Vec<String> {
    let mut names: Vec<String> =
        ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"].map(String::from).to_vec();
    names.extend((0..rest).map(|i| format!("f_rest_{i}")));
    names.extend(["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"].map(String::from));
    names
}

fn random_rows(n: usize, props: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    (0..n).map(|_| (0..props).map(|_| rng.random_range(-2.0..2.0f32)).collect()).collect()
}

#[test]
fn properties_found_by_name_in_any_order() {
    let mut names = standard_names(9);
    names.extend(
        ["albedo_0", "albedo_1", "albedo_2", "roughness", "metallic", "mystery", "semantic_id"].map(String::from),
    );
    let rows = random_rows(50, names.len(), 1);
    let reference = read_ply_bytes(&ply_with(&names, &rows), "ordered").unwrap();
    assert_eq!(reference.sh_degree, 1);
    assert_eq!(reference.extra_properties, ["mystery", "semantic_id"]);

    let mut order: Vec<usize> = (0..names.len()).collect();
    order.shuffle(&mut Pcg64Mcg::seed_from_u64(9));
    let shuffled_names: Vec<String> = order.iter().map(|&i| names[i].clone()).collect();
    let shuffled_rows: Vec<Vec<f32>> = rows.iter().map(|r| order.iter().map(|&i| r[i]).collect()).collect();
    let shuffled = read_ply_bytes(&ply_with(&shuffled_names, &shuffled_rows), "shuffled").unwrap();
    assert!(bits_equal(&reference, &shuffled), "shuffled property order changes the scene");
    let mut extras = shuffled.extra_properties.clone();
    extras.sort();
    assert_eq!(extras, ["mystery", "semantic_id"]);

    // Channel-major f_rest: f_rest_0..2 are the red channel's first three coefficients.
    let k = 4;
    let row = &rows[7];
    let idx = |n: &str| names.iter().position(|x| x == n).unwrap();
    assert_eq!(reference.sh[(7 * k + 1) * 3], row[idx("f_rest_0")]);
    assert_eq!(reference.sh[(7 * k + 1) * 3 + 1], row[idx("f_rest_3")]);
    assert_eq!(reference.sh[(7 * k + 3) * 3 + 2], row[idx("f_rest_8")]);
    assert_eq!(reference.sh[7 * k * 3 + 2], row[idx("f_dc_2")]);
}

#[test]
fn material_spellings_of_relightable_codes() {
    for (spelling, extra) in
        [("albedo_", vec!["roughness", "metallic"]), ("base_color_", vec!["roughness"]), ("albedo", vec![])]
    {
        let mut names = standard_names(0);
        names.extend((0..3).map(|i| format!("{spelling}{i}")));
        names.extend(extra.iter().map(|s| s.to_string()));
        let rows = random_rows(5, names.len(), 2);
        let scene = read_ply_bytes(&ply_with(&names, &rows), spelling).unwrap();
        let albedo = scene.materials.albedo.as_ref().unwrap_or_else(|| panic!("{spelling}: albedo not found"));
        let col = names.iter().position(|n| n == &format!("{spelling}1")).unwrap();
        assert_eq!(albedo[3][1], rows[3][col]);
        assert_eq!(scene.materials.roughness.is_some(), extra.contains(&"roughness"));
        assert_eq!(scene.materials.metallic.is_some(), extra.contains(&"metallic"));
        assert!(scene.extra_properties.is_empty(), "{spelling}: {:?}", scene.extra_properties);
        assert!(scene.attributes().shadeable());
    }
}

fn expect_error(bytes: &[u8], want_row: Option<usize>, want_property: Option<&str>, want_text: &str) -> SceneError {
    match read_ply_bytes(bytes, "case.ply") {
        Ok(_) => panic!("expected an error containing {want_text:?}"),
        Err(e) => {
            let shown = e.to_string();
            assert!(shown.starts_with("case.ply"), "{shown}");
            assert!(shown.contains(want_text), "{shown:?} lacks {want_text:?}");
            assert_eq!(e.row, want_row, "{shown}");
            assert_eq!(e.property.as_deref(), want_property, "{shown}");
            e
        }
    }
}

#[test]
fn bad_ply_inputs_give_clear_errors() {
    let names = standard_names(0);
    let p = names.len();
    let rows = random_rows(10, p, 3);
    let good = ply_with(&names, &rows);
    assert!(read_ply_bytes(&good, "good").is_ok());
    let header_len = good.len() - 10 * p * 4;

    // Truncated in row 6, inside property index 4 (ny).
    let cut = header_len + 6 * p * 4 + 4 * 4 + 2;
    expect_error(&good[..cut], Some(6), Some("ny"), "truncated");

    // Declared count larger / smaller than the data.
    let more = String::from_utf8_lossy(&good[..header_len]).replace("element vertex 10", "element vertex 11");
    let mut bytes = more.into_bytes();
    bytes.extend_from_slice(&good[header_len..]);
    expect_error(&bytes, Some(10), Some("x"), "truncated");
    let fewer = String::from_utf8_lossy(&good[..header_len]).replace("element vertex 10", "element vertex 9");
    let mut bytes = fewer.into_bytes();
    bytes.extend_from_slice(&good[header_len..]);
    expect_error(&bytes, None, None, "vertex count does not match");

    // Missing required property.
    let without: Vec<String> = names.iter().filter(|n| *n != "opacity").cloned().collect();
    let col = names.iter().position(|n| n == "opacity").unwrap();
    let rows_without: Vec<Vec<f32>> =
        rows.iter().map(|r| r.iter().enumerate().filter(|(i, _)| *i != col).map(|(_, v)| *v).collect()).collect();
    expect_error(&ply_with(&without, &rows_without), None, Some("opacity"), "missing");

    // NaN and Inf values, named by row and property.
    for (bad, text) in [(f32::NAN, "NaN"), (f32::INFINITY, "inf"), (f32::NEG_INFINITY, "-inf")] {
        let mut r = rows.clone();
        let col = names.iter().position(|n| n == "scale_1").unwrap();
        r[4][col] = bad;
        expect_error(&ply_with(&names, &r), Some(4), Some("scale_1"), text);
    }
    let mut r = rows.clone();
    r[2][names.iter().position(|n| n == "f_dc_1").unwrap()] = f32::NAN;
    expect_error(&ply_with(&names, &r), Some(2), Some("f_dc_1"), "NaN");

    // Zero quaternion.
    let mut r = rows.clone();
    for q in ["rot_0", "rot_1", "rot_2", "rot_3"] {
        r[8][names.iter().position(|n| n == q).unwrap()] = 0.0;
    }
    expect_error(&ply_with(&names, &r), Some(8), Some("rot_0..rot_3"), "quaternion is zero");

    // Not a PLY file at all; an empty file; a header without end.
    expect_error(b"\x89PNG\r\n\x1a\n0000", None, None, "not a PLY file");
    expect_error(b"", None, None, "not a PLY file");
    expect_error(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n", None, None, "end_header");
    expect_error(b"ply\nformat binary_little_endian 2.0\nelement vertex 0\nend_header\n", None, None, "version");
    expect_error(b"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nelement vertex 0\nend_header\n", None, None, "vertex element must come first");

    // Unsupported SH count (12 f_rest properties).
    let odd = standard_names(12);
    expect_error(&ply_with(&odd, &random_rows(2, odd.len(), 4)), None, None, "unsupported SH count");

    // A gap in f_rest numbering.
    let mut gap = standard_names(9);
    let i = gap.iter().position(|n| n == "f_rest_4").unwrap();
    gap[i] = "f_rest_9".into();
    expect_error(&ply_with(&gap, &random_rows(2, gap.len(), 5)), None, Some("f_rest_4"), "missing");

    // ASCII: a short row, junk, too many rows.
    let ascii_header = |n: usize| {
        let mut h = format!("ply\nformat ascii 1.0\nelement vertex {n}\n");
        for name in &names {
            let _ = writeln!(h, "property float {name}");
        }
        h + "end_header\n"
    };
    let row = |vals: &[f32]| vals.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(" ") + "\n";
    let mut text = ascii_header(2) + &row(&rows[0]);
    text += &row(&rows[1][..p - 1]);
    expect_error(text.as_bytes(), Some(1), Some("rot_3"), "too few values");
    let mut text = ascii_header(2) + &row(&rows[0]);
    text += &row(&rows[1]).replacen(' ', " abc ", 1);
    expect_error(text.as_bytes(), Some(1), Some("y"), "cannot parse \"abc\"");
    let text = ascii_header(1) + &row(&rows[0]) + &row(&rows[1]);
    expect_error(text.as_bytes(), None, None, "vertex count does not match");
    let text = ascii_header(3) + &row(&rows[0]);
    expect_error(text.as_bytes(), Some(1), Some("x"), "truncated");
}

#[test]
fn nothing_is_written_on_failure() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = small_demo(0);
    scene.opacity_logits[17] = f32::NAN;
    let path = dir.path().join("bad.ply");
    match write_ply(&path, &scene, PlyFormat::BinaryLittleEndian) {
        Err(Error::Scene(e)) => {
            assert_eq!(e.row, Some(17));
            assert_eq!(e.property.as_deref(), Some("opacity"));
        }
        other => panic!("expected a scene error, got {other:?}"),
    }
    // A write into a folder that does not exist fails too.
    let good = small_demo(0);
    assert!(write_ply(dir.path().join("missing").join("x.ply"), &good, PlyFormat::Ascii).is_err());
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "files left behind: {left:?}");

    // A missing file is an I/O error naming the path.
    match read_ply(dir.path().join("absent.ply")) {
        Err(e @ Error::Io { .. }) => assert!(e.to_string().contains("absent.ply")),
        other => panic!("expected an I/O error, got {other:?}"),
    }
}

#[test]
fn cameras_json_round_trip_and_errors() {
    let city = demo_city(&DemoOptions { seed: 1, gaussians: 1_000, sh_degree: 0 }).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cameras.json");
    write_cameras_json(&path, &city.cameras).unwrap();
    let back = read_cameras_json(&path).unwrap();
    assert_eq!(back.len(), city.cameras.len());
    for (a, b) in city.cameras.iter().zip(&back) {
        assert_eq!((a.width, a.height, &a.name), (b.width, b.height, &b.name));
        assert!((a.position - b.position).abs().max_element() < 1e-5);
        assert!((a.rotation.to_cols_array().iter().zip(b.rotation.to_cols_array())).all(|(x, y)| (x - y).abs() < 1e-6));
        assert_eq!(a.projection, b.projection);
    }

    // INRIA semantics: rotation rows of camera-to-world, position the centre.
    let text = r#"[{"id": 0, "img_name": "a", "width": 64, "height": 32, "position": [1, 2, 3],
        "rotation": [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], "fx": 50, "fy": 50}]"#;
    let cams = parse_cameras_json(text, "inline").unwrap();
    let c = &cams[0];
    // The camera looks along its third column: world +x (first rows' last entries).
    assert!((c.rotation.z_axis - Vec3::X).length() < 1e-6);
    let p = c.world_to_camera(Vec3::new(11.0, 2.0, 3.0));
    assert!((p - Vec3::new(0.0, 0.0, 10.0)).length() < 1e-5, "{p}");
    let px = c.project(p);
    assert_eq!((px.x, px.y), (32.0, 16.0));

    let cases = [
        ("[{\"id\": 0,", "malformed"),
        ("{}", "malformed"),
        (
            r#"[{"id": 0, "img_name": "a", "width": 64, "height": 32, "position": [1, 2, 3], "fx": 50, "fy": 50}]"#,
            "rotation",
        ),
        (
            r#"[{"id": 0, "img_name": "a", "width": 0, "height": 32, "position": [1, 2, 3], "rotation": [[1,0,0],[0,1,0],[0,0,1]], "fx": 50, "fy": 50}]"#,
            "empty",
        ),
        (
            r#"[{"id": 0, "img_name": "a", "width": 8, "height": 32, "position": [1, 2, 3], "rotation": [[2,0,0],[0,1,0],[0,0,1]], "fx": 50, "fy": 50}]"#,
            "not a rotation",
        ),
        (
            r#"[{"id": 0, "img_name": "a", "width": 8, "height": 32, "position": [1, 2, 3], "rotation": [[1,0,0],[0,1,0],[0,0,1]], "fx": -5, "fy": 50}]"#,
            "focal",
        ),
    ];
    for (text, want) in cases {
        match parse_cameras_json(text, "bad.json") {
            Ok(_) => panic!("accepted {text}"),
            Err(e) => {
                let shown = e.to_string();
                assert!(shown.starts_with("bad.json") && shown.contains(want), "{shown:?} lacks {want:?}");
            }
        }
    }
}

fn trained_scene_path() -> Option<std::path::PathBuf> {
    let path = srug_tests::shared_data()?.join("scenes").join("trained_iter7000.ply");
    path.is_file().then_some(path)
}

#[test]
fn real_trained_scene_loads() {
    let Some(path) = trained_scene_path() else {
        eprintln!("skipped: ../shared/data/scenes/trained_iter7000.ply is absent");
        return;
    };
    let scene = read_ply(&path).unwrap();
    assert_eq!(scene.len(), 9_080);
    assert_eq!(scene.sh_degree, 3);
    assert_eq!(scene.sh.len(), 9_080 * 16 * 3);
    assert!(scene.extra_properties.is_empty(), "{:?}", scene.extra_properties);
    let normals = scene.normals.as_ref().expect("the INRIA trainer writes nx, ny, nz");
    assert!(normals.iter().all(|n| *n == [0.0; 3]), "normals are all zero in this file");
    assert!(!scene.attributes().shadeable());
    let range = |v: &mut dyn Iterator<Item = f32>| v.fold((f32::MAX, f32::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    let (lo, hi) = range(&mut scene.means.iter().flatten().copied());
    assert!((-420.0..-400.0).contains(&lo) && (995.0..1010.0).contains(&hi), "coordinates {lo}..{hi}");
    let (lo, hi) = range(&mut scene.opacity_logits.iter().copied());
    assert!((-5.5..-5.0).contains(&lo) && (3.4..3.8).contains(&hi), "opacity logits {lo}..{hi}");
    let (lo, hi) = range(&mut scene.log_scales.iter().flatten().copied());
    assert!((-5.4..-5.0).contains(&lo) && (5.4..5.8).contains(&hi), "log scales {lo}..{hi}");
    let (lo, hi) = range(&mut scene.rotations.iter().map(|q| q.iter().map(|c| c * c).sum::<f32>().sqrt()));
    assert!((0.6..0.65).contains(&lo) && (1.1..1.2).contains(&hi), "quaternion norms {lo}..{hi} (not normalized)");
    assert!(scene.summary().contains("Gaussians: 9080"));

    // Round trip of the real file through our writer is bit-exact.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("copy.ply");
    write_ply(&out, &scene, PlyFormat::BinaryLittleEndian).unwrap();
    assert!(bits_equal(&scene, &read_ply(&out).unwrap()));
}

#[test]
fn demo_city_is_deterministic_and_complete() {
    for n in [1_000usize, 12_345, 100_000] {
        let a = demo_city(&DemoOptions { seed: 11, gaussians: n, sh_degree: 2 }).unwrap();
        assert_eq!(a.scene.len(), n, "exact Gaussian count");
        let attributes = a.scene.attributes();
        assert!(
            attributes.normals
                && attributes.albedo
                && attributes.roughness
                && attributes.metallic
                && attributes.ao
                && attributes.visibility
        );
        a.scene.validate("demo").unwrap();
        let b = demo_city(&DemoOptions { seed: 11, gaussians: n, sh_degree: 2 }).unwrap();
        assert!(bits_equal(&a.scene, &b.scene), "same seed, different scene");
    }
    let c = demo_city(&DemoOptions { seed: 12, gaussians: 12_345, sh_degree: 2 }).unwrap();
    let a = demo_city(&DemoOptions { seed: 11, gaussians: 12_345, sh_degree: 2 }).unwrap();
    assert!(!bits_equal(&a.scene, &c.scene), "the seed changes the scene");
    assert!(demo_city(&DemoOptions { seed: 1, gaussians: 10, sh_degree: 0 }).is_err());
    assert!(demo_city(&DemoOptions { seed: 1, gaussians: 5_000, sh_degree: 4 }).is_err());

    // Windows: some Gaussians are metallic and smooth.
    let m = &a.scene.materials;
    let sigmoid = |x: f32| 1.0 / (1.0 + (-x).exp());
    let windows = m
        .metallic
        .as_ref()
        .unwrap()
        .iter()
        .zip(m.roughness.as_ref().unwrap())
        .filter(|(mt, r)| sigmoid(**mt) > 0.8 && sigmoid(**r) < 0.15)
        .count();
    assert!(windows > 100, "{windows} window Gaussians");
}

#[test]
fn demo_tower_is_out_of_view_and_its_shadow_in_view() {
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 100_000, sh_degree: 0 }).unwrap();
    let tower = city.offscreen_tower;
    assert!(tower.max.z - tower.min.z >= 60.0, "the tower is tall");
    let inside = |p: Vec3| (0..3).all(|a| p[a] >= tower.min[a] - 1e-3 && p[a] <= tower.max[a] + 1e-3);
    let tower_points: Vec<Vec3> =
        city.scene.means.iter().map(|m| Vec3::from_array(*m)).filter(|p| inside(*p)).collect();
    assert!(tower_points.len() > 100);
    for (i, cam) in city.cameras.iter().enumerate() {
        assert!(tower_points.iter().all(|p| !cam.sees(*p)), "camera {i} sees the tower");
        assert!(tower.corners().iter().all(|p| !cam.sees(*p)), "camera {i} sees a tower corner");
        // Visible ground in the tower's shadow: the sun ray hits the tower.
        let shadowed = city
            .scene
            .means
            .iter()
            .map(|m| Vec3::from_array(*m))
            .filter(|p| p.z < 0.2 && cam.sees(*p) && tower.hit(*p + Vec3::Z * 0.05, city.sun_direction))
            .count();
        assert!(shadowed > 200, "camera {i}: only {shadowed} visible ground Gaussians in the tower's shadow");
    }
    assert!(city.sun_direction.z > 0.0 && (city.sun_direction.length() - 1.0).abs() < 1e-5);
}

#[test]
fn pinhole_and_orthographic_projections() {
    use srug::scene::Camera;
    // Pinhole: a point on the optical axis lands on the principal point; 90° fov maps x = z to the edge.
    let cam = Camera::look_at(Vec3::ZERO, Vec3::X, Vec3::Z, 90.0, 200, 100).unwrap();
    assert!((cam.fov_x_degrees().unwrap() - 90.0).abs() < 1e-4);
    let centre = cam.project(cam.world_to_camera(Vec3::new(5.0, 0.0, 0.0)));
    assert!((centre - glam::Vec2::new(100.0, 50.0)).length() < 1e-4);
    // World +z (up) is image up (smaller v); world −y is image right (OpenCV axes).
    let up = cam.project(cam.world_to_camera(Vec3::new(5.0, 0.0, 1.0)));
    assert!(up.y < 50.0);
    let right = cam.project(cam.world_to_camera(Vec3::new(5.0, -5.0, 0.0)));
    assert!((right.x - 200.0).abs() < 1e-3, "{right}");
    assert!(cam.sees(Vec3::new(5.0, 0.0, 0.0)) && !cam.sees(Vec3::new(-5.0, 0.0, 0.0)));

    // Orthographic from the sun: parallel rays, pixels per unit from the extent.
    let sun =
        Camera::orthographic(Vec3::new(0.0, 0.0, 100.0), -Vec3::Z, Vec3::Y, 40.0, 20.0, 400, 200, 0.0, 200.0).unwrap();
    let a = sun.world_to_camera(Vec3::new(10.0, 5.0, 0.0));
    assert!((a.z - 100.0).abs() < 1e-4, "depth along the light direction: {a}");
    let pa = sun.project(a);
    let pb = sun.project(sun.world_to_camera(Vec3::new(10.0, 5.0, -50.0)));
    assert!((pa - pb).length() < 1e-4, "parallel projection ignores depth");
    assert!(
        ((pa - glam::Vec2::new(200.0, 100.0)).length() - (10.0f32.powi(2) + 5.0f32.powi(2)).sqrt() * 10.0).abs() < 1e-3
    );
    assert!(sun.fov_x_degrees().is_none());
    assert!(Camera::orthographic(Vec3::ZERO, Vec3::ZERO, Vec3::Z, 1.0, 1.0, 1, 1, 0.0, 1.0).is_err());
    assert!(Camera::look_at(Vec3::ZERO, Vec3::Z, Vec3::Z, 60.0, 10, 10).is_err(), "up parallel to view");
}

/// A binary PLY read from disk streams into the scene (one copy on the host);
/// it gives the same scene and the same errors as the in-memory reader,
/// across block boundaries (rows of a 1 MiB block) and with a trailing element.
#[test]
fn streamed_and_in_memory_ply_reads_agree() {
    let dir = tempfile::tempdir().unwrap();
    let scene = srug_tests::random_scene(20_000, 3, 4, 30.0);
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian] {
        let path = dir.path().join(format!("s_{format:?}.ply"));
        write_ply(&path, &scene, format).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let streamed = read_ply(&path).unwrap();
        assert!(bits_equal(&streamed, &read_ply_bytes(&bytes, "memory").unwrap()), "{format:?}");
        assert!(bits_equal(&streamed, &scene), "{format:?}");
        // Truncated in the middle of a row of the second block, and with one byte too many.
        for cut in [bytes.len() - 7_000_000 / 2, bytes.len() - 1] {
            let p = dir.path().join("cut.ply");
            std::fs::write(&p, &bytes[..cut]).unwrap();
            let (a, b) = (read_ply(&p).unwrap_err().to_string(), read_ply_bytes(&bytes[..cut], "x").unwrap_err());
            assert!(a.ends_with(&b.message) && a.contains("truncated"), "{a} vs {b}");
        }
        let p = dir.path().join("long.ply");
        std::fs::write(&p, [bytes.as_slice(), &[0]].concat()).unwrap();
        assert!(read_ply(&p).unwrap_err().to_string().contains("does not match the data"));
    }
    // Elements after the vertex element are ignored, streamed or not.
    let mut bytes = Vec::new();
    srug::io::encode_scene(&scene, srug::io::SceneFormat::Ply).unwrap().clone_into(&mut bytes);
    let end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap();
    bytes.splice(end..end, b"element face 1\nproperty list uchar int vertex_indices\n".iter().copied());
    bytes.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    let p = dir.path().join("faces.ply");
    std::fs::write(&p, &bytes).unwrap();
    assert!(bits_equal(&read_ply(&p).unwrap(), &scene));
}

/// Integer id properties read exactly in every PLY encoding: ids past 2^24
/// (which f32 would round), negative ids as their 32-bit two's complement.
#[test]
fn ply_ids_read_exactly_in_every_encoding() {
    let dir = tempfile::tempdir().unwrap();
    let names = [
        "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1",
        "rot_2", "rot_3",
    ];
    let ids: [(i32, u16); 3] = [(16_777_217, 7), (-1, 65_535), (0, 0)];
    let header = |format: &str| {
        let mut h = format!("ply\nformat {format} 1.0\nelement vertex 3\n");
        for n in names {
            h += &format!("property float {n}\n");
        }
        h + "property int semantic\nproperty ushort instance\nend_header\n"
    };
    let floats = [0.0f32, 0.0, 0.0, 0.1, 0.1, 0.1, 1.0, -1.0, -1.0, -1.0, 1.0, 0.0, 0.0, 0.0];
    let mut le = header("binary_little_endian").into_bytes();
    let mut be = header("binary_big_endian").into_bytes();
    let mut ascii = header("ascii");
    for (s, i) in ids {
        for v in floats {
            le.extend_from_slice(&v.to_le_bytes());
            be.extend_from_slice(&v.to_be_bytes());
        }
        le.extend_from_slice(&s.to_le_bytes());
        le.extend_from_slice(&i.to_le_bytes());
        be.extend_from_slice(&s.to_be_bytes());
        be.extend_from_slice(&i.to_be_bytes());
        ascii += &format!("{} {s} {i}\n", floats.map(|v| v.to_string()).join(" "));
    }
    let want = vec![vec![16_777_217u32, u32::MAX, 0], vec![7u32, 65_535, 0]];
    for (name, bytes) in [("le.ply", le), ("be.ply", be), ("ascii.ply", ascii.into_bytes())] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let got = srug::io::read_ply_ids(&path, &["semantic".into(), "instance".into()]).unwrap();
        assert_eq!(got, want, "{name}");
        assert_eq!(read_ply(&path).unwrap().extra_properties, ["semantic", "instance"], "{name}");
    }
}

#[test]
fn core_bounds_leave_far_floaters_out() {
    let mut scene = srug_tests::random_scene(1000, 0, 3, 1.0);
    let inner = scene.bounds().unwrap();
    for (i, p) in [[1e4, 0.0, 0.0], [0.0, -1e4, 0.0], [0.0, 0.0, 5e3]].into_iter().enumerate() {
        scene.means[i] = p;
    }
    let all = scene.bounds().unwrap();
    assert!(all.max[0] >= 1e4 && all.min[1] <= -1e4);
    let core = scene.core_bounds(0.005).unwrap();
    for a in 0..3 {
        assert!(core.min[a] >= inner.min[a] - 1e-6 && core.max[a] <= inner.max[a] + 1e-6, "{core:?} vs {inner:?}");
        assert!(core.max[a] - core.min[a] > 0.5 * (inner.max[a] - inner.min[a]), "{core:?}");
    }
    // No tail: the plain bounds; a tail of a half or more, or an empty scene: none.
    assert_eq!(scene.core_bounds(0.0), Some(all));
    assert_eq!(scene.core_bounds(0.5), None);
    assert_eq!(srug::scene::Scene::default().core_bounds(0.01), None);
}
