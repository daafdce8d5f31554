//! nerfstudio and instant-ngp `transforms.json`.
//!
//! Intrinsics are shared at the top level (`fl_x`, `fl_y`, `cx`, `cy`, `w`,
//! `h`, or instant-ngp's `camera_angle_x`/`camera_angle_y`) and may be
//! overridden per frame; `camera_model` (PINHOLE, OPENCV, OPENCV_FISHEYE,
//! EQUIRECTANGULAR) and the distortion fields (`k1`..`k4`, `p1`, `p2`) name
//! the lens. nerfstudio's equirectangular focal lengths are in half-turns
//! (longitude π·(x − cx)/fl_x, latitude π·(y − cy)/fl_y, so fl_x = w / 2 for a
//! full panorama): srug's are those divided by π. Each frame's `transform_matrix` is
//! camera-to-world in OpenGL axes (x right, y up, z back), turned here into
//! srug's OpenCV axes by negating the y and z columns. Poses are taken as the
//! file gives them; nerfstudio's `applied_transform` (the change it made from
//! the COLMAP world) is reported, not undone. Frames come out in file order,
//! named by `file_path`.

use std::path::Path;

use glam::{Mat3, Vec3};
use serde_json::Value;

use crate::camera::lens::Lens;
use crate::camera::{Camera, Projection, DEFAULT_FAR, DEFAULT_NEAR};
use crate::error::Result;
use crate::scene::SceneError;

fn err(origin: &str, row: Option<usize>, field: &str, message: impl std::fmt::Display) -> SceneError {
    SceneError {
        path: origin.into(),
        row,
        property: Some(field.into()),
        message: format!("transforms.json: {message}"),
    }
}

/// Whether `text` looks like a transforms.json (a JSON object with `frames`).
pub(crate) fn looks_like(text: &str) -> bool {
    text.trim_start().starts_with('{') && text.contains("\"frames\"")
}

/// Reads a `transforms.json`.
pub fn read_transforms_json(path: impl AsRef<Path>) -> Result<Vec<Camera>> {
    let path = path.as_ref();
    Ok(parse_transforms_json(&super::read_text(path)?, &path.display().to_string())?)
}

/// Parses `transforms.json` text; `origin` names it in errors.
pub fn parse_transforms_json(text: &str, origin: &str) -> Result<Vec<Camera>, SceneError> {
    let root: Value =
        serde_json::from_str(text).map_err(|e| err(origin, None, "JSON", format!("is not valid JSON: {e}")))?;
    let frames = root["frames"].as_array().ok_or_else(|| err(origin, None, "frames", "missing or not a list"))?;
    if frames.is_empty() {
        return Err(err(origin, None, "frames", "lists no frame"));
    }
    if root.get("applied_transform").is_some() {
        log::info!(
            "{origin}: poses are in nerfstudio's world (applied_transform present); a scene trained on the \
             COLMAP model matches that model's cameras instead"
        );
    }
    frames.iter().enumerate().map(|(i, f)| frame(&root, f, i, origin)).collect()
}

