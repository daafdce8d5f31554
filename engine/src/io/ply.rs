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

/// Reads an INRIA-style 3DGS PLY file.
pub fn read_ply(path: impl AsRef<Path>) -> Result<Scene> {
    let path = path.as_ref();
    let bytes = super::read_file(path)?;
    Ok(read_ply_bytes(&bytes, &path.display().to_string())?)
}

/// Reads a PLY file held in memory; `origin` names it in errors.
pub fn read_ply_bytes(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    let header = parse_header(bytes, origin)?;
    let n = header.count;
    let data = &bytes[header.data_start..];
    let nprops = header.properties.len();

    // Decode into a column per property.
    let mut columns: Vec<Vec<f32>> = Vec::with_capacity(nprops);
    match header.format {
        PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
            let big = header.format == PlyFormat::BinaryBigEndian;
            let need =
                n.checked_mul(header.stride).ok_or_else(|| SceneError::file(origin, "vertex count overflows"))?;
            if data.len() < need {
                let row = data.len() / header.stride.max(1);
                let within = data.len() % header.stride.max(1);
                let prop = header.properties.iter().rev().find(|p| p.offset <= within).map_or("?", |p| p.name.as_str());
                return Err(SceneError::at(
                    origin,
                    row,
                    prop,
                    format!("file is truncated: data ends in row {row} of {n} declared vertices"),
                ));
            }
            if data.len() > need && !header.more_elements {
                let extra = data.len() - need;
                return Err(SceneError::file(
                    origin,
                    format!(
                        "vertex count does not match the data: {n} vertices declared but {extra} bytes ({:.2} rows) follow them",
                        extra as f64 / header.stride.max(1) as f64
                    ),
                ));
            }
            for p in &header.properties {
                let mut col = Vec::with_capacity(n);
                let size = p.ty.size();
                for row in 0..n {
                    let at = row * header.stride + p.offset;
                    col.push(p.ty.decode(&data[at..at + size], big));
                }
                columns.push(col);
            }
        }
        PlyFormat::Ascii => {
            let text = std::str::from_utf8(data).map_err(|_| SceneError::file(origin, "ASCII PLY data is not text"))?;
            columns = (0..nprops).map(|_| Vec::with_capacity(n.min(data.len() / 2 + 1))).collect();
            let mut lines = text.lines().filter(|l| !l.trim().is_empty());
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
                for (i, p) in header.properties.iter().enumerate() {
                    let token =
                        tokens.next().ok_or_else(|| SceneError::at(origin, row, &p.name, "row has too few values"))?;
                    let v =
                        p.ty.parse_ascii(token)
                            .ok_or_else(|| SceneError::at(origin, row, &p.name, format!("cannot parse \"{token}\"")))?;
                    columns[i].push(v);
                }
                if tokens.next().is_some() {
                    return Err(SceneError {
                        path: origin.into(),
                        row: Some(row),
                        property: None,
                        message: format!("row has more than {nprops} values"),
                    });
                }
            }
            if !header.more_elements && lines.next().is_some() {
                return Err(SceneError::file(
                    origin,
                    format!("vertex count does not match the data: more than {n} rows follow the header"),
                ));
            }
        }
    }
    assemble(&header, columns, origin)
}

