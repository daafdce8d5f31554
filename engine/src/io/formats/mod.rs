//! Every common splat scene format, detected from content, read into a
//! [`Scene`] and written back.
//!
//! | format | detected by | what it keeps |
//! |---|---|---|
//! | INRIA PLY | `ply` + header | everything, f32 (relighting attributes too) |
//! | compressed PLY (SuperSplat) | `ply` + a `chunk` element | per 256 Gaussians: position 11/10/11 bits and log scale 11/10/11 bits of the chunk's range, rotation 3×10 bits, colour and opacity 8 bits, SH 8 bits over −4..4 |
//! | `.splat` (antimatter15) | no magic: whole 32-byte rows with finite positions and positive scales | f32 position and scale, 8-bit colour, opacity and rotation, no SH beyond degree 0 |
//! | `.spz` (Niantic, versions 1-4) | gzip magic or `NGSP` | position 24-bit fixed point (2^-12 m by default), log scale 1/16, rotation 3×9 bits (v3+), colour and opacity 8 bits, SH 8 bits (5 and 4 significant bits as written) |
//! | SOG v2 (PlayCanvas) | ZIP magic, or a `meta.json` | position 16 bits of a log range, rotation 3×8 bits, scale, colour and SH through 256-entry codebooks and a palette (written: at most 4096 entries) |
//! | GLB `KHR_gaussian_splatting` | `glTF` magic | f32 everything (normalized integer rotation/scale/opacity read too) |
//!
//! Invariants: detection looks at the content only; a file whose extension
//! names another format is read as what it is, with a warning. Every reader
//! bounds what it allocates by the file's real size and [`crate::io::Limits`]
//! before allocating, and returns a validated scene or an error naming the
//! file, the format and the field; nothing partial.

mod compressed_ply;
mod frame;
mod glb;
mod sog;
mod splat;
mod spz;

use std::path::Path;

use crate::error::{Error, Result};
use crate::scene::{Scene, SceneError};

/// A scene of `n` Gaussians with room for them: SH zeroed (decoders write it
/// by index), the other arrays empty with capacity `n` (decoders push).
fn decoding_scene(n: usize, sh_degree: u32) -> Scene {
    Scene {
        means: Vec::with_capacity(n),
        normals: None,
        sh_degree,
        sh: vec![0.0; n * crate::scene::sh_coefficients(sh_degree) * 3],
        opacity_logits: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
        materials: crate::scene::Materials::default(),
        extra_properties: Vec::new(),
    }
}

/// The scene file formats srug reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SceneFormat {
    /// INRIA 3DGS PLY (binary little endian when written).
    Ply,
    /// PlayCanvas SuperSplat compressed PLY.
    CompressedPly,
    /// antimatter15 `.splat`.
    Splat,
    /// Niantic `.spz` (written as version 4).
    Spz,
    /// PlayCanvas SOG version 2 (written bundled).
    Sog,
    /// Binary glTF with `KHR_gaussian_splatting`.
    Glb,
}

impl SceneFormat {
    /// Every format.
    pub const ALL: [SceneFormat; 6] = [Self::Ply, Self::CompressedPly, Self::Splat, Self::Spz, Self::Sog, Self::Glb];

