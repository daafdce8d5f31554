//! Binary glTF with the Khronos `KHR_gaussian_splatting` extension.
//!
//! A Gaussian primitive is a `POINTS` primitive whose attributes are
//! `POSITION`, `KHR_gaussian_splatting:ROTATION` (xyzw), `:SCALE` (linear),
//! `:OPACITY` (after the sigmoid) and `:SH_DEGREE_l_COEF_n` (RGB per
//! coefficient, band by band). Every Gaussian primitive of every mesh a
//! node instantiates is read; its node's translation and uniform scale are
//! applied (a node rotation is refused: rotating SH needs Wigner matrices
//! srug does not implement yet). glTF is +Y up; srug reads it into the PLY's
//! frame by the same 180° turn about Z that splat-transform applies when it
//! writes a PLY scene as GLB, so a round trip returns the PLY's numbers.
//! Rotation and scale accessors may be normalized integers, as the
//! specification allows; sparse accessors are refused.

use serde_json::Value;

use super::frame::AxisFlip;
use crate::scene::{sh_coefficients, Materials, Scene, SceneError};

const MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const PREFIX: &str = "KHR_gaussian_splatting:";

fn err(origin: &str, field: &str, message: impl std::fmt::Display) -> SceneError {
    SceneError { path: origin.into(), row: None, property: Some(field.into()), message: format!("GLB: {message}") }
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// Where the binary chunk's bytes come from: memory, or a file read range by
/// range (so a large GLB is never held whole beside the scene it decodes to).
enum Bin<'a> {
    Memory(&'a [u8]),
    File { file: std::fs::File, offset: u64, len: u64 },
}

impl Bin<'_> {
    fn len(&self) -> u64 {
        match self {
            Bin::Memory(b) => b.len() as u64,
            Bin::File { len, .. } => *len,
        }
    }

    /// `len` bytes from `start` (within the chunk, checked by the caller).
    fn range(&self, start: usize, len: usize) -> std::io::Result<std::borrow::Cow<'_, [u8]>> {
        use std::io::{Read, Seek, SeekFrom};
        match self {
            Bin::Memory(b) => Ok(std::borrow::Cow::Borrowed(&b[start..start + len])),
            Bin::File { file, offset, .. } => {
                let mut f = file;
                f.seek(SeekFrom::Start(offset + start as u64))?;
                let mut buf = vec![0u8; len];
                f.read_exact(&mut buf)?;
                Ok(std::borrow::Cow::Owned(buf))
            }
        }
    }
}

/// Walks the chunk headers of a GLB whose first `total` bytes `read_at`
/// returns; the JSON and the binary chunk's (offset, length).
fn chunks(
    total: u64,
    read_at: &mut dyn FnMut(u64, usize) -> std::io::Result<Vec<u8>>,
    origin: &str,
) -> Result<(Value, Option<(u64, u64)>), SceneError> {
    let io = |e: std::io::Error| err(origin, "chunk", format!("cannot be read: {e}"));
    let header = if total >= 20 { read_at(0, 12).map_err(io)? } else { Vec::new() };
    if header.len() < 12 || &header[..4] != MAGIC {
        return Err(err(origin, "header", "not a binary glTF file (no glTF magic)"));
    }
    let version = u32_at(&header, 4);
    if version != 2 {
        return Err(err(origin, "version", format!("container version {version}, only 2 is defined")));
    }
    let length = u64::from(u32_at(&header, 8));
    if length != total {
        return Err(err(origin, "length", format!("header declares {length} bytes, the file has {total}")));
    }
    let mut at = 12u64;
    let mut json = None;
    let mut bin = None;
    while at + 8 <= total {
        let h = read_at(at, 8).map_err(io)?;
        let len = u64::from(u32_at(&h, 0));
        let ty = u32_at(&h, 4);
        if at + 8 + len > total {
            return Err(err(origin, "chunk", "the file is truncated inside a chunk"));
        }
        match ty {
            CHUNK_JSON if json.is_none() => {
                let body = read_at(at + 8, len as usize).map_err(io)?;
                json = Some(
                    serde_json::from_slice::<Value>(&body)
                        .map_err(|e| err(origin, "JSON chunk", format!("is not valid JSON: {e}")))?,
                )
            }
            CHUNK_BIN if bin.is_none() => bin = Some((at + 8, len)),
            _ => {}
        }
        at += 8 + len;
    }
    let json = json.ok_or_else(|| err(origin, "JSON chunk", "the file has no JSON chunk"))?;
    Ok((json, bin))
}

