//! The compressed PLY of PlayCanvas SuperSplat and splat-transform.
//!
//! A binary little-endian PLY with a `chunk` element (per 256 Gaussians: the
//! float bounds of position, log scale and, optionally, colour), a `vertex`
//! element of four packed `uint`s (position 11-10-11 bits within the chunk's
//! bounds; rotation as the largest component's index in 2 bits and the other
//! three in 10 bits each, scaled by √2; log scale 11-10-11; colour and
//! opacity 8-8-8-8) and an optional `sh` element of `uchar` f_rest values
//! (`(b + 0.5)/256` mapped to −4..4, with 0 and 255 the ends). Decoding
//! follows splat-transform's `decompressPly` formula by formula in f64 and
//! rounds once to f32, as its Float32Array columns do.

use super::splat::byte_logit;
use crate::scene::{sh_coefficients, Scene, SceneError, SH_C0};

/// Gaussians per chunk.
const CHUNK: usize = 256;
/// The chunk element's position and log-scale bounds, in file order.
const CHUNK_BOUNDS: [&str; 12] = [
    "min_x",
    "min_y",
    "min_z",
    "max_x",
    "max_y",
    "max_z",
    "min_scale_x",
    "min_scale_y",
    "min_scale_z",
    "max_scale_x",
    "max_scale_y",
    "max_scale_z",
];
/// The chunk element's optional colour bounds.
const CHUNK_COLOURS: [&str; 6] = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"];
/// The vertex element's packed words.
const PACKED: [&str; 4] = ["packed_position", "packed_rotation", "packed_scale", "packed_color"];
const SH_C0_F64: f64 = 0.282_094_791_773_878_14;

fn err(origin: &str, field: &str, message: impl std::fmt::Display) -> SceneError {
    SceneError {
        path: origin.into(),
        row: None,
        property: Some(field.into()),
        message: format!("compressed PLY: {message}"),
    }
}

struct Element {
    name: String,
    count: usize,
    /// (name, size in bytes, type name)
    properties: Vec<(String, usize, String)>,
}

impl Element {
    fn stride(&self) -> usize {
        self.properties.iter().map(|p| p.1).sum()
    }
}

/// Whether a PLY header (text before `end_header`) is the compressed layout.
pub(crate) fn is_compressed_header(header: &str) -> bool {
    header.lines().any(|l| l.trim() == "element chunk" || l.trim().starts_with("element chunk "))
        && header.contains("packed_position")
}

fn parse_header(bytes: &[u8], origin: &str) -> Result<(Vec<Element>, usize), SceneError> {
    let end =
        bytes.windows(10).position(|w| w == b"end_header").ok_or_else(|| err(origin, "header", "no end_header"))?;
    let newline = bytes[end..]
        .iter()
        .position(|&c| c == b'\n')
        .ok_or_else(|| err(origin, "header", "end_header is not followed by a newline"))?;
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| err(origin, "header", "the header is not text"))?;
    let mut elements: Vec<Element> = Vec::new();
    for (no, line) in text.lines().enumerate() {
        let w: Vec<&str> = line.split_whitespace().collect();
        let at = |m: &str| err(origin, "header", format!("line {}: {m}: \"{}\"", no + 1, line.trim()));
        match w.as_slice() {
            ["ply"] | [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _] => {
                if *f != "binary_little_endian" {
                    return Err(at("compressed PLY must be binary_little_endian"));
                }
            }
            ["element", name, n] => {
                let n: u64 = n.parse().map_err(|_| at("bad element count"))?;
                let count = crate::io::limits().gaussians(n).map_err(|why| at(&why))?;
                elements.push(Element { name: (*name).into(), count, properties: Vec::new() });
            }
            ["property", ty, name] => {
                let size = match *ty {
                    "char" | "uchar" | "int8" | "uint8" => 1,
                    "short" | "ushort" | "int16" | "uint16" => 2,
                    "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
                    "double" | "float64" => 8,
                    _ => return Err(at("unknown property type")),
                };
                let e = elements.last_mut().ok_or_else(|| at("property before any element"))?;
                e.properties.push(((*name).into(), size, (*ty).into()));
            }
            _ => return Err(at("unrecognized header line")),
        }
    }
    Ok((elements, end + newline + 1))
}