fn assemble(header: &Header, columns: Vec<Vec<f32>>, origin: &str) -> Result<Scene, SceneError> {
    let mut by_name: HashMap<&str, usize> =
        header.properties.iter().enumerate().map(|(i, p)| (p.name.as_str(), i)).collect();
    let mut columns: Vec<Option<Vec<f32>>> = columns.into_iter().map(Some).collect();
    let mut take = |name: &str| -> Option<Vec<f32>> { by_name.remove(name).and_then(|i| columns[i].take()) };
    let require = |take: &mut dyn FnMut(&str) -> Option<Vec<f32>>, name: &str| {
        take(name).ok_or_else(|| SceneError {
            path: origin.into(),
            row: None,
            property: Some(name.into()),
            message: "required property is missing".into(),
        })
    };
    let n = header.count;
    let zip3 =
        |a: Vec<f32>, b: Vec<f32>, c: Vec<f32>| -> Vec<[f32; 3]> { (0..n).map(|i| [a[i], b[i], c[i]]).collect() };

    let means = zip3(require(&mut take, "x")?, require(&mut take, "y")?, require(&mut take, "z")?);
    let dc = [require(&mut take, "f_dc_0")?, require(&mut take, "f_dc_1")?, require(&mut take, "f_dc_2")?];
    let opacity_logits = require(&mut take, "opacity")?;
    let log_scales =
        zip3(require(&mut take, "scale_0")?, require(&mut take, "scale_1")?, require(&mut take, "scale_2")?);
    let r = [
        require(&mut take, "rot_0")?,
        require(&mut take, "rot_1")?,
        require(&mut take, "rot_2")?,
        require(&mut take, "rot_3")?,
    ];
    let rotations = (0..n).map(|i| [r[0][i], r[1][i], r[2][i], r[3][i]]).collect();

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
    let mut rest = Vec::with_capacity(rest_count);
    for j in 0..rest_count {
        let name = format!("f_rest_{j}");
        rest.push(take(&name).ok_or_else(|| SceneError {
            path: origin.into(),
            row: None,
            property: Some(name.clone()),
            message: format!("missing; f_rest_0..f_rest_{} must all be present", rest_count - 1),
        })?);
    }
    let mut sh = vec![0.0f32; n * k * 3];
    for g in 0..n {
        for c in 0..3 {
            sh[g * k * 3 + c] = dc[c][g];
            for coef in 1..k {
                sh[(g * k + coef) * 3 + c] = rest[c * (k - 1) + coef - 1][g];
            }
        }
    }

    let normals = match (take("nx"), take("ny"), take("nz")) {
        (Some(a), Some(b), Some(c)) => Some(zip3(a, b, c)),
        (None, None, None) => None,
        _ => return Err(SceneError::file(origin, "normals need all of nx, ny, nz")),
    };
    let mut albedo = None;
    for spelling in ["albedo_", "base_color_", "albedo"] {
        let names: Vec<String> = (0..3).map(|i| format!("{spelling}{i}")).collect();
        let present = names.iter().filter(|n| by_name_has(header, n)).count();
        if present == 3 {
            if let (Some(a), Some(b), Some(c)) = (take(&names[0]), take(&names[1]), take(&names[2])) {
                albedo = Some(zip3(a, b, c));
                break;
            }
        } else if present > 0 {
            return Err(SceneError::file(origin, format!("albedo needs all of {}", names.join(", "))));
        }
    }
    let materials = Materials {
        albedo,
        roughness: take("roughness"),
        metallic: take("metallic"),
        ao: take("ao"),
        visibility: take("visibility"),
    };
    let extra_properties =
        header.properties.iter().filter(|p| by_name.contains_key(p.name.as_str())).map(|p| p.name.clone()).collect();
    let scene =
        Scene { means, normals, sh_degree, sh, opacity_logits, log_scales, rotations, materials, extra_properties };
    scene.validate(origin)?;
    Ok(scene)
}

fn by_name_has(header: &Header, name: &str) -> bool {
    header.properties.iter().any(|p| p.name == name)
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
    let path = path.as_ref();
    scene.validate("scene to write")?;
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default(),
        std::process::id()
    ));
    let result = write_ply_to(&tmp, scene, format).and_then(|()| std::fs::rename(&tmp, path).map_err(Error::io(path)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn write_ply_to(path: &Path, scene: &Scene, format: PlyFormat) -> Result<()> {
    let file = std::fs::File::create(path).map_err(Error::io(path))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    let written = write_ply_into(&mut w, scene, format).and_then(|()| w.flush());
    written.and_then(|()| w.get_ref().sync_all()).map_err(Error::io(path))
}

/// Writes `scene` as PLY into any writer (all properties float; not validated here).
pub(crate) fn write_ply_into(w: &mut impl Write, scene: &Scene, format: PlyFormat) -> std::io::Result<()> {
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
    header += "end_header\n";
    w.write_all(header.as_bytes())?;
    let mut row = Vec::with_capacity(names.len());
    let mut line = String::new();
    for g in 0..scene.len() {
        row_values(scene, g, &mut row);
        match format {
            PlyFormat::BinaryLittleEndian => row.iter().try_for_each(|v| w.write_all(&v.to_le_bytes()))?,
            PlyFormat::BinaryBigEndian => row.iter().try_for_each(|v| w.write_all(&v.to_be_bytes()))?,
            PlyFormat::Ascii => {
                line.clear();
                for (i, v) in row.iter().enumerate() {
                    if i > 0 {
                        line.push(' ');
                    }
                    // Rust's float Display is the shortest string that parses back exactly.
                    line += &v.to_string();
                }
                line.push('\n');
                w.write_all(line.as_bytes())?;
            }
        }
    }
    Ok(())
}
