//! The INRIA 3DGS PLY format: reader (binary little/big endian, ASCII) and writer.
//!
//! Written here rather than with a generic PLY crate because loading must be
//! fast for millions of rows, look properties up by name in any order, accept
//! the material spellings of public relightable-Gaussian codes, and report
//! every defect with the file, row and property at fault.
//!
//! Only the `vertex` element is read; it must come first (elements after it,
//! such as faces, are ignored). The writer writes to a temporary file and
//! renames it, so a failed write leaves nothing behind.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use crate::error::{Error, Result};
use crate::scene::{sh_coefficients, Materials, Scene, SceneError};

/// PLY data encodings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyFormat {
    /// `binary_little_endian 1.0` (what trainers write).
    BinaryLittleEndian,
    /// `binary_big_endian 1.0`.
    BinaryBigEndian,
    /// `ascii 1.0`.
    Ascii,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn decode(self, b: &[u8], big: bool) -> f32 {
        macro_rules! get {
            ($t:ty, $n:literal) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            Self::I8 => f32::from(b[0] as i8),
            Self::U8 => f32::from(b[0]),
            Self::I16 => f32::from(get!(i16, 2)),
            Self::U16 => f32::from(get!(u16, 2)),
            Self::I32 => get!(i32, 4) as f32,
            Self::U32 => get!(u32, 4) as f32,
            Self::F32 => get!(f32, 4),
            Self::F64 => get!(f64, 8) as f32,
        }
    }

    /// An integer property's value exactly, signed values as their 32-bit two's
    /// complement (−1 reads as `u32::MAX`); `None` for float types.
    fn decode_id(self, b: &[u8], big: bool) -> Option<u32> {
        let two = |b: &[u8]| if big { [b[0], b[1]] } else { [b[1], b[0]] };
        let four = |b: &[u8]| if big { [b[0], b[1], b[2], b[3]] } else { [b[3], b[2], b[1], b[0]] };
        Some(match self {
            Self::I8 => i32::from(b[0] as i8) as u32,
            Self::U8 => u32::from(b[0]),
            Self::I16 => i32::from(i16::from_be_bytes(two(b))) as u32,
            Self::U16 => u32::from(u16::from_be_bytes(two(b))),
            Self::I32 => i32::from_be_bytes(four(b)) as u32,
            Self::U32 => u32::from_be_bytes(four(b)),
            Self::F32 | Self::F64 => return None,
        })
    }

    fn parse_ascii(self, token: &str) -> Option<f32> {
        match self {
            Self::F32 => token.parse::<f32>().ok(),
            Self::F64 => token.parse::<f64>().ok().map(|v| v as f32),
            _ => token.parse::<i64>().ok().map(|v| v as f32),
        }
    }
}

struct Property {
    name: String,
    ty: ScalarType,
    offset: usize,
}

struct Header {
    format: PlyFormat,
    count: usize,
    properties: Vec<Property>,
    stride: usize,
    data_start: usize,
    more_elements: bool,
}