/// Decodes a compressed PLY file.
pub(crate) fn read(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    let (elements, mut at) = parse_header(bytes, origin)?;
    let find = |name: &str| elements.iter().find(|e| e.name == name);
    let chunk = find("chunk").ok_or_else(|| err(origin, "chunk", "no chunk element"))?;
    let vertex = find("vertex").ok_or_else(|| err(origin, "vertex", "no vertex element"))?;
    let n = vertex.count;
    if chunk.count != n.div_ceil(CHUNK) {
        return Err(err(
            origin,
            "chunk",
            format!("{} chunks for {n} Gaussians, expected {}", chunk.count, n.div_ceil(CHUNK)),
        ));
    }
    // Element data, in header order, with sizes checked against the file.
    let mut data: Vec<&[u8]> = Vec::new();
    for e in &elements {
        let size = e.count.checked_mul(e.stride()).ok_or_else(|| err(origin, &e.name, "element size overflows"))?;
        let body = bytes.get(at..at + size).ok_or_else(|| {
            err(origin, &e.name, format!("the file is truncated: {} rows of {} bytes do not fit", e.count, e.stride()))
        })?;
        data.push(body);
        at += size;
    }
    if at != bytes.len() {
        return Err(err(origin, "file size", format!("{} bytes follow the last element", bytes.len() - at)));
    }
    let index = |name: &str| elements.iter().position(|e| e.name == name).unwrap_or(0);
    let column = |e: &Element, d: &[u8], name: &str, ty: &str| -> Result<Vec<[u8; 4]>, SceneError> {
        let mut off = 0;
        for (p, size, t) in &e.properties {
            if p == name {
                if t != ty && !(ty == "float" && t == "float32") && !(ty == "uint" && t == "uint32") {
                    return Err(err(origin, name, format!("is {t}, expected {ty}")));
                }
                let stride = e.stride();
                return Ok((0..e.count)
                    .map(|r| {
                        let b = &d[r * stride + off..];
                        [b[0], b[1], b[2], b[3]]
                    })
                    .collect());
            }
            off += size;
        }
        Err(err(origin, name, format!("the {} element has no {name} property", e.name)))
    };
    let (cd, vd) = (data[index("chunk")], data[index("vertex")]);
    let f = |name: &str| -> Result<Vec<f64>, SceneError> {
        Ok(column(chunk, cd, name, "float")?.into_iter().map(|b| f64::from(f32::from_le_bytes(b))).collect())
    };
    let u = |name: &str| -> Result<Vec<u32>, SceneError> {
        Ok(column(vertex, vd, name, "uint")?.into_iter().map(u32::from_le_bytes).collect())
    };
    let bounds: Vec<Vec<f64>> = CHUNK_BOUNDS.iter().map(|name| f(name)).collect::<Result<_, _>>()?;
    let colour: Option<Vec<Vec<f64>>> = if chunk.properties.iter().any(|p| p.0 == "min_r") {
        Some(CHUNK_COLOURS.iter().map(|name| f(name)).collect::<Result<_, _>>()?)
    } else {
        None
    };
    let [pp, pr, ps, pc] = PACKED.map(u);
    let (pp, pr, ps, pc) = (pp?, pr?, ps?, pc?);
    let sh_element = find("sh");
    let rest = sh_element.map_or(0, |e| e.properties.len());
    let degree = match rest {
        0 => 0,
        9 => 1,
        24 => 2,
        45 => 3,
        c => return Err(err(origin, "sh", format!("{c} SH properties (expected 9, 24 or 45)"))),
    };
    if let Some(e) = sh_element {
        if e.count != n || e.properties.iter().any(|p| p.2 != "uchar" && p.2 != "uint8") {
            return Err(err(origin, "sh", "the sh element must have one uchar row per Gaussian"));
        }
    }
    let k = sh_coefficients(degree);
    let unorm = |v: u32, bits: u32| f64::from(v & ((1 << bits) - 1)) / f64::from((1u32 << bits) - 1);
    let lerp = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
    let mut scene = super::decoding_scene(n, degree);
    for i in 0..n {
        let c = i / CHUNK;
        let b = |j: usize| bounds[j][c];
        let p = [unorm(pp[i] >> 21, 11), unorm(pp[i] >> 11, 10), unorm(pp[i], 11)];
        scene.means.push([0, 1, 2].map(|a| lerp(b(a), b(3 + a), p[a]) as f32));
        let s = [unorm(ps[i] >> 21, 11), unorm(ps[i] >> 11, 10), unorm(ps[i], 11)];
        scene.log_scales.push([0, 1, 2].map(|a| lerp(b(6 + a), b(9 + a), s[a]) as f32));
        let norm = std::f64::consts::SQRT_2;
        let r = [unorm(pr[i] >> 20, 10), unorm(pr[i] >> 10, 10), unorm(pr[i], 10)].map(|v| (v - 0.5) * norm);
        let m = (1.0 - (r[0] * r[0] + r[1] * r[1] + r[2] * r[2])).max(0.0).sqrt();
        let q = match pr[i] >> 30 {
            0 => [m, r[0], r[1], r[2]],
            1 => [r[0], m, r[1], r[2]],
            2 => [r[0], r[1], m, r[2]],
            _ => [r[0], r[1], r[2], m],
        };
        scene.rotations.push(q.map(|v| v as f32));
        let col = [unorm(pc[i] >> 24, 8), unorm(pc[i] >> 16, 8), unorm(pc[i] >> 8, 8)];
        for a in 0..3 {
            let v = match &colour {
                Some(cb) => lerp(cb[a][c], cb[3 + a][c], col[a]),
                None => col[a],
            };
            scene.sh[i * k * 3 + a] = ((v - 0.5) / SH_C0_F64) as f32;
        }
        scene.opacity_logits.push(byte_logit((pc[i] & 0xff) as u8));
    }
    if let Some(e) = sh_element {
        let d = data[index("sh")];
        for i in 0..n {
            for j in 0..rest {
                let byte = d[i * rest + j];
                let t = match byte {
                    0 => 0.0,
                    255 => 1.0,
                    b => (f64::from(b) + 0.5) / 256.0,
                };
                // f_rest_j is channel-major: channel j / (k-1), coefficient j % (k-1) + 1.
                let (channel, coef) = (j / (k - 1), j % (k - 1) + 1);
                scene.sh[(i * k + coef) * 3 + channel] = ((t - 0.5) * 8.0) as f32;
            }
        }
        let _ = e;
    }
    scene.validate(origin)?;
    Ok(scene)
}

