//! Cameras: pinhole and orthographic projections, and INRIA `cameras.json`.
//!
//! Conventions (NOTES.md §3): camera axes are OpenCV's (x right, y down,
//! z forward); `rotation` is camera-to-world (its columns are the camera axes in
//! world space) and `position` the camera centre; pixel centres are at +0.5.

use std::path::Path;

use glam::{Mat3, Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::SceneError;
use crate::error::{Error, Result};

/// How camera space maps to pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Perspective: u = fx·x/z + cx, v = fy·y/z + cy.
    Pinhole {
        /// Focal length in pixels, x.
        fx: f32,
        /// Focal length in pixels, y.
        fy: f32,
        /// Principal point, x.
        cx: f32,
        /// Principal point, y.
        cy: f32,
    },
    /// Parallel: u = sx·x + cx, v = sy·y + cy (the sun's shadow-map camera).
    Orthographic {
        /// Pixels per world unit, x.
        sx: f32,
        /// Pixels per world unit, y.
        sy: f32,
        /// Pixel of the optical axis, x.
        cx: f32,
        /// Pixel of the optical axis, y.
        cy: f32,
    },
}

/// A camera: pose, image size and projection.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Name (the image name in cameras.json).
    pub name: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Camera-to-world rotation.
    pub rotation: Mat3,
    /// Camera centre in world space.
    pub position: Vec3,
    /// Projection.
    pub projection: Projection,
    /// Near plane distance (camera z).
    pub near: f32,
    /// Far plane distance (camera z).
    pub far: f32,
}

/// Default near plane (gsplat's; INRIA uses 0.2).
pub const DEFAULT_NEAR: f32 = 0.01;
/// Default far plane.
pub const DEFAULT_FAR: f32 = 1.0e4;

impl Camera {
    /// A pinhole camera at `eye` looking at `target`, with `up` roughly up in
    /// the image and `fov_x_degrees` horizontal field of view.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_x_degrees: f32, width: u32, height: u32) -> Result<Self> {
        let rotation = look_rotation(eye, target, up)?;
        if !(fov_x_degrees > 0.0 && fov_x_degrees < 180.0) || width == 0 || height == 0 {
            return Err(Error::InvalidArgument(format!(
                "fov {fov_x_degrees}° / size {width}x{height} is not a camera"
            )));
        }
        let fx = width as f32 * 0.5 / (fov_x_degrees.to_radians() * 0.5).tan();
        Ok(Self {
            name: String::new(),
            width,
            height,
            rotation,
            position: eye,
            projection: Projection::Pinhole { fx, fy: fx, cx: width as f32 * 0.5, cy: height as f32 * 0.5 },
            near: DEFAULT_NEAR,
            far: DEFAULT_FAR,
        })
    }

    /// An orthographic camera at `eye` looking along `direction`, covering
    /// `extent_x` × `extent_y` world units with a `width` × `height` image
    /// (the sun's shadow-map camera). Depth runs from `near` to `far` along `direction`.
    #[allow(clippy::too_many_arguments, reason = "a camera is defined by this many independent quantities")]
    pub fn orthographic(
        eye: Vec3,
        direction: Vec3,
        up: Vec3,
        extent_x: f32,
        extent_y: f32,
        width: u32,
        height: u32,
        near: f32,
        far: f32,
    ) -> Result<Self> {
        let rotation = look_rotation(eye, eye + direction, up)?;
        let valid = extent_x > 0.0 && extent_y > 0.0 && extent_x.is_finite() && extent_y.is_finite() && near < far;
        if !valid || width == 0 || height == 0 {
            return Err(Error::InvalidArgument(format!(
                "orthographic extent {extent_x}x{extent_y}, size {width}x{height}, depth {near}..{far} is not a camera"
            )));
        }
        Ok(Self {
            name: String::new(),
            width,
            height,
            rotation,
            position: eye,
            projection: Projection::Orthographic {
                sx: width as f32 / extent_x,
                sy: height as f32 / extent_y,
                cx: width as f32 * 0.5,
                cy: height as f32 * 0.5,
            },
            near,
            far,
        })
    }

    /// The same camera with its image resized to `width`×`height` (intrinsics scaled).
    pub fn resized(&self, width: u32, height: u32) -> Self {
        let (kx, ky) = (width as f32 / self.width as f32, height as f32 / self.height as f32);
        let projection = match self.projection {
            Projection::Pinhole { fx, fy, cx, cy } => {
                Projection::Pinhole { fx: fx * kx, fy: fy * ky, cx: cx * kx, cy: cy * ky }
            }
            Projection::Orthographic { sx, sy, cx, cy } => {
                Projection::Orthographic { sx: sx * kx, sy: sy * ky, cx: cx * kx, cy: cy * ky }
            }
        };
        Self { width, height, projection, ..self.clone() }
    }

    /// World to camera coordinates.
    pub fn world_to_camera(&self, p: Vec3) -> Vec3 {
        self.rotation.transpose() * (p - self.position)
    }

    /// Camera coordinates to pixel coordinates (no clipping).
    pub fn project(&self, p: Vec3) -> Vec2 {
        match self.projection {
            Projection::Pinhole { fx, fy, cx, cy } => Vec2::new(fx * p.x / p.z + cx, fy * p.y / p.z + cy),
            Projection::Orthographic { sx, sy, cx, cy } => Vec2::new(sx * p.x + cx, sy * p.y + cy),
        }
    }

    /// Horizontal field of view in degrees (pinhole only).
    pub fn fov_x_degrees(&self) -> Option<f32> {
        match self.projection {
            Projection::Pinhole { fx, .. } => Some((2.0 * (self.width as f32 * 0.5 / fx).atan()).to_degrees()),
            Projection::Orthographic { .. } => None,
        }
    }

    /// Whether a world point projects inside the image and in front of the camera.
    pub fn sees(&self, p: Vec3) -> bool {
        let c = self.world_to_camera(p);
        if c.z <= self.near || c.z >= self.far {
            return false;
        }
        let px = self.project(c);
        px.x >= 0.0 && px.y >= 0.0 && px.x < self.width as f32 && px.y < self.height as f32
    }
}

