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

use crate::scene::{sh_coefficients, Scene, SceneError};

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
    let mut scene = super::decoding_scene(n, degree);
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

/// Palette entries for the higher SH bands: splat-transform's size rule
/// (1024 × a power of two up to 64, by count) capped at 4096, which keeps the
/// k-means a CPU can run in seconds for a million Gaussians.
fn palette_size(n: usize) -> usize {
    let steps = (n as f64 / 1024.0).log2().floor();
    let size = (2f64.powf(steps).min(64.0) * 1024.0) as usize;
    size.clamp(1, 4096).min(n.max(1))
}

/// A 256-entry codebook for `values` (1D k-means from quantile starts, a few
/// Lloyd steps on the sorted values) and each value's index in it.
fn codebook_1d(values: &[f32]) -> (Vec<f64>, Vec<u8>) {
    let mut sorted: Vec<f32> = values.to_vec();
    sorted.sort_by(f32::total_cmp);
    let n = sorted.len().max(1);
    let mut centres: Vec<f64> = (0..256).map(|i| f64::from(sorted[((2 * i + 1) * n / 512).min(n - 1)])).collect();
    for _ in 0..8 {
        centres.sort_by(f64::total_cmp);
        let mut sum = vec![0.0f64; 256];
        let mut count = vec![0usize; 256];
        let mut c = 0;
        for &v in &sorted {
            let v = f64::from(v);
            while c + 1 < 256 && (centres[c + 1] - v).abs() <= (centres[c] - v).abs() {
                c += 1;
            }
            sum[c] += v;
            count[c] += 1;
        }
        for i in 0..256 {
            if count[i] > 0 {
                centres[i] = sum[i] / count[i] as f64;
            }
        }
    }
    centres.sort_by(f64::total_cmp);
    // Stored as f32 in the JSON reader's f64: round now so the labels pick the nearest stored value.
    let centres: Vec<f64> = centres.iter().map(|c| f64::from(*c as f32)).collect();
    let labels = values
        .iter()
        .map(|&v| {
            let v = f64::from(v);
            let i = centres.partition_point(|c| *c < v);
            let best = [i.saturating_sub(1), i.min(255)]
                .into_iter()
                .min_by(|&a, &b| (centres[a] - v).abs().total_cmp(&(centres[b] - v).abs()))
                .unwrap_or(0);
            best as u8
        })
        .collect();
    (centres, labels)
}

/// The nearest of `centroids` (rows of `dim`) to each row of `points`, on all cores.
fn assign(points: &[f32], dim: usize, centroids: &[f32], labels: &mut [u16]) {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let rows_per = (labels.len().div_ceil(threads)).max(1);
    std::thread::scope(|scope| {
        for (chunk, out) in points.chunks(rows_per * dim).zip(labels.chunks_mut(rows_per)) {
            scope.spawn(move || {
                for (p, label) in chunk.chunks_exact(dim).zip(out.iter_mut()) {
                    let mut best = (f32::INFINITY, 0);
                    for (c, centre) in centroids.chunks_exact(dim).enumerate() {
                        let mut d = 0.0f32;
                        for (a, b) in p.iter().zip(centre) {
                            d += (a - b) * (a - b);
                        }
                        if d < best.0 {
                            best = (d, c);
                        }
                    }
                    *label = best.1 as u16;
                }
            });
        }
    });
}