fn parse_header(bytes: &[u8], path: &str) -> Result<Header, SceneError> {
    let err = |m: String| SceneError::file(path, m);
    if !bytes.starts_with(b"ply\n") && !bytes.starts_with(b"ply\r\n") {
        return Err(err("not a PLY file (it does not start with \"ply\")".into()));
    }
    let end = find(bytes, b"end_header").ok_or_else(|| err("PLY header has no end_header".into()))?;
    let newline = bytes[end..]
        .iter()
        .position(|&c| c == b'\n')
        .ok_or_else(|| err("end_header is not followed by a newline".into()))?;
    let data_start = end + newline + 1;
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| err("PLY header is not text".into()))?;
    let mut format = None;
    let mut element: Option<String> = None;
    let mut seen_vertex = false;
    let mut more_elements = false;
    let mut count = 0usize;
    let mut properties: Vec<Property> = Vec::new();
    let mut stride = 0;
    for (line_no, line) in text.lines().enumerate().skip(1) {
        let words: Vec<&str> = line.split_whitespace().collect();
        let at = |m: &str| err(format!("header line {}: {m}: \"{}\"", line_no + 1, line.trim()));
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, v] => {
                if *v != "1.0" {
                    return Err(at("unsupported PLY version"));
                }
                format = Some(match *f {
                    "ascii" => PlyFormat::Ascii,
                    "binary_little_endian" => PlyFormat::BinaryLittleEndian,
                    "binary_big_endian" => PlyFormat::BinaryBigEndian,
                    _ => return Err(at("unknown format")),
                });
            }
            ["element", name, n] => {
                if seen_vertex {
                    more_elements = true;
                } else if *name != "vertex" {
                    return Err(at("the vertex element must come first"));
                } else {
                    seen_vertex = true;
                    let declared: u64 = n.parse().map_err(|_| at("bad element count"))?;
                    count =
                        crate::io::limits().gaussians(declared).map_err(|why| at(&format!("vertex count: {why}")))?;
                }
                element = Some((*name).to_string());
            }
            ["property", "list", ..] => {
                if element.as_deref() == Some("vertex") && !more_elements {
                    return Err(at("list properties in the vertex element are not supported"));
                }
            }
            ["property", ty, name] => {
                if element.is_none() {
                    return Err(at("property before any element"));
                }
                if more_elements {
                    continue;
                }
                let ty = ScalarType::parse(ty).ok_or_else(|| at("unknown property type"))?;
                if properties.iter().any(|p| p.name == *name) {
                    return Err(at("duplicate property"));
                }
                properties.push(Property { name: (*name).to_string(), ty, offset: stride });
                stride += ty.size();
            }
            _ => return Err(at("unrecognized header line")),
        }
    }
    let format = format.ok_or_else(|| err("PLY header has no format line".into()))?;
    if !seen_vertex {
        return Err(err("PLY file has no vertex element".into()));
    }
    Ok(Header { format, count, properties, stride, data_start, more_elements })
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// Reads integer id properties (`semantic`, `instance`, ...) of a PLY's
/// vertices exactly, one list per name, for the top-Gaussian id channels.
/// Signed ids are kept as their 32-bit two's complement, so −1 ("no label")
/// reads as `u32::MAX`, the value of pixels no Gaussian reaches.
pub fn read_ply_ids(path: impl AsRef<Path>, names: &[String]) -> Result<Vec<Vec<u32>>> {
    let path = path.as_ref();
    let origin = path.display().to_string();
    let bytes = super::read_file(path)?;
    let header = parse_header(&bytes, &origin)?;
    let n = header.count;
    let data = &bytes[header.data_start..];
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        let prop = header.properties.iter().find(|p| &p.name == name).ok_or_else(|| SceneError {
            path: origin.clone(),
            row: None,
            property: Some(name.clone()),
            message: format!(
                "no such property (integer properties: {})",
                header
                    .properties
                    .iter()
                    .filter(|p| !matches!(p.ty, ScalarType::F32 | ScalarType::F64))
                    .map(|p| p.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })?;
        if matches!(prop.ty, ScalarType::F32 | ScalarType::F64) {
            return Err(SceneError::at(&origin, 0, name, "is a float property; ids must be integers").into());
        }
        let values = match header.format {
            PlyFormat::Ascii => {
                let text =
                    std::str::from_utf8(data).map_err(|_| SceneError::file(&origin, "ASCII PLY data is not text"))?;
                let column = header.properties.iter().position(|p| p.name == *name).unwrap_or(0);
                let mut v = Vec::with_capacity(n);
                for (row, line) in text.lines().filter(|l| !l.trim().is_empty()).take(n).enumerate() {
                    let token = line.split_whitespace().nth(column).unwrap_or("");
                    let id = token
                        .parse::<i64>()
                        .ok()
                        .filter(|x| (i64::from(i32::MIN)..=i64::from(u32::MAX)).contains(x))
                        .ok_or_else(|| SceneError::at(&origin, row, name, format!("\"{token}\" is not a 32-bit id")))?;
                    v.push(id as u32);
                }
                v
            }
            format => {
                check_binary_length(&header, data.len(), &origin)?;
                let big = format == PlyFormat::BinaryBigEndian;
                (0..n)
                    .map(|g| prop.ty.decode_id(&data[g * header.stride + prop.offset..], big).unwrap_or(u32::MAX))
                    .collect()
            }
        };
        if values.len() != n {
            return Err(SceneError::file(&origin, format!("{name}: {} values for {n} vertices", values.len())).into());
        }
        out.push(values);
    }
    Ok(out)
}

/// Where one PLY property goes in a [`Scene`].
#[derive(Clone, Copy, Debug, PartialEq)]
enum Dest {
    Mean(usize),
    Normal(usize),
    /// SH coefficient `coef` of `channel` (0 is the DC term).
    Sh {
        channel: usize,
        coef: usize,
    },
    Opacity,
    Scale(usize),
    Rot(usize),
    Albedo(usize),
    Roughness,
    Metallic,
    Ao,
    Visibility,
    Ignore,
}

/// The destination of every property, decided once from the header (any
/// property order; the material spellings of public relightable codes).
struct Plan {
    dests: Vec<Dest>,
    sh_degree: u32,
    normals: bool,
    albedo: bool,
    singles: [bool; 4],
    extra: Vec<String>,
}

impl Plan {
    fn new(header: &Header, origin: &str) -> Result<Plan, SceneError> {
        let index: HashMap<&str, usize> =
            header.properties.iter().enumerate().map(|(i, p)| (p.name.as_str(), i)).collect();
        let mut dests = vec![Dest::Ignore; header.properties.len()];
        let mut used = vec![false; header.properties.len()];
        let mut place = |name: &str, d: Dest| -> bool {
            match index.get(name) {
                Some(&i) => {
                    dests[i] = d;
                    used[i] = true;
                    true
                }
                None => false,
            }
        };
        let missing = |name: &str| SceneError {
            path: origin.into(),
            row: None,
            property: Some(name.into()),
            message: "required property is missing".into(),
        };
        for (a, name) in ["x", "y", "z"].into_iter().enumerate() {
            place(name, Dest::Mean(a)).then_some(()).ok_or_else(|| missing(name))?;
        }
        for c in 0..3 {
            let name = format!("f_dc_{c}");
            place(&name, Dest::Sh { channel: c, coef: 0 }).then_some(()).ok_or_else(|| missing(&name))?;
        }
        place("opacity", Dest::Opacity).then_some(()).ok_or_else(|| missing("opacity"))?;
        for a in 0..3 {
            let name = format!("scale_{a}");
            place(&name, Dest::Scale(a)).then_some(()).ok_or_else(|| missing(&name))?;
        }
        for a in 0..4 {
            let name = format!("rot_{a}");
            place(&name, Dest::Rot(a)).then_some(()).ok_or_else(|| missing(&name))?;
        }
        // f_rest_*: channel-major, 3·((d+1)² − 1) of them.
        let rest_count = header.properties.iter().filter(|p| p.name.starts_with("f_rest_")).count();
        let sh_degree = match rest_count {
            0 => 0,
            9 => 1,
            24 => 2,
            45 => 3,
            c => {
                return Err(SceneError::file(
                    origin,
                    format!("unsupported SH count: {c} f_rest properties (expected 0, 9, 24 or 45)"),
                ))
            }
        };
        let k = sh_coefficients(sh_degree);
        for j in 0..rest_count {
            let name = format!("f_rest_{j}");
            if !place(&name, Dest::Sh { channel: j / (k - 1), coef: j % (k - 1) + 1 }) {
                return Err(SceneError {
                    path: origin.into(),
                    row: None,
                    property: Some(name),
                    message: format!("missing; f_rest_0..f_rest_{} must all be present", rest_count - 1),
                });
            }
        }
        let normals = match ["nx", "ny", "nz"].map(|n| index.contains_key(n)) {
            [true, true, true] => {
                for (a, n) in ["nx", "ny", "nz"].into_iter().enumerate() {
                    place(n, Dest::Normal(a));
                }
                true
            }
            [false, false, false] => false,
            _ => return Err(SceneError::file(origin, "normals need all of nx, ny, nz")),
        };
        let mut albedo = false;
        for spelling in ["albedo_", "base_color_", "albedo"] {
            let names: Vec<String> = (0..3).map(|i| format!("{spelling}{i}")).collect();
            let present = names.iter().filter(|n| index.contains_key(n.as_str())).count();
            if present == 3 {
                for (a, n) in names.iter().enumerate() {
                    place(n, Dest::Albedo(a));
                }
                albedo = true;
                break;
            } else if present > 0 {
                return Err(SceneError::file(origin, format!("albedo needs all of {}", names.join(", "))));
            }
        }
        let singles = [
            place("roughness", Dest::Roughness),
            place("metallic", Dest::Metallic),
            place("ao", Dest::Ao),
            place("visibility", Dest::Visibility),
        ];
        let extra = header.properties.iter().zip(&used).filter(|(_, u)| !**u).map(|(p, _)| p.name.clone()).collect();
        Ok(Plan { dests, sh_degree, normals, albedo, singles, extra })
    }

    /// A scene of `n` Gaussians, every array at its final size (zeroed).
    fn empty_scene(&self, n: usize) -> Scene {
        let k = sh_coefficients(self.sh_degree);
        let single = |on: bool| on.then(|| vec![0.0f32; n]);
        Scene {
            means: vec![[0.0; 3]; n],
            normals: self.normals.then(|| vec![[0.0; 3]; n]),
            sh_degree: self.sh_degree,
            sh: vec![0.0; n * k * 3],
            opacity_logits: vec![0.0; n],
            log_scales: vec![[0.0; 3]; n],
            rotations: vec![[0.0; 4]; n],
            materials: Materials {
                albedo: self.albedo.then(|| vec![[0.0; 3]; n]),
                roughness: single(self.singles[0]),
                metallic: single(self.singles[1]),
                ao: single(self.singles[2]),
                visibility: single(self.singles[3]),
            },
            extra_properties: self.extra.clone(),
        }
    }

    /// Writes property `i` of rows `g0..`, one row per value of `values`:
    /// where it goes is matched once, not once a value.
    fn set_column(&self, scene: &mut Scene, i: usize, g0: usize, values: impl Iterator<Item = f32>) {
        let k = sh_coefficients(self.sh_degree);
        let m = &mut scene.materials;
        fn fill<T>(dest: &mut [T], g0: usize, values: impl Iterator<Item = f32>, set: impl Fn(&mut T, f32)) {
            dest.iter_mut().skip(g0).zip(values).for_each(|(x, v)| set(x, v));
        }
        match self.dests[i] {
            Dest::Mean(a) => fill(&mut scene.means, g0, values, |x, v| x[a] = v),
            Dest::Normal(a) => {
                if let Some(n) = &mut scene.normals {
                    fill(n, g0, values, |x, v| x[a] = v);
                }
            }
            Dest::Sh { channel, coef } => {
                let first = (g0 * k + coef) * 3 + channel;
                scene.sh.iter_mut().skip(first).step_by(k * 3).zip(values).for_each(|(x, v)| *x = v);
            }
            Dest::Opacity => fill(&mut scene.opacity_logits, g0, values, |x, v| *x = v),
            Dest::Scale(a) => fill(&mut scene.log_scales, g0, values, |x, v| x[a] = v),
            Dest::Rot(a) => fill(&mut scene.rotations, g0, values, |x, v| x[a] = v),
            Dest::Albedo(a) => {
                if let Some(n) = &mut m.albedo {
                    fill(n, g0, values, |x, v| x[a] = v);
                }
            }
            d @ (Dest::Roughness | Dest::Metallic | Dest::Ao | Dest::Visibility) => {
                let slot = match d {
                    Dest::Roughness => &mut m.roughness,
                    Dest::Metallic => &mut m.metallic,
                    Dest::Ao => &mut m.ao,
                    _ => &mut m.visibility,
                };
                if let Some(n) = slot {
                    fill(n, g0, values, |x, v| *x = v);
                }
            }
            Dest::Ignore => {}
        }
    }

    /// Decodes `n` binary rows of `data` (rows of `header.stride` bytes) into
    /// rows `g0..` of `scene`: property by property over runs of rows that stay
    /// in cache, each property's type and destination matched once a run.
    fn set_binary_rows(&self, scene: &mut Scene, header: &Header, data: &[u8], big: bool, g0: usize, n: usize) {
        const RUN: usize = 512;
        let stride = header.stride;
        for (run, rows) in data[..n * stride].chunks(RUN * stride).enumerate() {
            let g = g0 + run * RUN;
            for (i, p) in header.properties.iter().enumerate() {
                if self.dests[i] == Dest::Ignore {
                    continue;
                }
                let fields = rows.chunks_exact(stride).map(|row| &row[p.offset..p.offset + p.ty.size()]);
                match (p.ty, big) {
                    (ScalarType::F32, false) => {
                        self.set_column(scene, i, g, fields.map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
                    }
                    (ty, _) => self.set_column(scene, i, g, fields.map(|b| ty.decode(b, big))),
                }
            }
        }
    }

    /// Writes row `g`, whose property `i` has the value `value(i)`.
    fn set_row(&self, scene: &mut Scene, g: usize, value: impl Fn(usize) -> f32) {
        let k = sh_coefficients(self.sh_degree);
        for (i, d) in self.dests.iter().enumerate() {
            let v = value(i);
            let m = &mut scene.materials;
            match *d {
                Dest::Mean(a) => scene.means[g][a] = v,
                Dest::Normal(a) => {
                    if let Some(n) = &mut scene.normals {
                        n[g][a] = v;
                    }
                }
                Dest::Sh { channel, coef } => scene.sh[(g * k + coef) * 3 + channel] = v,
                Dest::Opacity => scene.opacity_logits[g] = v,
                Dest::Scale(a) => scene.log_scales[g][a] = v,
                Dest::Rot(a) => scene.rotations[g][a] = v,
                Dest::Albedo(a) => {
                    if let Some(x) = &mut m.albedo {
                        x[g][a] = v;
                    }
                }
                Dest::Roughness | Dest::Metallic | Dest::Ao | Dest::Visibility => {
                    let slot = match *d {
                        Dest::Roughness => &mut m.roughness,
                        Dest::Metallic => &mut m.metallic,
                        Dest::Ao => &mut m.ao,
                        _ => &mut m.visibility,
                    };
                    if let Some(x) = slot {
                        x[g] = v;
                    }
                }
                Dest::Ignore => {}
            }
        }
    }
}

/// The error for binary data that ends before the rows the header declares.
fn truncated(header: &Header, data_len: usize, origin: &str) -> SceneError {
    let n = header.count;
    let row = data_len / header.stride.max(1);
    let within = data_len % header.stride.max(1);
    let prop = header.properties.iter().rev().find(|p| p.offset <= within).map_or("?", |p| p.name.as_str());
    SceneError::at(origin, row, prop, format!("file is truncated: data ends in row {row} of {n} declared vertices"))
}

/// Checks the binary data length against the declared rows.
fn check_binary_length(header: &Header, data_len: usize, origin: &str) -> Result<(), SceneError> {
    let n = header.count;
    let need = n.checked_mul(header.stride).ok_or_else(|| SceneError::file(origin, "vertex count overflows"))?;
    if data_len < need {
        return Err(truncated(header, data_len, origin));
    }
    if data_len > need && !header.more_elements {
        let extra = data_len - need;
        return Err(SceneError::file(
            origin,
            format!(
                "vertex count does not match the data: {n} vertices declared but {extra} bytes ({:.2} rows) follow them",
                extra as f64 / header.stride.max(1) as f64
            ),
        ));
    }
    Ok(())
}

/// Reads an INRIA-style 3DGS PLY file. Binary files stream from disk into
/// the scene's arrays, so the host holds one copy of the scene, not the file
/// and the scene.
pub fn read_ply(path: impl AsRef<Path>) -> Result<Scene> {
    let path = path.as_ref();
    match open_ply(path)? {
        OpenedPly::Whole(scene) => Ok(scene),
        OpenedPly::Rows(mut rows) => {
            let mut scene = rows.plan.empty_scene(rows.header.count);
            while let Some((first, n)) = rows.next_block(1 << 20) {
                rows.read_rows(&mut scene, first, n)?;
            }
            scene.validate(&rows.origin)?;
            Ok(scene)
        }
    }
}

/// One block of a PLY scene read by [`read_ply_blocks`].
pub struct PlyBlock<'a> {
    /// Gaussians in the whole file.
    pub total: usize,
    /// Index of this block's first Gaussian in the file.
    pub first: usize,
    /// This block's Gaussians, validated (errors name their rows in the file).
    pub gaussians: &'a Scene,
}

/// Reads a PLY scene in blocks of about `block_bytes` of the file, in file
/// order, each validated, so a caller can move the scene elsewhere (to the
/// device) without the host ever holding all of it. Files [`read_ply`]
/// cannot stream (ASCII, or past the size limit it words refusals for) come
/// as one block. Stops at the first error `on_block` returns.
pub fn read_ply_blocks(
    path: impl AsRef<Path>,
    block_bytes: usize,
    mut on_block: impl FnMut(&PlyBlock<'_>) -> Result<()>,
) -> Result<()> {
    match open_ply(path.as_ref())? {
        OpenedPly::Whole(scene) => on_block(&PlyBlock { total: scene.len(), first: 0, gaussians: &scene }),
        OpenedPly::Rows(mut rows) => {
            let total = rows.header.count;
            if total == 0 {
                return on_block(&PlyBlock { total, first: 0, gaussians: &rows.plan.empty_scene(0) });
            }
            let mut block = Scene::default();
            while let Some((first, n)) = rows.next_block(block_bytes) {
                if block.len() != n {
                    block = rows.plan.empty_scene(n);
                }
                rows.read_rows(&mut block, 0, n)?;
                block.validate(&rows.origin).map_err(|mut e| {
                    e.row = e.row.map(|r| r + first);
                    e
                })?;
                on_block(&PlyBlock { total, first, gaussians: &block })?;
            }
            Ok(())
        }
    }
}

/// A PLY file opened for reading: whole where it cannot stream, else its
/// binary rows behind the parsed header.
enum OpenedPly {
    Whole(Scene),
    Rows(PlyRows),
}

/// The binary rows of an opened PLY file, read a block at a time.
struct PlyRows {
    reader: std::io::BufReader<std::fs::File>,
    header: Header,
    plan: Plan,
    big_endian: bool,
    origin: String,
    path: std::path::PathBuf,
    /// Rows read so far.
    next: usize,
    /// The current block's bytes.
    block: Vec<u8>,
}

impl PlyRows {
    /// The rows of the next block of about `block_bytes`: (its first row, its
    /// rows), or `None` at the end.
    fn next_block(&self, block_bytes: usize) -> Option<(usize, usize)> {
        let (count, stride) = (self.header.count, self.header.stride);
        (self.next < count).then(|| (self.next, (block_bytes / stride.max(1) + 1).min(count - self.next)))
    }

    /// Reads the next `n` rows into rows `g0..g0 + n` of `scene`, a piece of
    /// about 256 KiB at a time, each decoded while it is still in cache.
    fn read_rows(&mut self, scene: &mut Scene, g0: usize, n: usize) -> Result<()> {
        use std::io::Read;
        let stride = self.header.stride.max(1);
        let piece = (256 << 10) / stride + 1;
        for start in (0..n).step_by(piece) {
            let rows = piece.min(n - start);
            self.block.resize(rows * stride, 0);
            let (first, header, origin, path) = (self.next, &self.header, &self.origin, &self.path);
            self.reader.read_exact(&mut self.block).map_err(|e| match e.kind() {
                std::io::ErrorKind::UnexpectedEof => Error::from(truncated(header, first * stride, origin)),
                _ => Error::io(path)(e),
            })?;
            self.plan.set_binary_rows(scene, &self.header, &self.block, self.big_endian, g0 + start, rows);
            self.next += rows;
        }
        Ok(())
    }
}

/// Opens a PLY scene: binary files behind their parsed header, ready to
/// stream; ASCII files and those past the size limit read whole.
fn open_ply(path: &Path) -> Result<OpenedPly> {
    use std::io::{BufRead, Read};
    let origin = path.display().to_string();
    let file = std::fs::File::open(path).map_err(Error::io(path))?;
    let meta = file.metadata().map_err(Error::io(path))?;
    let max = super::limits().max_file_bytes;
    if !meta.is_file() || meta.len() > max {
        // The whole-file reader words these refusals.
        return Ok(OpenedPly::Whole(read_ply_bytes(&super::read_file(path)?, &origin)?));
    }
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    // The header: bytes up to end_header and its newline (at most 16 MiB).
    let mut head = Vec::new();
    loop {
        let before = head.len();
        let n = reader.by_ref().take(1 << 16).read_until(b'\n', &mut head).map_err(Error::io(path))?;
        let line_start = before;
        if n == 0 || head.len() > 16 << 20 || head[line_start..].starts_with(b"end_header") {
            break;
        }
        if head.len() >= 4 && !head.starts_with(b"ply") {
            break;
        }
    }
    let header = parse_header(&head, &origin)?;
    if header.format == PlyFormat::Ascii {
        return Ok(OpenedPly::Whole(read_ply_bytes(&super::read_file(path)?, &origin)?));
    }
    let data_len = usize::try_from(meta.len()).unwrap_or(usize::MAX).saturating_sub(header.data_start);
    check_binary_length(&header, data_len, &origin)?;
    let plan = Plan::new(&header, &origin)?;
    let big_endian = header.format == PlyFormat::BinaryBigEndian;
    Ok(OpenedPly::Rows(PlyRows {
        reader,
        header,
        plan,
        big_endian,
        origin,
        path: path.to_path_buf(),
        next: 0,
        block: Vec::new(),
    }))
}

/// Reads a PLY file held in memory; `origin` names it in errors.
pub fn read_ply_bytes(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    let header = parse_header(bytes, origin)?;
    let n = header.count;
    let data = &bytes[header.data_start..];
    let nprops = header.properties.len();
    let plan;
    let mut scene;
    match header.format {
        PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
            let big = header.format == PlyFormat::BinaryBigEndian;
            check_binary_length(&header, data.len(), origin)?;
            plan = Plan::new(&header, origin)?;
            scene = plan.empty_scene(n);
            plan.set_binary_rows(&mut scene, &header, data, big, 0, n);
        }
        PlyFormat::Ascii => {
            let text = std::str::from_utf8(data).map_err(|_| SceneError::file(origin, "ASCII PLY data is not text"))?;
            let mut lines = text.lines().filter(|l| !l.trim().is_empty());
            // Rows are parsed before the plan is applied so defects are reported in file order.
            let mut rows: Vec<Vec<f32>> = Vec::with_capacity(n.min(data.len() / 2 + 1));
            for row in 0..n {
                let line = lines.next().ok_or_else(|| {
                    SceneError::at(
                        origin,
                        row,
                        &header.properties.first().map_or(String::new(), |p| p.name.clone()),
                        format!("file is truncated: data ends in row {row} of {n} declared vertices"),
                    )
                })?;
                let mut tokens = line.split_whitespace();
                let mut values = Vec::with_capacity(nprops);
                for p in &header.properties {
                    let token =
                        tokens.next().ok_or_else(|| SceneError::at(origin, row, &p.name, "row has too few values"))?;
                    let v =
                        p.ty.parse_ascii(token)
                            .ok_or_else(|| SceneError::at(origin, row, &p.name, format!("cannot parse \"{token}\"")))?;
                    values.push(v);
                }
                if tokens.next().is_some() {
                    return Err(SceneError {
                        path: origin.into(),
                        row: Some(row),
                        property: None,
                        message: format!("row has more than {nprops} values"),
                    });
                }
                rows.push(values);
            }
            if !header.more_elements && lines.next().is_some() {
                return Err(SceneError::file(
                    origin,
                    format!("vertex count does not match the data: more than {n} rows follow the header"),
                ));
            }
            plan = Plan::new(&header, origin)?;
            scene = plan.empty_scene(n);
            for (g, values) in rows.iter().enumerate() {
                plan.set_row(&mut scene, g, |i| values[i]);
            }
        }
    }
    scene.validate(origin)?;
    Ok(scene)
}

/// Property names in the order the writer emits them.
fn property_names(scene: &Scene) -> Vec<String> {
    let k = sh_coefficients(scene.sh_degree);
    let mut names: Vec<String> = ["x", "y", "z"].map(String::from).to_vec();
    if scene.normals.is_some() {
        names.extend(["nx", "ny", "nz"].map(String::from));
    }
    names.extend((0..3).map(|i| format!("f_dc_{i}")));
    names.extend((0..3 * (k - 1)).map(|i| format!("f_rest_{i}")));
    names.push("opacity".into());
    names.extend((0..3).map(|i| format!("scale_{i}")));
    names.extend((0..4).map(|i| format!("rot_{i}")));
    let m = &scene.materials;
    if m.albedo.is_some() {
        names.extend((0..3).map(|i| format!("albedo_{i}")));
    }
    for (name, v) in
        [("roughness", &m.roughness), ("metallic", &m.metallic), ("ao", &m.ao), ("visibility", &m.visibility)]
    {
        if v.is_some() {
            names.push(name.into());
        }
    }
    names
}

/// The values of row `g` in [`property_names`] order.
fn row_values(scene: &Scene, g: usize, out: &mut Vec<f32>) {
    let k = sh_coefficients(scene.sh_degree);
    out.clear();
    out.extend_from_slice(&scene.means[g]);
    if let Some(n) = &scene.normals {
        out.extend_from_slice(&n[g]);
    }
    for c in 0..3 {
        out.push(scene.sh[g * k * 3 + c]);
    }
    for c in 0..3 {
        for coef in 1..k {
            out.push(scene.sh[(g * k + coef) * 3 + c]);
        }
    }
    out.push(scene.opacity_logits[g]);
    out.extend_from_slice(&scene.log_scales[g]);
    out.extend_from_slice(&scene.rotations[g]);
    let m = &scene.materials;
    if let Some(a) = &m.albedo {
        out.extend_from_slice(&a[g]);
    }
    for v in [&m.roughness, &m.metallic, &m.ao, &m.visibility].into_iter().flatten() {
        out.push(v[g]);
    }
}

/// Writes `scene` as a PLY file (all properties float). Validates first; on any
/// failure nothing is left at `path`.
pub fn write_ply(path: impl AsRef<Path>, scene: &Scene, format: PlyFormat) -> Result<()> {
    write_ply_with_flags(path, scene, format, &[])
}

/// [`write_ply`] with per-Gaussian flags appended as `uchar` properties (0 or
/// 1 each; tools that do not know them skip them, srug reads them with
/// [`read_ply_ids`]), e.g. which Gaussians a completion added. Every flag
/// list must hold one value per Gaussian.
pub fn write_ply_with_flags(
    path: impl AsRef<Path>,
    scene: &Scene,
    format: PlyFormat,
    flags: &[(&str, &[bool])],
) -> Result<()> {
    let path = path.as_ref();
    scene.validate("scene to write")?;
    for (name, values) in flags {
        let clash = property_names(scene).iter().any(|n| n == name);
        if values.len() != scene.len() || clash || name.is_empty() || !name.bytes().all(|b| b.is_ascii_graphic()) {
            return Err(Error::invalid(
                format!("PLY flag property \"{name}\" ({} values)", values.len()),
                format!("needs a new printable name and one value per Gaussian ({})", scene.len()),
            ));
        }
    }
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default(),
        std::process::id()
    ));
    let result =
        write_ply_to(&tmp, scene, format, flags).and_then(|()| std::fs::rename(&tmp, path).map_err(Error::io(path)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn write_ply_to(path: &Path, scene: &Scene, format: PlyFormat, flags: &[(&str, &[bool])]) -> Result<()> {
    let file = std::fs::File::create(path).map_err(Error::io(path))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    let written = write_ply_into(&mut w, scene, format, flags).and_then(|()| w.flush());
    written.and_then(|()| w.get_ref().sync_all()).map_err(Error::io(path))
}

/// Writes `scene` as PLY into any writer (its properties float, then `flags`
/// as uchar; not validated here).
pub(crate) fn write_ply_into(
    w: &mut impl Write,
    scene: &Scene,
    format: PlyFormat,
    flags: &[(&str, &[bool])],
) -> std::io::Result<()> {
    let names = property_names(scene);
    let mut header = String::from("ply\n");
    header += match format {
        PlyFormat::Ascii => "format ascii 1.0\n",
        PlyFormat::BinaryLittleEndian => "format binary_little_endian 1.0\n",
        PlyFormat::BinaryBigEndian => "format binary_big_endian 1.0\n",
    };
    header += "comment written by srug\n";
    header += &format!("element vertex {}\n", scene.len());
    for n in &names {
        header += &format!("property float {n}\n");
    }
    for (n, _) in flags {
        header += &format!("property uchar {n}\n");
    }
    header += "end_header\n";
    w.write_all(header.as_bytes())?;
    let mut row = Vec::with_capacity(names.len());
    let mut line = String::new();
    for g in 0..scene.len() {
        row_values(scene, g, &mut row);
        match format {
            PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
                let little = format == PlyFormat::BinaryLittleEndian;
                row.iter().try_for_each(|v| w.write_all(&if little { v.to_le_bytes() } else { v.to_be_bytes() }))?;
                flags.iter().try_for_each(|(_, f)| w.write_all(&[u8::from(f[g])]))?;
            }
            PlyFormat::Ascii => {
                line.clear();
                for (i, v) in row.iter().enumerate() {
                    if i > 0 {
                        line.push(' ');
                    }
                    // Rust's float Display is the shortest string that parses back exactly.
                    line += &v.to_string();
                }
                for (_, f) in flags {
                    line += if f[g] { " 1" } else { " 0" };
                }
                line.push('\n');
                w.write_all(line.as_bytes())?;
            }
        }
    }
    Ok(())
}
