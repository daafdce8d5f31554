//! PlayCanvas SOG (version 2): a `meta.json` and lossless WebP images, either
//! bundled in a ZIP (`.sog`) or side by side (`meta.json` + `*.webp`).
//!
//! Each Gaussian is one texel of every image: positions as 16-bit values
//! (two images, low and high bytes) within per-axis bounds of
//! `sign(x)·ln(|x| + 1)`; rotations as the three smallest quaternion
//! components (×√2, in bytes) plus the largest's index in alpha (252 + i);
//! log scales and DC colours as indices into 256-entry codebooks, opacity as
//! a byte; higher SH bands as a 16-bit label into a palette of centroids
//! whose bytes index a shared codebook. Decoding follows splat-transform's
//! `readSog` formula by formula in f64 and rounds once to f32. The frame is
//! the PLY's.

use serde_json::Value;

use crate::scene::{sh_coefficients, Materials, Scene, SceneError};

fn err(origin: &str, field: &str, message: impl std::fmt::Display) -> SceneError {
    SceneError { path: origin.into(), row: None, property: Some(field.into()), message: format!("SOG: {message}") }
}

/// A decoded RGBA8 image.
struct Rgba {
    width: usize,
    height: usize,
    texels: Vec<u8>,
}

fn decode_webp(bytes: &[u8], name: &str, origin: &str) -> Result<Rgba, SceneError> {
    let bad = |m: String| err(origin, name, m);
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::WebP);
    let l = crate::io::limits();
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(l.max_image_side);
    limits.max_image_height = Some(l.max_image_side);
    limits.max_alloc = Some(l.max_decoded_bytes);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| bad(format!("cannot decode the WebP image: {e}")))?;
    let rgba = img.to_rgba8();
    Ok(Rgba { width: rgba.width() as usize, height: rgba.height() as usize, texels: rgba.into_raw() })
}