/// Decodes one component (bytes, normalized) to f32.
type ComponentDecoder = fn(&[u8], bool) -> f32;

/// The element count of accessor `index`, checked against the limits.
fn accessor_count(json: &Value, index: &Value, name: &str, origin: &str) -> Result<usize, SceneError> {
    let bad = |m: String| err(origin, name, m);
    let i = index.as_u64().ok_or_else(|| bad("attribute is not an accessor index".into()))? as usize;
    let a = json["accessors"].get(i).ok_or_else(|| bad(format!("accessor {i} does not exist")))?;
    let count = a["count"].as_u64().ok_or_else(|| bad(format!("accessor {i} has no count")))?;
    crate::io::limits().gaussians(count).map_err(|why| bad(format!("accessor {i}: {why}")))
}

/// Where an accessor's elements lie and how they decode, checked against the
/// binary chunk before anything is allocated for them.
struct Layout {
    count: usize,
    width: usize,
    size: usize,
    decode: ComponentDecoder,
    normalized: bool,
    view_offset: usize,
    offset: usize,
    stride: usize,
    needed: usize,
}

impl Layout {
    /// Decodes the elements (normalized integers mapped as glTF defines),
    /// handing each one's values to `sink`; reads only the bytes they span.
    fn read(
        &self,
        bin: &Bin<'_>,
        name: &str,
        origin: &str,
        sink: &mut dyn FnMut(usize, &[f32]),
    ) -> Result<(), SceneError> {
        let bytes = bin
            .range(self.view_offset, self.needed)
            .map_err(|e| err(origin, name, format!("the binary chunk cannot be read: {e}")))?;
        let mut values = vec![0.0f32; self.width];
        for e in 0..self.count {
            let at = self.offset + e * self.stride;
            for (c, v) in values.iter_mut().enumerate() {
                *v = (self.decode)(&bytes[at + c * self.size..], self.normalized);
            }
            sink(e, &values);
        }
        Ok(())
    }
}