/// k-means of `points` (rows of `dim` floats) into `k` centroids: starts
/// spread over the rows, Lloyd steps on at most 32768 rows spread over the
/// scene, then every row labelled with its nearest centroid.
fn kmeans(points: &[f32], dim: usize, k: usize, steps: usize) -> (Vec<f32>, Vec<u16>) {
    let n = points.len() / dim;
    let sample_rows = n.min(32768);
    let sample: Vec<f32> = (0..sample_rows)
        .flat_map(|i| points[(i * n / sample_rows) * dim..(i * n / sample_rows + 1) * dim].to_vec())
        .collect();
    let mut centroids: Vec<f32> =
        (0..k).flat_map(|i| sample[(i * sample_rows / k) * dim..(i * sample_rows / k + 1) * dim].to_vec()).collect();
    let mut labels = vec![0u16; sample_rows];
    for _ in 0..steps {
        assign(&sample, dim, &centroids, &mut labels);
        let mut sum = vec![0.0f64; k * dim];
        let mut count = vec![0usize; k];
        for (p, &l) in sample.chunks_exact(dim).zip(&labels) {
            count[l as usize] += 1;
            for (s, v) in sum[l as usize * dim..(l as usize + 1) * dim].iter_mut().zip(p) {
                *s += f64::from(*v);
            }
        }
        for c in 0..k {
            if count[c] > 0 {
                for j in 0..dim {
                    centroids[c * dim + j] = (sum[c * dim + j] / count[c] as f64) as f32;
                }
            }
        }
    }
    let mut all = vec![0u16; n];
    assign(points, dim, &centroids, &mut all);
    (centroids, all)
}

fn encode_webp(rgba: &[u8], width: usize, height: usize) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::webp::WebPEncoder::new_lossless(&mut out)
        .write_image(rgba, width as u32, height as u32, image::ExtendedColorType::Rgba8)
        .map_err(|e| format!("WebP encoding failed: {e}"))?;
    Ok(out)
}