/// Camera-to-world rotation for OpenCV axes looking from `eye` at `target`.
pub fn look_rotation(eye: Vec3, target: Vec3, up: Vec3) -> Result<Mat3> {
    let forward = (target - eye).normalize_or_zero();
    let right = forward.cross(up).normalize_or_zero();
    if forward == Vec3::ZERO || right == Vec3::ZERO || !forward.is_finite() {
        return Err(Error::InvalidArgument(format!("look-at from {eye} to {target} with up {up} is degenerate")));
    }
    let down = forward.cross(right);
    Ok(Mat3::from_cols(right, down, forward))
}

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

/// Reads an INRIA `cameras.json`.
pub fn read_cameras_json(path: impl AsRef<Path>) -> Result<Vec<Camera>> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(Error::io(path))?;
    Ok(parse_cameras_json(&text, &path.display().to_string())?)
}

/// Parses INRIA `cameras.json` text; `origin` names it in errors.
pub fn parse_cameras_json(text: &str, origin: &str) -> Result<Vec<Camera>, SceneError> {
    let entries: Vec<JsonCamera> =
        serde_json::from_str(text).map_err(|e| SceneError::file(origin, format!("malformed cameras.json: {e}")))?;
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
    Ok(Camera {
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
    })
}

/// Writes pinhole cameras as INRIA `cameras.json` (orthographic ones are refused).
pub fn write_cameras_json(path: impl AsRef<Path>, cameras: &[Camera]) -> Result<()> {
    let path = path.as_ref();
    let mut entries = Vec::with_capacity(cameras.len());
    for (i, c) in cameras.iter().enumerate() {
        let Projection::Pinhole { fx, fy, .. } = c.projection else {
            return Err(Error::InvalidArgument(format!(
                "camera {i} is orthographic; cameras.json holds pinhole cameras"
            )));
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
    let text = serde_json::to_string_pretty(&entries).map_err(|e| Error::InvalidArgument(e.to_string()))?;
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, text).map_err(Error::io(&tmp))?;
    std::fs::rename(&tmp, path).map_err(Error::io(path))
}