fn frame(root: &Value, f: &Value, i: usize, origin: &str) -> Result<Camera, SceneError> {
    let bad = |field: &str, m: String| err(origin, Some(i), field, m);
    // A per-frame value overrides the shared one.
    let get = |key: &str| f.get(key).or_else(|| root.get(key)).and_then(Value::as_f64);
    let w = get("w").ok_or_else(|| bad("w", "image width missing".into()))?;
    let h = get("h").ok_or_else(|| bad("h", "image height missing".into()))?;
    if !(w >= 1.0
        && h >= 1.0
        && w.fract() == 0.0
        && h.fract() == 0.0
        && w <= f64::from(u32::MAX)
        && h <= f64::from(u32::MAX))
    {
        return Err(bad("w/h", format!("image size {w}x{h} is not a positive whole number of pixels")));
    }
    let fov = |angle: Option<f64>, size: f64| angle.map(|a| 0.5 * size / (0.5 * a).tan());
    let fx = get("fl_x").or_else(|| fov(get("camera_angle_x"), w));
    let fy = get("fl_y").or_else(|| fov(get("camera_angle_y"), h)).or(fx);
    let (Some(fx), Some(fy)) = (fx, fy) else {
        return Err(bad("fl_x", "no focal length (fl_x/fl_y or camera_angle_x)".into()));
    };
    if !(fx.is_finite() && fx > 0.0 && fy.is_finite() && fy > 0.0) {
        return Err(bad("fl_x/fl_y", format!("focal lengths {fx} / {fy} must be finite and positive")));
    }
    let cx = get("cx").unwrap_or(w * 0.5);
    let cy = get("cy").unwrap_or(h * 0.5);
    let model = f.get("camera_model").or_else(|| root.get("camera_model")).and_then(Value::as_str).unwrap_or("OPENCV");
    let c = |k: &str| get(k).unwrap_or(0.0);
    let lens = match model {
        "PINHOLE" => Lens::Pinhole,
        // nerfstudio's OPENCV radial polynomial is k1..k3; a k4 there has no OpenCV meaning.
        "OPENCV" if c("k4") == 0.0 => {
            Lens::RadialTangential { k: [c("k1"), c("k2"), c("k3"), 0.0, 0.0, 0.0], p: [c("p1"), c("p2")] }
        }
        "OPENCV_FISHEYE" => Lens::Fisheye { k: [c("k1"), c("k2"), c("k3"), c("k4")] },
        "EQUIRECTANGULAR" => Lens::Equirectangular,
        other => {
            return Err(bad(
                "camera_model",
                format!(
                    "{other}{} is a lens srug does not render (it renders PINHOLE, OPENCV with k1-k3, p1, p2, \
                     OPENCV_FISHEYE and EQUIRECTANGULAR)",
                    if c("k4") != 0.0 { format!(" with k4={}", c("k4")) } else { String::new() }
                ),
            ))
        }
    };
    let lens = match lens {
        Lens::RadialTangential { k, p } if k.iter().chain(&p).all(|v| *v == 0.0) => Lens::Pinhole,
        lens => lens,
    };
    let m = f["transform_matrix"].as_array().ok_or_else(|| bad("transform_matrix", "missing".into()))?;
    let rows: Vec<Vec<f64>> =
        m.iter().map(|r| r.as_array().into_iter().flatten().filter_map(Value::as_f64).collect()).collect();
    if rows.len() < 3 || rows.iter().take(3).any(|r| r.len() != 4 || r.iter().any(|v| !v.is_finite())) {
        return Err(bad("transform_matrix", "is not a finite 3x4 or 4x4 matrix".into()));
    }
    // OpenGL camera axes (y up, z back) to OpenCV (y down, z forward): negate columns 1 and 2.
    let col = |c: usize, s: f64| Vec3::new((rows[0][c] * s) as f32, (rows[1][c] * s) as f32, (rows[2][c] * s) as f32);
    let rotation = Mat3::from_cols(col(0, 1.0), col(1, -1.0), col(2, -1.0));
    let orthonormality =
        (rotation.transpose() * rotation - Mat3::IDENTITY).to_cols_array().iter().fold(0.0f32, |m, v| m.max(v.abs()));
    if orthonormality > 1e-3 || rotation.determinant() < 0.0 {
        return Err(bad(
            "transform_matrix",
            format!(
                "its rotation is not one (|RᵀR − I| = {orthonormality:.2e}, det = {:.3}); scaled poses are not supported",
                rotation.determinant()
            ),
        ));
    }
    let (fx, fy) =
        if lens == Lens::Equirectangular { (fx / std::f64::consts::PI, fy / std::f64::consts::PI) } else { (fx, fy) };
    let camera = Camera {
        name: f["file_path"].as_str().unwrap_or("").to_string(),
        width: w as u32,
        height: h as u32,
        rotation,
        position: col(3, 1.0),
        projection: Projection::Pinhole { fx: fx as f32, fy: fy as f32, cx: cx as f32, cy: cy as f32 },
        near: DEFAULT_NEAR,
        far: DEFAULT_FAR,
        lens,
    };
    camera.validate().map_err(|e| bad("f32 values", e.to_string()))?;
    Ok(camera)
}