/// Encodes a scene as a bundled SOG version 2 (a ZIP of `meta.json` and
/// lossless WebP images), laid out as splat-transform lays it out: Gaussians
/// in Morton order, images `ceil(√n / 4)·4` wide. Scales and DC colours go
/// through 256-entry codebooks, the higher SH bands through a palette of at
/// most 4096 centroids (k-means) whose values share a codebook.
pub(crate) fn encode(scene: &Scene) -> Result<Vec<u8>, String> {
    let n = scene.len();
    if n == 0 {
        return Err("an empty scene cannot be written as SOG".into());
    }
    let k = sh_coefficients(scene.sh_degree);
    let order = super::compressed_ply::morton_order(scene);
    let width = (((n as f64).sqrt() / 4.0).ceil() as usize * 4).max(4);
    let height = (n.div_ceil(width).div_ceil(4) * 4).max(4);
    let texels = width * height * 4;
    let log_transform = |v: f64| v.signum() * (v.abs() + 1.0).ln();
    // Means.
    let mut mins = [f64::INFINITY; 3];
    let mut maxs = [f64::NEG_INFINITY; 3];
    for p in &scene.means {
        for a in 0..3 {
            let v = log_transform(f64::from(p[a]));
            mins[a] = mins[a].min(v);
            maxs[a] = maxs[a].max(v);
        }
    }
    let (mut lo, mut hi) = (vec![0u8; texels], vec![0u8; texels]);
    let mut quats = vec![0u8; texels];
    for (t, &g) in order.iter().enumerate() {
        for a in 0..3 {
            let range = maxs[a] - mins[a];
            let q = if range > 0.0 {
                (65535.0 * (log_transform(f64::from(scene.means[g][a])) - mins[a]) / range) as u32
            } else {
                0
            };
            lo[t * 4 + a] = (q & 0xff) as u8;
            hi[t * 4 + a] = ((q >> 8) & 0xff) as u8;
        }
        lo[t * 4 + 3] = 255;
        hi[t * 4 + 3] = 255;
        let q = scene.rotations[g].map(f64::from);
        let len = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut q = q.map(|v| v / len);
        let largest = (0..4).fold(0, |m, i| if q[i].abs() > q[m].abs() { i } else { m });
        if q[largest] < 0.0 {
            q = q.map(|v| -v);
        }
        let others: [usize; 3] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]][largest];
        for (j, &i) in others.iter().enumerate() {
            quats[t * 4 + j] = (255.0 * (q[i] * std::f64::consts::SQRT_2 * 0.5 + 0.5)).clamp(0.0, 255.0) as u8;
        }
        quats[t * 4 + 3] = 252 + largest as u8;
    }
    // Scales and DC colours through codebooks; opacity as a byte.
    let scale_values: Vec<f32> = scene.log_scales.iter().flatten().copied().collect();
    let (scale_code, scale_labels) = codebook_1d(&scale_values);
    let dc_values: Vec<f32> = (0..n).flat_map(|g| scene.sh[g * k * 3..g * k * 3 + 3].to_vec()).collect();
    let (dc_code, dc_labels) = codebook_1d(&dc_values);
    let (mut scales, mut sh0) = (vec![0u8; texels], vec![0u8; texels]);
    for (t, &g) in order.iter().enumerate() {
        for a in 0..3 {
            scales[t * 4 + a] = scale_labels[g * 3 + a];
            sh0[t * 4 + a] = dc_labels[g * 3 + a];
        }
        scales[t * 4 + 3] = 255;
        let alpha = 1.0 / (1.0 + (-f64::from(scene.opacity_logits[g])).exp());
        sh0[t * 4 + 3] = (alpha * 255.0).clamp(0.0, 255.0) as u8;
    }
    let mut files: Vec<(String, Vec<u8>)> = vec![
        ("means_l.webp".into(), encode_webp(&lo, width, height)?),
        ("means_u.webp".into(), encode_webp(&hi, width, height)?),
        ("quats.webp".into(), encode_webp(&quats, width, height)?),
        ("scales.webp".into(), encode_webp(&scales, width, height)?),
        ("sh0.webp".into(), encode_webp(&sh0, width, height)?),
    ];
    let mut meta = serde_json::json!({
        "version": 2,
        "asset": {"generator": "srug"},
        "count": n,
        "means": {"mins": mins, "maxs": maxs, "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"codebook": scale_code, "files": ["scales.webp"]},
        "quats": {"files": ["quats.webp"]},
        "sh0": {"codebook": dc_code, "files": ["sh0.webp"]},
    });
    if scene.sh_degree > 0 {
        // Rows in the decoder's f_rest order: channel-major, coefficient inside.
        let coeffs = k - 1;
        let dim = 3 * coeffs;
        let rows: Vec<f32> = (0..n)
            .flat_map(|g| (0..dim).map(move |j| (g, j)))
            .map(|(g, j)| scene.sh[(g * k + j % coeffs + 1) * 3 + j / coeffs])
            .collect();
        let palette = palette_size(n);
        let (centroids, labels) = kmeans(&rows, dim, palette, 6);
        let (code, centroid_labels) = codebook_1d(&centroids);
        let (cw, ch) = (64 * coeffs, palette.div_ceil(64));
        let mut cimg = vec![0u8; cw * ch * 4];
        for c in 0..palette {
            for j in 0..coeffs {
                let t = ((c / 64) * cw + (c % 64) * coeffs + j) * 4;
                for channel in 0..3 {
                    cimg[t + channel] = centroid_labels[c * dim + channel * coeffs + j];
                }
                cimg[t + 3] = 255;
            }
        }
        let mut limg = vec![0u8; texels];
        for (t, &g) in order.iter().enumerate() {
            limg[t * 4] = (labels[g] & 0xff) as u8;
            limg[t * 4 + 1] = (labels[g] >> 8) as u8;
            limg[t * 4 + 3] = 255;
        }
        files.push(("shN_centroids.webp".into(), encode_webp(&cimg, cw, ch)?));
        files.push(("shN_labels.webp".into(), encode_webp(&limg, width, height)?));
        meta["shN"] = serde_json::json!({
            "count": palette, "bands": scene.sh_degree, "codebook": code,
            "files": ["shN_centroids.webp", "shN_labels.webp"],
        });
    }
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    let text = serde_json::to_vec(&meta).map_err(|e| e.to_string())?;
    files.insert(0, ("meta.json".into(), text));
    for (name, bytes) in &files {
        use std::io::Write;
        zip.start_file(name.as_str(), options).map_err(|e| format!("ZIP: {e}"))?;
        zip.write_all(bytes).map_err(|e| format!("ZIP: {e}"))?;
    }
    Ok(zip.finish().map_err(|e| format!("ZIP: {e}"))?.into_inner())
}