    /// The format's name as messages and `--help` spell it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ply => "PLY",
            Self::CompressedPly => "compressed PLY",
            Self::Splat => ".splat",
            Self::Spz => "SPZ",
            Self::Sog => "SOG",
            Self::Glb => "GLB",
        }
    }

    /// The format named as `srug convert --format` spells it: ply, compressed-ply,
    /// splat, spz, sog or glb.
    pub fn parse(name: &str) -> Result<SceneFormat> {
        Ok(match name {
            "ply" => Self::Ply,
            "compressed-ply" => Self::CompressedPly,
            "splat" => Self::Splat,
            "spz" => Self::Spz,
            "glb" => Self::Glb,
            "sog" => Self::Sog,
            _ => {
                return Err(Error::invalid(
                    format!("format \"{name}\""),
                    "is unknown (ply, compressed-ply, splat, spz, sog, glb)",
                ))
            }
        })
    }

    /// Whether srug can write it (every format it reads).
    pub fn writable(self) -> bool {
        true
    }

    /// The format a file name's extension names (`.compressed.ply` before
    /// `.ply`; `meta.json` is an unbundled SOG).
    pub fn from_extension(path: &Path) -> Option<SceneFormat> {
        let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
        let ext = |e: &str| name.ends_with(e);
        Some(if ext(".compressed.ply") {
            Self::CompressedPly
        } else if ext(".ply") {
            Self::Ply
        } else if ext(".splat") {
            Self::Splat
        } else if ext(".spz") {
            Self::Spz
        } else if ext(".sog") || name == "meta.json" {
            Self::Sog
        } else if ext(".glb") {
            Self::Glb
        } else {
            return None;
        })
    }

    /// The format of `bytes`, from their content alone.
    pub fn detect(bytes: &[u8]) -> Option<SceneFormat> {
        if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
            let end = bytes.windows(10).position(|w| w == b"end_header").unwrap_or(bytes.len().min(1 << 16));
            let header = String::from_utf8_lossy(&bytes[..end]);
            return Some(if compressed_ply::is_compressed_header(&header) { Self::CompressedPly } else { Self::Ply });
        }
        if bytes.starts_with(b"NGSP") || bytes.starts_with(&[0x1f, 0x8b]) {
            return Some(Self::Spz);
        }
        if bytes.starts_with(b"glTF") {
            return Some(Self::Glb);
        }
        if bytes.starts_with(b"PK\x03\x04") {
            return Some(Self::Sog);
        }
        let text = bytes.iter().position(|b| !b.is_ascii_whitespace()).map(|i| &bytes[i..]);
        if text.is_some_and(|t| t.starts_with(b"{")) && bytes.windows(7).any(|w| w == b"\"means\"") {
            return Some(Self::Sog);
        }
        if splat::plausible(bytes) {
            return Some(Self::Splat);
        }
        None
    }
}

impl std::fmt::Display for SceneFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Reads a scene in any format srug reads, detected from the content; an
/// extension that names another format is reported as a warning.
pub fn read_scene(path: impl AsRef<Path>) -> Result<Scene> {
    let path = path.as_ref();
    if let Some(format @ (SceneFormat::Ply | SceneFormat::Glb)) = prefix_format(path) {
        // Uncompressed formats stream from disk: one copy of the scene on the host, not the file and the scene.
        warn_if_misnamed(path, format);
        return if format == SceneFormat::Ply { super::read_ply(path) } else { glb::read_path(path) };
    }
    let bytes = super::read_file(path)?;
    let origin = path.display().to_string();
    let format = SceneFormat::detect(&bytes).ok_or_else(|| {
        SceneError::file(&origin, "not a scene file srug reads (PLY, compressed PLY, .splat, SPZ, SOG or GLB)")
    })?;
    warn_if_misnamed(path, format);
    if format == SceneFormat::Sog && !bytes.starts_with(b"PK") {
        // An unbundled SOG: meta.json with the images beside it.
        let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        let mut load = |name: &str| -> std::result::Result<Vec<u8>, SceneError> {
            let file = Path::new(name);
            if file.is_absolute() || file.components().any(|c| matches!(c, std::path::Component::ParentDir)) {
                return Err(SceneError::file(
                    &origin,
                    format!("SOG: image path \"{name}\" leaves the folder of meta.json"),
                ));
            }
            super::read_file(dir.join(file)).map_err(|e| SceneError::file(&origin, format!("SOG: {e}")))
        };
        return Ok(sog::read_with(&bytes, &mut load, &origin)?);
    }
    Ok(read_scene_as(&bytes, format, &origin)?)
}

/// The format of a regular file whose first 64 KiB identify it as an INRIA PLY
/// (not the compressed layout) or a GLB; `None` otherwise.
fn prefix_format(path: &Path) -> Option<SceneFormat> {
    use std::io::Read;
    let file = std::fs::File::open(path).ok()?;
    let meta = file.metadata().ok()?;
    if !meta.is_file() || meta.len() > super::limits().max_file_bytes {
        return None;
    }
    let mut prefix = Vec::with_capacity(1 << 16);
    file.take(1 << 16).read_to_end(&mut prefix).ok()?;
    if prefix.starts_with(b"glTF") {
        return Some(SceneFormat::Glb);
    }
    SceneFormat::detect(&prefix).filter(|f| *f == SceneFormat::Ply)
}

