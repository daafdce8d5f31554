//! INRIA `cameras.json`: a list of `{id, img_name, width, height,
//! position[3], rotation[3][3], fx, fy}` (camera centre, camera-to-world
//! rotation, OpenCV axes, principal point at the image centre;
//! docs/conventions.md §3).

use std::path::Path;

use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

use crate::camera::{Camera, Projection, DEFAULT_FAR, DEFAULT_NEAR};
use crate::error::{Error, Result};
use crate::scene::SceneError;

/// One entry of INRIA's cameras.json.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct JsonCamera {
    id: i64,
    img_name: String,
    width: u32,
    height: u32,
    position: [f64; 3],
    rotation: [[f64; 3]; 3],
    fx: f64,
    fy: f64,
}

/// The camera file formats srug reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraFormat {
    /// INRIA 3DGS `cameras.json` (a JSON list).
    InriaJson,
    /// A COLMAP sparse model (`cameras`/`images`, text or binary).
    Colmap,
    /// nerfstudio / instant-ngp `transforms.json` (a JSON object with `frames`).
    TransformsJson,
}

impl CameraFormat {
    /// The format of the cameras at `path` (a COLMAP model may be given as its
    /// folder or one of its files), from the content.
    pub fn detect(path: &Path) -> Option<CameraFormat> {
        if super::colmap::is_model(path) {
            return Some(Self::Colmap);
        }
        let text = super::read_text(path).ok()?;
        if super::transforms_json::looks_like(&text) {
            Some(Self::TransformsJson)
        } else if text.trim_start().starts_with('[') {
            Some(Self::InriaJson)
        } else {
            None
        }
    }
}

/// Reads cameras in any format srug reads (INRIA `cameras.json`, a COLMAP
/// sparse model, nerfstudio/instant-ngp `transforms.json`), detected from
/// the content.
pub fn read_cameras(path: impl AsRef<Path>) -> Result<Vec<Camera>> {
    let path = path.as_ref();
    match CameraFormat::detect(path) {
        Some(CameraFormat::Colmap) => super::read_colmap(path),
        Some(CameraFormat::TransformsJson) => super::read_transforms_json(path),
        Some(CameraFormat::InriaJson) => read_cameras_json(path),
        // Let the INRIA reader word the failure (missing file, not a regular file, malformed JSON).
        None if !path.is_dir() => read_cameras_json(path),
        None => Err(Error::invalid(
            path.display().to_string(),
            "is a folder without a COLMAP model (cameras and images .txt or .bin)",
        )),
    }
}

/// Reads an INRIA `cameras.json`.
pub fn read_cameras_json(path: impl AsRef<Path>) -> Result<Vec<Camera>> {
    let path = path.as_ref();
    let text = super::read_text(path)?;
    Ok(parse_cameras_json(&text, &path.display().to_string())?)
}

/// Parses INRIA `cameras.json` text; `origin` names it in errors.
pub fn parse_cameras_json(text: &str, origin: &str) -> Result<Vec<Camera>, SceneError> {
    let entries: Vec<JsonCamera> =
        serde_json::from_str(text).map_err(|e| SceneError::file(origin, format!("malformed cameras.json: {e}")))?;
    if entries.is_empty() {
        return Err(SceneError::file(origin, "lists no camera"));
    }
    entries.iter().enumerate().map(|(i, e)| from_json(e, i, origin)).collect()
}

fn from_json(e: &JsonCamera, i: usize, origin: &str) -> Result<Camera, SceneError> {
    let bad = |field: &str, m: String| SceneError::at(origin, i, field, m);
    if e.width == 0 || e.height == 0 {
        return Err(bad("width/height", format!("image size {}x{} is empty", e.width, e.height)));
    }
    if !(e.fx.is_finite() && e.fx > 0.0 && e.fy.is_finite() && e.fy > 0.0) {
        return Err(bad("fx/fy", format!("focal lengths {} / {} must be finite and positive", e.fx, e.fy)));
    }
    if e.position.iter().any(|v| !v.is_finite()) {
        return Err(bad("position", format!("{:?} is not finite", e.position)));
    }
    let r = e.rotation;
    if r.iter().flatten().any(|v| !v.is_finite()) {
        return Err(bad("rotation", "has non-finite entries".into()));
    }
    // rows of the camera-to-world rotation
    let rotation = Mat3::from_cols(
        Vec3::new(r[0][0] as f32, r[1][0] as f32, r[2][0] as f32),
        Vec3::new(r[0][1] as f32, r[1][1] as f32, r[2][1] as f32),
        Vec3::new(r[0][2] as f32, r[1][2] as f32, r[2][2] as f32),
    );
    let orthonormality =
        (rotation.transpose() * rotation - Mat3::IDENTITY).to_cols_array().iter().fold(0.0f32, |m, v| m.max(v.abs()));
    if orthonormality > 1e-3 || rotation.determinant() < 0.0 {
        return Err(bad(
            "rotation",
            format!("is not a rotation (|RᵀR − I| = {orthonormality:.2e}, det = {:.3})", rotation.determinant()),
        ));
    }
    let camera = Camera {
        name: e.img_name.clone(),
        width: e.width,
        height: e.height,
        rotation,
        position: Vec3::new(e.position[0] as f32, e.position[1] as f32, e.position[2] as f32),
        projection: Projection::Pinhole {
            fx: e.fx as f32,
            fy: e.fy as f32,
            cx: e.width as f32 * 0.5,
            cy: e.height as f32 * 0.5,
        },
        near: DEFAULT_NEAR,
        far: DEFAULT_FAR,
        lens: crate::camera::lens::Lens::Pinhole,
    };
    // The same values in f32, as the GPU will use them.
    match camera.validate() {
        Ok(()) => Ok(camera),
        Err(Error::InvalidArgument { what, why }) => Err(bad("f32 values", format!("{what} {why}"))),
        Err(other) => Err(bad("f32 values", other.to_string())),
    }
}

/// Writes pinhole cameras as INRIA `cameras.json` (orthographic ones are refused).
pub fn write_cameras_json(path: impl AsRef<Path>, cameras: &[Camera]) -> Result<()> {
    let path = path.as_ref();
    let mut entries = Vec::with_capacity(cameras.len());
    for (i, c) in cameras.iter().enumerate() {
        let Projection::Pinhole { fx, fy, .. } = c.projection else {
            return Err(Error::invalid(format!("camera {i}"), "is orthographic; cameras.json holds pinhole cameras"));
        };
        let r = c.rotation;
        entries.push(JsonCamera {
            id: i as i64,
            img_name: c.name.clone(),
            width: c.width,
            height: c.height,
            position: c.position.to_array().map(f64::from),
            rotation: [0, 1, 2].map(|row| [0, 1, 2].map(|col| f64::from(r.col(col)[row]))),
            fx: f64::from(fx),
            fy: f64::from(fy),
        });
    }
    let text = serde_json::to_string_pretty(&entries)
        .map_err(|e| Error::Internal(format!("cannot serialize cameras: {e}")))?;
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, text).map_err(Error::io(&tmp))?;
    std::fs::rename(&tmp, path).map_err(Error::io(path))
}
