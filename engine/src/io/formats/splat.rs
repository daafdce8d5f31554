//! antimatter15's `.splat`: 32 bytes per Gaussian, no header.
//!
//! Row: position (3 × f32), linear scale (3 × f32), RGBA (4 × u8: colour =
//! 0.5 + C0·dc, alpha = sigmoid(opacity)), rotation (4 × u8, w first,
//! `(q / |q|)·128 + 128`). Decoding follows the format's reference viewer
//! (antimatter15/splat `main.js`): rotation `(b − 128) / 128`, colour and
//! alpha `b / 255`. Degree-0 colour only; the frame is the PLY's.

use crate::scene::{Materials, Scene, SceneError, SH_C0};

/// Bytes per Gaussian.
pub(crate) const ROW: usize = 32;

/// The logit of a byte-coded probability `b / 255`, with 0 and 255 kept finite
/// (a probability of 1e-7 or 1 − 1e-7: sigmoid of it rounds to the same f32 as 0 or 1 within 1e-7).
pub(crate) fn byte_logit(b: u8) -> f32 {
    let p = (f64::from(b) / 255.0).clamp(1e-7, 1.0 - 1e-7);
    (p / (1.0 - p)).ln() as f32
}

/// Whether `bytes` plausibly hold `.splat` rows (the format has no magic):
/// a non-empty multiple of 32 bytes whose first rows have finite positions
/// and finite positive scales.
pub(crate) fn plausible(bytes: &[u8]) -> bool {
    if bytes.is_empty() || bytes.len() % ROW != 0 {
        return false;
    }
    bytes.chunks_exact(ROW).take(64).all(|r| {
        let f = |i: usize| f32::from_le_bytes([r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]]);
        (0..3).all(|i| f(i).is_finite() && f(i).abs() < 1e8) && (3..6).all(|i| f(i).is_finite() && f(i) > 0.0)
    })
}

/// Decodes a `.splat` file.
pub(crate) fn read(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    let err = |m: String| SceneError::file(origin, format!(".splat: {m}"));
    if bytes.is_empty() {
        return Err(err("the file is empty".into()));
    }
    if bytes.len() % ROW != 0 {
        return Err(err(format!(
            "{} bytes is not a whole number of 32-byte rows (the file is truncated or not a .splat file)",
            bytes.len()
        )));
    }
    let n = crate::io::limits().gaussians((bytes.len() / ROW) as u64).map_err(err)?;
    let mut scene = Scene {
        means: Vec::with_capacity(n),
        normals: None,
        sh_degree: 0,
        sh: Vec::with_capacity(3 * n),
        opacity_logits: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
        materials: Materials::default(),
        extra_properties: Vec::new(),
    };
    for (row, r) in bytes.chunks_exact(ROW).enumerate() {
        let f = |i: usize| f32::from_le_bytes([r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]]);
        scene.means.push([f(0), f(1), f(2)]);
        let mut log_scale = [0.0; 3];
        for (a, s) in log_scale.iter_mut().enumerate() {
            let v = f(3 + a);
            if !(v > 0.0 && v.is_finite()) {
                return Err(SceneError::at(
                    origin,
                    row,
                    ["scale_x", "scale_y", "scale_z"][a],
                    format!(".splat: linear scale {v} is not a finite positive number"),
                ));
            }
            *s = v.ln();
        }
        scene.log_scales.push(log_scale);
        for c in 0..3 {
            scene.sh.push((f32::from(r[24 + c]) / 255.0 - 0.5) / SH_C0);
        }
        scene.opacity_logits.push(byte_logit(r[27]));
        let q = [0, 1, 2, 3].map(|i| (f32::from(r[28 + i]) - 128.0) / 128.0);
        if q.iter().all(|c| *c == 0.0) {
            return Err(SceneError::at(
                origin,
                row,
                "rotation",
                ".splat: rotation bytes are all 128 (a zero quaternion)",
            ));
        }
        scene.rotations.push(q);
    }
    scene.validate(origin)?;
    Ok(scene)
}

/// Encodes a scene as `.splat` rows in the scene's order (higher SH bands and
/// relighting attributes are not stored by the format).
pub(crate) fn encode(scene: &Scene) -> Vec<u8> {
    let k = crate::scene::sh_coefficients(scene.sh_degree);
    let mut out = Vec::with_capacity(scene.len() * ROW);
    let byte = |v: f64| (v * 255.0).clamp(0.0, 255.0) as u8;
    for g in 0..scene.len() {
        for v in scene.means[g] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in scene.log_scales[g] {
            out.extend_from_slice(&v.exp().to_le_bytes());
        }
        for c in 0..3 {
            out.push(byte(0.5 + f64::from(SH_C0) * f64::from(scene.sh[g * k * 3 + c])));
        }
        out.push(byte(1.0 / (1.0 + (-f64::from(scene.opacity_logits[g])).exp())));
        let q = scene.rotations[g].map(f64::from);
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        for c in q {
            out.push((c / norm * 128.0 + 128.0).clamp(0.0, 255.0) as u8);
        }
    }
    out
}