/// Encodes a scene as compressed PLY, chunks in Morton order of the centres
/// so each chunk's bounds stay tight (SH beyond degree 0 kept; relighting
/// attributes are not stored by the format).
pub(crate) fn encode(scene: &Scene) -> Vec<u8> {
    let n = scene.len();
    let k = sh_coefficients(scene.sh_degree);
    let order = morton_order(scene);
    let chunks = n.div_ceil(CHUNK);
    let rest = 3 * (k - 1);
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment written by srug\n");
    header += &format!("element chunk {chunks}\n");
    for name in CHUNK_BOUNDS.iter().chain(&CHUNK_COLOURS) {
        header += &format!("property float {name}\n");
    }
    header += &format!("element vertex {n}\n");
    for name in PACKED {
        header += &format!("property uint {name}\n");
    }
    if rest > 0 {
        header += &format!("element sh {n}\n");
        for j in 0..rest {
            header += &format!("property uchar f_rest_{j}\n");
        }
    }
    header += "end_header\n";
    let mut out = header.into_bytes();
    let colour = |g: usize, a: usize| f64::from(SH_C0) * f64::from(scene.sh[g * k * 3 + a]) + 0.5;
    let mut vertices = Vec::with_capacity(n * 16);
    for members in order.chunks(CHUNK) {
        let mut lo = [f32::INFINITY; 9];
        let mut hi = [f32::NEG_INFINITY; 9];
        for &g in members {
            let v = [
                scene.means[g][0],
                scene.means[g][1],
                scene.means[g][2],
                scene.log_scales[g][0],
                scene.log_scales[g][1],
                scene.log_scales[g][2],
                colour(g, 0) as f32,
                colour(g, 1) as f32,
                colour(g, 2) as f32,
            ];
            for j in 0..9 {
                lo[j] = lo[j].min(v[j]);
                hi[j] = hi[j].max(v[j]);
            }
        }
        for (group, range) in [(0usize, 0..3), (3, 3..6), (6, 6..9)] {
            let _ = group;
            for j in range.clone() {
                out.extend_from_slice(&lo[j].to_le_bytes());
            }
            for j in range {
                out.extend_from_slice(&hi[j].to_le_bytes());
            }
        }
        let t = |v: f64, j: usize| {
            if hi[j] > lo[j] {
                ((v - f64::from(lo[j])) / (f64::from(hi[j]) - f64::from(lo[j]))).clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        let q = |v: f64, bits: u32| (v * f64::from((1u32 << bits) - 1)).round() as u32;
        for &g in members {
            let p = scene.means[g];
            let packed_position =
                q(t(f64::from(p[0]), 0), 11) << 21 | q(t(f64::from(p[1]), 1), 10) << 11 | q(t(f64::from(p[2]), 2), 11);
            let s = scene.log_scales[g];
            let packed_scale =
                q(t(f64::from(s[0]), 3), 11) << 21 | q(t(f64::from(s[1]), 4), 10) << 11 | q(t(f64::from(s[2]), 5), 11);
            let rot = scene.rotations[g].map(f64::from);
            let norm = rot.iter().map(|c| c * c).sum::<f64>().sqrt();
            let rot = rot.map(|c| c / norm);
            let largest = (0..4).fold(0, |m, i| if rot[i].abs() > rot[m].abs() { i } else { m });
            let sign = if rot[largest] < 0.0 { -1.0 } else { 1.0 };
            let mut packed_rotation = largest as u32;
            for (i, c) in rot.iter().enumerate() {
                if i != largest {
                    packed_rotation =
                        packed_rotation << 10 | q((c * sign / std::f64::consts::SQRT_2 + 0.5).clamp(0.0, 1.0), 10);
                }
            }
            let alpha = 1.0 / (1.0 + (-f64::from(scene.opacity_logits[g])).exp());
            let packed_color = q(t(colour(g, 0), 6), 8) << 24
                | q(t(colour(g, 1), 7), 8) << 16
                | q(t(colour(g, 2), 8), 8) << 8
                | q(alpha, 8);
            for v in [packed_position, packed_rotation, packed_scale, packed_color] {
                vertices.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    out.extend_from_slice(&vertices);
    for &g in &order {
        for j in 0..rest {
            let (channel, coef) = (j / (k - 1), j % (k - 1) + 1);
            let v = f64::from(scene.sh[(g * k + coef) * 3 + channel]);
            out.push((((v / 8.0 + 0.5) * 256.0).floor()).clamp(0.0, 255.0) as u8);
        }
    }
    out
}

/// Gaussian indices sorted by the Morton code of their centres over their
/// bounds (10 bits per axis; [`Scene::morton_order_over`]).
pub(crate) fn morton_order(scene: &Scene) -> Vec<usize> {
    scene.bounds().map_or_else(Vec::new, |b| scene.morton_order_over(&b))
}