/// Reads a scene held in memory (any format but an unbundled SOG, whose
/// images are separate files); `origin` names it in errors.
pub fn read_scene_bytes(bytes: &[u8], origin: &str) -> std::result::Result<Scene, SceneError> {
    let format = SceneFormat::detect(bytes).ok_or_else(|| {
        SceneError::file(origin, "not a scene file srug reads (PLY, compressed PLY, .splat, SPZ, SOG or GLB)")
    })?;
    read_scene_as(bytes, format, origin)
}

/// Reads the scene at `path` in blocks ([`super::read_ply_blocks`]): an
/// INRIA PLY (detected from its content, as [`read_scene`] does) streams in
/// blocks of about `block_bytes` of the file, so the host never holds it
/// whole; every other format is read whole and given as one block.
pub fn read_scene_blocks(
    path: impl AsRef<Path>,
    block_bytes: usize,
    mut on_block: impl FnMut(&super::PlyBlock<'_>) -> Result<()>,
) -> Result<()> {
    let path = path.as_ref();
    if prefix_format(path) == Some(SceneFormat::Ply) {
        warn_if_misnamed(path, SceneFormat::Ply);
        return super::read_ply_blocks(path, block_bytes, on_block);
    }
    let scene = read_scene(path)?;
    on_block(&super::PlyBlock { total: scene.len(), first: 0, gaussians: &scene })
}

/// Warns where `path`'s extension names another format than its content's.
fn warn_if_misnamed(path: &Path, format: SceneFormat) {
    if let Some(named) = SceneFormat::from_extension(path).filter(|f| *f != format) {
        log::warn!(
            "{}: the extension says {named} but the content is {format}; reading it as {format}",
            path.display()
        );
    }
}

/// Reads `bytes` as `format`.
pub fn read_scene_as(bytes: &[u8], format: SceneFormat, origin: &str) -> std::result::Result<Scene, SceneError> {
    match format {
        SceneFormat::Ply => super::read_ply_bytes(bytes, origin),
        SceneFormat::CompressedPly => compressed_ply::read(bytes, origin),
        SceneFormat::Splat => splat::read(bytes, origin),
        SceneFormat::Spz => spz::read(bytes, origin),
        SceneFormat::Sog if bytes.starts_with(b"PK") => sog::read_bundle(bytes, origin),
        SceneFormat::Sog => {
            Err(SceneError::file(origin, "SOG: an unbundled meta.json must be read from its folder (read_scene)"))
        }
        SceneFormat::Glb => glb::read(bytes, origin),
    }
}

/// What `format` drops of `scene` (SH bands, relighting attributes), in words; empty when nothing.
pub fn dropped_by(format: SceneFormat, scene: &Scene) -> Vec<String> {
    let mut out = Vec::new();
    if format == SceneFormat::Ply {
        return out;
    }
    if format == SceneFormat::Splat && scene.sh_degree > 0 {
        out.push(format!("SH bands 1 to {} (.splat stores colour only)", scene.sh_degree));
    }
    let groups = scene.attributes().names();
    if !groups.is_empty() {
        out.push(format!("relighting attributes ({})", groups.join(", ")));
    }
    out
}

/// Encodes a scene as `format` (validated first).
pub fn encode_scene(scene: &Scene, format: SceneFormat) -> Result<Vec<u8>> {
    scene.validate("scene to write")?;
    let refuse = |why: String| Error::invalid(format!("{format} output"), why);
    match format {
        SceneFormat::Ply => {
            let mut out = Vec::new();
            super::ply::write_ply_into(&mut out, scene, super::PlyFormat::BinaryLittleEndian, &[])
                .map_err(|e| Error::Internal(format!("writing PLY to memory: {e}")))?;
            Ok(out)
        }
        SceneFormat::CompressedPly => Ok(compressed_ply::encode(scene)),
        SceneFormat::Splat => Ok(splat::encode(scene)),
        SceneFormat::Spz => spz::encode(scene).map_err(refuse),
        SceneFormat::Glb => glb::encode(scene).map_err(refuse),
        SceneFormat::Sog => sog::encode(scene).map_err(refuse),
    }
}

/// Writes a scene as `format`, atomically (nothing is left at `path` on failure).
pub fn write_scene(path: impl AsRef<Path>, scene: &Scene, format: SceneFormat) -> Result<()> {
    let path = path.as_ref();
    if format == SceneFormat::Ply {
        return super::write_ply(path, scene, super::PlyFormat::BinaryLittleEndian);
    }
    let bytes = encode_scene(scene, format)?;
    super::write_atomic(path, &bytes)
}
