//! `srug convert`: a scene from any format srug reads into any it writes.

use std::path::PathBuf;

use srug::io::{self, SceneFormat};
use srug::{Error, Result};

/// Arguments of `srug convert`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct ConvertArgs {
    /// The scene to read: PLY, compressed PLY, .splat, .spz, .sog / meta.json or .glb
    /// (detected from the content).
    input: PathBuf,
    /// The file to write; its format comes from `--format` or else its extension
    /// (.ply, .compressed.ply, .splat, .spz, .sog, .glb).
    output: PathBuf,
    /// Output format: ply, compressed-ply, splat, spz, sog (bundled) or glb.
    #[arg(long, value_parser = parse_format)]
    format: Option<SceneFormat>,
    /// The order to write the Gaussians in: file (as read) or morton (along a Morton curve through
    /// their centres, so neighbours in the file are neighbours in space: a trained scene's file
    /// is close to a random order, which splats markedly slower; docs/bench/splat.md).
    #[arg(long, value_enum, default_value = "file")]
    order: GaussianOrder,
}

/// The order `srug convert` writes Gaussians in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum GaussianOrder {
    /// As read.
    File,
    /// Along a Morton curve through the centres (`Scene::morton_order`).
    Morton,
}

fn parse_format(s: &str) -> std::result::Result<SceneFormat, String> {
    SceneFormat::parse(s).map_err(|e| e.to_string())
}

impl ConvertArgs {
    /// Runs `srug convert`.
    pub(super) fn run(&self) -> Result<()> {
        let format = match self.format {
            Some(f) => f,
            None => SceneFormat::from_extension(&self.output).filter(|f| f.writable()).ok_or_else(|| {
                Error::invalid(
                    format!("output {}", self.output.display()),
                    "its extension names no format srug writes; use .ply, .compressed.ply, .splat, .spz, .sog or .glb, or --format",
                )
            })?,
        };
        if format == SceneFormat::Sog && self.output.file_name().is_some_and(|n| n == "meta.json") {
            return Err(Error::invalid(
                format!("output {}", self.output.display()),
                "srug writes SOG bundled (one .sog file), not as meta.json beside its images",
            ));
        }
        if let Some(named) = SceneFormat::from_extension(&self.output) {
            if named != format {
                log::warn!("{}: writing {format} under an extension that says {named}", self.output.display());
            }
        }
        let mut scene = io::read_scene(&self.input)?;
        if self.order == GaussianOrder::Morton {
            scene = scene.permuted(&scene.morton_order());
        }
        for what in io::dropped_by(format, &scene) {
            log::warn!("{format} does not store {what}; they are not in {}", self.output.display());
        }
        io::write_scene(&self.output, &scene, format)?;
        println!("{} Gaussians (SH degree {}) -> {} ({format})", scene.len(), scene.sh_degree, self.output.display());
        Ok(())
    }
}