/// Reads a SOG whose files `load` returns by name (the bundle's entries or the folder's files).
pub(crate) fn read_with(
    meta: &[u8],
    load: &mut dyn FnMut(&str) -> Result<Vec<u8>, SceneError>,
    origin: &str,
) -> Result<Scene, SceneError> {
    let meta: Value =
        serde_json::from_slice(meta).map_err(|e| err(origin, "meta.json", format!("is not valid JSON: {e}")))?;
    match meta["version"].as_u64() {
        Some(2) => {}
        None => {
            return Err(err(
                origin,
                "meta.json version",
                "version 1 (legacy, no version field) is not supported; re-export it with splat-transform",
            ))
        }
        Some(v) => return Err(err(origin, "meta.json version", format!("version {v} is not one srug reads (2)"))),
    }
    let declared = meta["count"].as_u64().ok_or_else(|| err(origin, "count", "missing"))?;
    let n = crate::io::limits().gaussians(declared).map_err(|why| err(origin, "count", why))?;
    let file = |section: &str, i: usize| -> Result<String, SceneError> {
        meta[section]["files"][i]
            .as_str()
            .map(String::from)
            .ok_or_else(|| err(origin, &format!("{section}.files"), "missing"))
    };
    let floats = |v: &Value, field: &str, len: usize| -> Result<Vec<f64>, SceneError> {
        let a: Vec<f64> = v.as_array().into_iter().flatten().filter_map(Value::as_f64).collect();
        if a.len() != len {
            return Err(err(origin, field, format!("{} numbers, expected {len}", a.len())));
        }
        Ok(a)
    };
    let mut image = |section: &str, i: usize| -> Result<Rgba, SceneError> {
        let name = file(section, i)?;
        let img = decode_webp(&load(&name)?, &name, origin)?;
        if img.width * img.height < n {
            return Err(err(
                origin,
                &name,
                format!("{}x{} texels hold fewer than the {n} Gaussians", img.width, img.height),
            ));
        }
        Ok(img)
    };
    let mins = floats(&meta["means"]["mins"], "means.mins", 3)?;
    let maxs = floats(&meta["means"]["maxs"], "means.maxs", 3)?;
    let lo = image("means", 0)?;
    let hi = image("means", 1)?;
    let quats = image("quats", 0)?;
    let scales = image("scales", 0)?;
    let sh0 = image("sh0", 0)?;
    let scale_code = floats(&meta["scales"]["codebook"], "scales.codebook", 256)?;
    let colour_code = floats(&meta["sh0"]["codebook"], "sh0.codebook", 256)?;
    let bands =
        if meta.get("shN").is_some_and(|v| !v.is_null()) { meta["shN"]["bands"].as_u64().unwrap_or(0) } else { 0 };
    if bands > 3 {
        return Err(err(origin, "shN.bands", format!("{bands} bands (0 to 3)")));
    }
    let degree = bands as u32;
    let k = sh_coefficients(degree);
    let inv_log = |v: f64| {
        let e = v.abs().exp() - 1.0;
        if v < 0.0 {
            -e
        } else {
            e
        }
    };
    let mut scene = Scene {
        means: Vec::with_capacity(n),
        normals: None,
        sh_degree: degree,
        sh: vec![0.0; n * k * 3],
        opacity_logits: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
        materials: Materials::default(),
        extra_properties: Vec::new(),
    };
    for i in 0..n {
        let o = i * 4;
        scene.means.push([0, 1, 2].map(|a| {
            let v = u16::from(lo.texels[o + a]) | u16::from(hi.texels[o + a]) << 8;
            let range = if maxs[a] - mins[a] != 0.0 { maxs[a] - mins[a] } else { 1.0 };
            inv_log(mins[a] + range * (f64::from(v) / 65535.0)) as f32
        }));
        let tag = quats.texels[o + 3];
        let q = if (252..=255).contains(&tag) {
            let largest = usize::from(tag - 252);
            let others: [usize; 3] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]][largest];
            let mut c = [0.0f64; 4];
            for (j, &idx) in others.iter().enumerate() {
                c[idx] = (f64::from(quats.texels[o + j]) / 255.0 * 2.0 - 1.0) / std::f64::consts::SQRT_2;
            }
            c[largest] = (1.0 - (c[0] * c[0] + c[1] * c[1] + c[2] * c[2] + c[3] * c[3])).max(0.0).sqrt();
            c
        } else {
            return Err(SceneError::at(
                origin,
                i,
                "quats",
                format!("SOG: texel alpha {tag} is not a largest-component tag (252 to 255)"),
            ));
        };
        scene.rotations.push(q.map(|v| v as f32));
        scene.log_scales.push([0, 1, 2].map(|a| scale_code[usize::from(scales.texels[o + a])] as f32));
        for a in 0..3 {
            scene.sh[i * k * 3 + a] = colour_code[usize::from(sh0.texels[o + a])] as f32;
        }
        let p = (f64::from(sh0.texels[o + 3]) / 255.0).clamp(1e-6, 1.0 - 1e-6);
        scene.opacity_logits.push((p / (1.0 - p)).ln() as f32);
    }
    if degree > 0 {
        let coeffs = k - 1;
        let palette = meta["shN"]["count"].as_u64().ok_or_else(|| err(origin, "shN.count", "missing"))? as usize;
        let code = floats(&meta["shN"]["codebook"], "shN.codebook", 256)?;
        let labels = image("shN", 1)?;
        let centroids = decode_webp(&load(&file("shN", 0)?)?, "shN centroids", origin)?;
        if centroids.width != 64 * coeffs {
            return Err(err(origin, "shN centroids", format!("width {} is not 64 × {coeffs}", centroids.width)));
        }
        for i in 0..n {
            let label = usize::from(labels.texels[i * 4]) | usize::from(labels.texels[i * 4 + 1]) << 8;
            if label >= palette {
                return Err(SceneError::at(
                    origin,
                    i,
                    "shN labels",
                    format!("SOG: label {label} is outside the {palette}-entry palette"),
                ));
            }
            for j in 0..coeffs {
                let (cx, cy) = ((label % 64) * coeffs + j, label / 64);
                if cy >= centroids.height {
                    return Err(SceneError::at(
                        origin,
                        i,
                        "shN centroids",
                        format!("SOG: label {label} lies below the centroid image"),
                    ));
                }
                let t = (cy * centroids.width + cx) * 4;
                for c in 0..3 {
                    scene.sh[(i * k + j + 1) * 3 + c] = code[usize::from(centroids.texels[t + c])] as f32;
                }
            }
        }
    }
    scene.validate(origin)?;
    Ok(scene)
}

/// Reads a bundled `.sog` (a ZIP holding `meta.json` and the images).
pub(crate) fn read_bundle(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    let zip_err = |e: zip::result::ZipError| err(origin, "zip", format!("not a readable ZIP bundle: {e}"));
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(zip_err)?;
    let max = crate::io::limits().max_decoded_bytes;
    let mut entry = |name: &str| -> Result<Vec<u8>, SceneError> {
        use std::io::Read;
        let mut f = archive.by_name(name).map_err(|e| err(origin, name, format!("missing from the bundle: {e}")))?;
        if f.size() > max {
            return Err(err(origin, name, format!("declares {} bytes, more than the decode limit", f.size())));
        }
        let mut out = Vec::with_capacity((f.size() as usize).min(bytes.len().saturating_mul(4)));
        f.by_ref()
            .take(max + 1)
            .read_to_end(&mut out)
            .map_err(|e| err(origin, name, format!("cannot be read: {e}")))?;
        Ok(out)
    };
    let meta = entry("meta.json")?;
    read_with(&meta, &mut entry, origin)
}