/// The layout of accessor `index`, every size checked against the binary chunk.
fn accessor_layout(
    json: &Value,
    bin: &Bin<'_>,
    index: &Value,
    name: &str,
    width: usize,
    origin: &str,
) -> Result<Layout, SceneError> {
    let bad = |m: String| err(origin, name, m);
    let i = index.as_u64().ok_or_else(|| bad("attribute is not an accessor index".into()))? as usize;
    let a = json["accessors"].get(i).ok_or_else(|| bad(format!("accessor {i} does not exist")))?;
    if a.get("sparse").is_some() {
        return Err(bad(format!("accessor {i} is sparse; sparse accessors are not supported")));
    }
    let ty = a["type"].as_str().unwrap_or("");
    let want = match width {
        1 => "SCALAR",
        3 => "VEC3",
        _ => "VEC4",
    };
    if ty != want {
        return Err(bad(format!("accessor {i} is {ty}, expected {want}")));
    }
    let count = accessor_count(json, index, name, origin)?;
    let normalized = a["normalized"].as_bool().unwrap_or(false);
    let component = a["componentType"].as_u64().unwrap_or(0);
    let (size, decode): (usize, ComponentDecoder) = match component {
        5126 => (4, |b, _| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        5120 => (1, |b, n| {
            let v = f32::from(b[0] as i8);
            if n {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }),
        5121 => (1, |b, n| if n { f32::from(b[0]) / 255.0 } else { f32::from(b[0]) }),
        5122 => (2, |b, n| {
            let v = f32::from(i16::from_le_bytes([b[0], b[1]]));
            if n {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }),
        5123 => (2, |b, n| {
            let v = f32::from(u16::from_le_bytes([b[0], b[1]]));
            if n {
                v / 65535.0
            } else {
                v
            }
        }),
        other => return Err(bad(format!("accessor {i} has component type {other}, which this attribute cannot use"))),
    };
    // An accessor without a buffer view is all zeros by the glTF rules: no
    // Gaussian attribute is meaningful so, and a tiny file could claim billions.
    let Some(view_index) = a["bufferView"].as_u64() else {
        return Err(bad(format!("accessor {i} has no buffer view (all zeros); Gaussian attributes need data")));
    };
    let view = &json["bufferViews"][view_index as usize];
    if view["buffer"].as_u64() != Some(0) || json["buffers"][0].get("uri").is_some() {
        return Err(bad(format!("accessor {i} is not in the GLB's own binary chunk")));
    }
    let view_offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let view_length = view["byteLength"].as_u64().unwrap_or(0) as usize;
    let offset = a["byteOffset"].as_u64().unwrap_or(0) as usize;
    let element = size * width;
    let stride = view["byteStride"].as_u64().map_or(element, |s| s as usize);
    if view_offset.checked_add(view_length).is_none_or(|end| end as u64 > bin.len()) {
        return Err(bad(format!("buffer view {view_index} lies outside the binary chunk")));
    }
    let needed = if count == 0 {
        Some(0)
    } else {
        stride.checked_mul(count - 1).and_then(|s| s.checked_add(offset)).and_then(|s| s.checked_add(element))
    };
    let needed = needed
        .filter(|&n| stride >= element && n <= view_length)
        .ok_or_else(|| bad(format!("accessor {i}: {count} elements do not fit buffer view {view_index}")))?;
    Ok(Layout { count, width, size, decode, normalized, view_offset, offset, stride, needed })
}

/// The translation and uniform scale of each node instantiating mesh `m`, walking the scene graph.
fn instances(json: &Value, origin: &str) -> Result<Vec<(usize, [f32; 3], f32)>, SceneError> {
    let mut out = Vec::new();
    let nodes = json["nodes"].as_array().cloned().unwrap_or_default();
    let scene_index = json["scene"].as_u64().unwrap_or(0) as usize;
    let roots: Vec<usize> = match json["scenes"].get(scene_index) {
        Some(s) => s["nodes"]
            .as_array()
            .map(|a| a.iter().filter_map(|v| v.as_u64().map(|v| v as usize)).collect())
            .unwrap_or_default(),
        None => (0..nodes.len()).collect(),
    };
    let mut stack: Vec<(usize, [f32; 3], f32, usize)> = roots.into_iter().map(|r| (r, [0.0; 3], 1.0, 0)).collect();
    while let Some((n, t, s, depth)) = stack.pop() {
        if depth > 64 {
            return Err(err(origin, "nodes", "the node hierarchy is deeper than 64 (or has a cycle)"));
        }
        let node = nodes.get(n).ok_or_else(|| err(origin, "nodes", format!("node {n} does not exist")))?;
        let (lt, ls) = node_transform(node, n, origin)?;
        let world_t = [t[0] + s * lt[0], t[1] + s * lt[1], t[2] + s * lt[2]];
        let world_s = s * ls;
        if let Some(m) = node["mesh"].as_u64() {
            out.push((m as usize, world_t, world_s));
        }
        for c in node["children"].as_array().into_iter().flatten() {
            if let Some(c) = c.as_u64() {
                stack.push((c as usize, world_t, world_s, depth + 1));
            }
        }
    }
    Ok(out)
}

fn node_transform(node: &Value, n: usize, origin: &str) -> Result<([f32; 3], f32), SceneError> {
    let floats = |v: &Value| -> Vec<f32> {
        v.as_array().into_iter().flatten().filter_map(|x| x.as_f64()).map(|x| x as f32).collect()
    };
    let refuse = |what: &str| {
        err(
            origin,
            "nodes",
            format!("node {n} has a {what}; only translation and uniform scale are supported for Gaussian primitives"),
        )
    };
    if let Some(m) = node.get("matrix") {
        let m = floats(m);
        let identity3 =
            |s: f32| (0..3).all(|c| (0..3).all(|r| (m[c * 4 + r] - if c == r { s } else { 0.0 }).abs() < 1e-6));
        if m.len() != 16 || !identity3(m[0]) || m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0 {
            return Err(refuse("matrix with rotation, shear or non-uniform scale"));
        }
        return Ok(([m[12], m[13], m[14]], m[0]));
    }
    if let Some(r) = node.get("rotation") {
        let r = floats(r);
        if r.len() != 4 || r[0] != 0.0 || r[1] != 0.0 || r[2] != 0.0 {
            return Err(refuse("rotation"));
        }
    }
    let t = node.get("translation").map(floats).unwrap_or_else(|| vec![0.0; 3]);
    let s = node.get("scale").map(floats).unwrap_or_else(|| vec![1.0; 3]);
    if t.len() != 3 || s.len() != 3 || s[0] != s[1] || s[1] != s[2] || s[0] <= 0.0 {
        return Err(refuse("non-uniform or non-positive scale"));
    }
    Ok(([t[0], t[1], t[2]], s[0]))
}

/// Decodes a GLB held in memory.
pub(crate) fn read(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    let mut read_at = |at: u64, len: usize| -> std::io::Result<Vec<u8>> {
        let at = at as usize;
        bytes
            .get(at..at + len)
            .map(<[u8]>::to_vec)
            .ok_or_else(|| std::io::Error::from(std::io::ErrorKind::UnexpectedEof))
    };
    let (json, range) = chunks(bytes.len() as u64, &mut read_at, origin)?;
    let bin = Bin::Memory(range.map_or(&[][..], |(o, l)| &bytes[o as usize..(o + l) as usize]));
    decode(&json, &bin, origin)
}

/// Decodes a GLB file, reading each attribute's bytes from disk as it is
/// decoded into the scene (the host holds the scene and one attribute, not the file).
pub(crate) fn read_path(path: &std::path::Path) -> crate::error::Result<Scene> {
    use std::io::{Read, Seek, SeekFrom};
    let origin = path.display().to_string();
    let file = std::fs::File::open(path).map_err(crate::error::Error::io(path))?;
    let total = file.metadata().map_err(crate::error::Error::io(path))?.len();
    let mut read_at = |at: u64, len: usize| -> std::io::Result<Vec<u8>> {
        let mut f = &file;
        f.seek(SeekFrom::Start(at))?;
        let mut buf = Vec::with_capacity(len.min(1 << 26));
        f.take(len as u64).read_to_end(&mut buf)?;
        if buf.len() < len {
            return Err(std::io::Error::from(std::io::ErrorKind::UnexpectedEof));
        }
        Ok(buf)
    };
    let (json, range) = chunks(total, &mut read_at, &origin)?;
    let (offset, len) = range.unwrap_or((0, 0));
    let bin = Bin::File { file, offset, len };
    Ok(decode(&json, &bin, &origin)?)
}

fn decode(json: &Value, bin: &Bin<'_>, origin: &str) -> Result<Scene, SceneError> {
    let used = json["extensionsUsed"].as_array().into_iter().flatten().any(|e| e == "KHR_gaussian_splatting");
    if !used {
        return Err(err(origin, "extensionsUsed", "the file does not use KHR_gaussian_splatting (no Gaussians in it)"));
    }
    for e in json["extensionsRequired"].as_array().into_iter().flatten() {
        if e != "KHR_gaussian_splatting" {
            return Err(err(origin, "extensionsRequired", format!("requires {e}, which srug does not implement")));
        }
    }
    let mut parts: Vec<Scene> = Vec::new();
    for (mesh, t, s) in instances(json, origin)? {
        let prims = json["meshes"][mesh]["primitives"].as_array().cloned().unwrap_or_default();
        for (p, prim) in prims.iter().enumerate() {
            let Some(ext) = prim["extensions"].get("KHR_gaussian_splatting") else { continue };
            let where_ = format!("mesh {mesh} primitive {p}");
            if prim["mode"].as_u64() != Some(0) {
                return Err(err(origin, &where_, "a Gaussian primitive must have mode POINTS (0)"));
            }
            if let Some(k) = ext["kernel"].as_str() {
                if k != "ellipse" {
                    log::warn!("{origin}: {where_}: kernel \"{k}\" is rendered as the ellipse kernel");
                }
            }
            match ext["colorSpace"].as_str() {
                None | Some("srgb_rec709_display") => {}
                Some(cs) => log::warn!(
                    "{origin}: {where_}: colour space \"{cs}\" is rendered as srgb_rec709_display, like every 3DGS scene"
                ),
            }
            parts.push(primitive(json, bin, &prim["attributes"], &where_, t, s, origin)?);
        }
    }
    let mut scene = match parts.len() {
        0 => return Err(err(origin, "meshes", "no node instantiates a KHR_gaussian_splatting primitive")),
        1 => parts.remove(0),
        _ => concatenate(parts, origin)?,
    };
    AxisFlip::GLTF_PLY.apply_turn(&mut scene, true);
    scene.validate(origin)?;
    Ok(scene)
}

/// One Gaussian primitive, each attribute decoded straight into the scene's arrays.
fn primitive(
    json: &Value,
    bin: &Bin<'_>,
    attrs: &Value,
    where_: &str,
    t: [f32; 3],
    s: f32,
    origin: &str,
) -> Result<Scene, SceneError> {
    let field = |name: &str| format!("{where_} {name}");
    let index = |name: &str| -> Result<&Value, SceneError> {
        attrs.get(name).ok_or_else(|| err(origin, &field(name), "required attribute is missing"))
    };
    let n = accessor_count(json, index("POSITION")?, &field("POSITION"), origin)?;
    // Higher bands present, each whole.
    let mut degree = 0u32;
    for l in 1..=3usize {
        let present = (0..2 * l + 1).filter(|m| attrs.get(format!("{PREFIX}SH_DEGREE_{l}_COEF_{m}")).is_some()).count();
        if present == 0 {
            break;
        }
        if present != 2 * l + 1 {
            return Err(err(
                origin,
                &format!("{where_} SH_DEGREE_{l}"),
                format!("band {l} is partly defined ({present} of {} coefficients)", 2 * l + 1),
            ));
        }
        degree = l as u32;
    }
    let k = sh_coefficients(degree);
    // Every attribute's layout, checked against the file, before the scene is allocated.
    let mut names: Vec<(String, usize)> = vec![
        ("POSITION".into(), 3),
        (format!("{PREFIX}ROTATION"), 4),
        (format!("{PREFIX}SCALE"), 3),
        (format!("{PREFIX}OPACITY"), 1),
    ];
    for l in 0..=degree as usize {
        names.extend((0..2 * l + 1).map(|m| (format!("{PREFIX}SH_DEGREE_{l}_COEF_{m}"), 3)));
    }
    let mut layouts = Vec::with_capacity(names.len());
    for (name, width) in &names {
        let layout = accessor_layout(json, bin, index(name)?, &field(name), *width, origin)?;
        if layout.count != n {
            return Err(err(origin, &field(name), format!("{} elements for {n} positions", layout.count)));
        }
        layouts.push(layout);
    }
    let mut scene = Scene {
        means: vec![[0.0; 3]; n],
        normals: None,
        sh_degree: degree,
        sh: vec![0.0; n * k * 3],
        opacity_logits: vec![0.0; n],
        log_scales: vec![[0.0; 3]; n],
        rotations: vec![[0.0; 4]; n],
        materials: Materials::default(),
        extra_properties: Vec::new(),
    };
    let mut fault: Option<SceneError> = None;
    let mut next = layouts.iter().zip(&names);
    let mut read = |sink: &mut dyn FnMut(usize, &[f32])| -> Result<(), SceneError> {
        let (layout, (name, _)) = next.next().ok_or_else(|| err(origin, where_, "internal: attribute list ran out"))?;
        layout.read(bin, &field(name), origin, sink)
    };
    read(&mut |i, v| scene.means[i] = [0, 1, 2].map(|a| t[a] + s * v[a]))?;
    read(&mut |i, v| scene.rotations[i] = [v[3], v[0], v[1], v[2]])?;
    let ln_s = s.ln();
    let scale_field = field(&format!("{PREFIX}SCALE"));
    read(&mut |i, v| {
        for (out, &lin) in scene.log_scales[i].iter_mut().zip(v) {
            if !(lin > 0.0 && lin.is_finite()) && fault.is_none() {
                fault = Some(SceneError::at(
                    origin,
                    i,
                    &scale_field,
                    format!("GLB: linear scale {lin} is not a finite positive number"),
                ));
            }
            *out = lin.ln() + ln_s;
        }
    })?;
    let opacity_field = field(&format!("{PREFIX}OPACITY"));
    read(&mut |i, v| {
        let o = f64::from(v[0]);
        if !(0.0..=1.0).contains(&o) && fault.is_none() {
            fault = Some(SceneError::at(origin, i, &opacity_field, format!("GLB: opacity {o} is outside 0..1")));
        }
        let o = o.clamp(1e-7, 1.0 - 1e-7);
        scene.opacity_logits[i] = (o / (1.0 - o)).ln() as f32;
    })?;
    // The SH coefficient accessors follow in band order.
    for coef in 0..k {
        let sh = &mut scene.sh;
        read(&mut |i, v| sh[(i * k + coef) * 3..(i * k + coef) * 3 + 3].copy_from_slice(v))?;
    }
    match fault {
        Some(e) => Err(e),
        None => Ok(scene),
    }
}

fn concatenate(parts: Vec<Scene>, origin: &str) -> Result<Scene, SceneError> {
    let degree = parts[0].sh_degree;
    if parts.iter().any(|p| p.sh_degree != degree) {
        return Err(err(origin, "meshes", "Gaussian primitives with different SH degrees cannot form one scene"));
    }
    let mut out = Scene { sh_degree: degree, ..Scene::default() };
    for p in parts {
        out.means.extend(p.means);
        out.sh.extend(p.sh);
        out.opacity_logits.extend(p.opacity_logits);
        out.log_scales.extend(p.log_scales);
        out.rotations.extend(p.rotations);
    }
    Ok(out)
}

/// Encodes a scene as a GLB with one Gaussian primitive (float attributes,
/// the layout splat-transform writes; relighting attributes are not stored).
pub(crate) fn encode(scene: &Scene) -> Result<Vec<u8>, String> {
    let mut s = scene.clone();
    AxisFlip::GLTF_PLY.apply_turn(&mut s, false);
    let n = s.len();
    let k = sh_coefficients(s.sh_degree);
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = serde_json::Map::new();
    let mut push = |name: String, ty: &str, values: Vec<f32>, bounds: Option<(Vec<f32>, Vec<f32>)>| {
        let offset = bin.len();
        for v in &values {
            bin.extend_from_slice(&v.to_le_bytes());
        }
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": values.len() * 4, "target": 34962}),
        );
        let mut a = serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126, "count": n, "type": ty});
        if let Some((lo, hi)) = bounds {
            a["min"] = serde_json::json!(lo);
            a["max"] = serde_json::json!(hi);
        }
        accessors.push(a);
        attributes.insert(name, serde_json::json!(accessors.len() - 1));
    };
    let bounds = s.bounds().map(|b| (b.min.to_vec(), b.max.to_vec()));
    push("POSITION".into(), "VEC3", s.means.iter().flatten().copied().collect(), bounds);
    push(
        format!("{PREFIX}ROTATION"),
        "VEC4",
        s.rotations.iter().flat_map(|q| [q[1], q[2], q[3], q[0]]).collect(),
        None,
    );
    push(format!("{PREFIX}SCALE"), "VEC3", s.log_scales.iter().flatten().map(|v| v.exp()).collect(), None);
    push(
        format!("{PREFIX}OPACITY"),
        "SCALAR",
        s.opacity_logits.iter().map(|o| 1.0 / (1.0 + (-o).exp())).collect(),
        None,
    );
    let mut coef = 0;
    for l in 0..=s.sh_degree as usize {
        for m in 0..2 * l + 1 {
            let values = (0..n).flat_map(|g| s.sh[(g * k + coef) * 3..(g * k + coef) * 3 + 3].to_vec()).collect();
            push(format!("{PREFIX}SH_DEGREE_{l}_COEF_{m}"), "VEC3", values, None);
            coef += 1;
        }
    }
    let json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "srug"},
        "extensionsUsed": ["KHR_gaussian_splatting"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors,
        "meshes": [{"primitives": [{"attributes": attributes, "mode": 0, "extensions": {"KHR_gaussian_splatting": {
            "kernel": "ellipse", "colorSpace": "srgb_rec709_display", "sortingMethod": "cameraDistance", "projection": "perspective"}}}]}],
    });
    let mut text = serde_json::to_vec(&json).map_err(|e| e.to_string())?;
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let total32 = u32::try_from(total).map_err(|_| format!("{total} bytes exceed the GLB 4 GiB limit"))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}
