//! `srug bench formats`: load time, file size and host memory of a scene in
//! every format (no GPU).

use std::path::PathBuf;

use srug::scene::demo::{demo_city, DemoOptions};
use srug::Result;

use crate::args::spinner;
use crate::bench;

/// Arguments of `srug bench formats`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct FormatBenchArgs {
    /// Gaussians in the demo city written in every format.
    #[arg(long, default_value_t = 1_000_000)]
    gaussians: usize,
    /// SH degree of the scene.
    #[arg(long, default_value_t = 3)]
    sh_degree: u32,
    /// Reads per file (median reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// More scene files to time (for example a SOG another tool wrote).
    #[arg(long, value_delimiter = ',')]
    files: Vec<PathBuf>,
    /// Internal: read this one file and print seconds, baseline and peak memory (what each timed read runs).
    #[arg(long, hide = true)]
    measure_read: Option<PathBuf>,
}

impl FormatBenchArgs {
    /// Runs `srug bench formats`.
    pub(crate) fn run(&self) -> Result<()> {
        if let Some(path) = &self.measure_read {
            return bench::formats::measure_read(path);
        }
        let bar = spinner("generating the demo city");
        let mut city = demo_city(&DemoOptions { seed: 7, gaussians: self.gaussians, sh_degree: self.sh_degree })?;
        // Colour-only formats keep none of the relighting attributes; time the plain scene in all.
        city.scene.materials = Default::default();
        city.scene.normals = None;
        let dir = tempfile_dir()?;
        let rows = bench::formats::format_bench(&city.scene, &dir, &self.files, self.repeats, |m| {
            bar.set_message(m.to_string())
        });
        let _ = std::fs::remove_dir_all(&dir);
        let rows = rows?;
        bar.finish_and_clear();
        println!(
            "{} Gaussians, SH degree {}; scene {:.1} MiB on the host\n",
            city.scene.len(),
            city.scene.sh_degree,
            bench::formats::scene_bytes(&city.scene) as f64 / 1048576.0
        );
        println!("| file | format | Gaussians | MiB | bytes/Gaussian | write s | read s (median) | M Gaussians/s | read peak / scene |");
        println!("|---|---|---:|---:|---:|---:|---:|---:|---:|");
        for r in &rows {
            println!(
                "| {} | {} | {} | {:.1} | {:.1} | {} | {:.3} | {:.2} | {} |",
                r.label,
                r.format,
                r.gaussians,
                r.file_bytes as f64 / 1048576.0,
                r.file_bytes as f64 / r.gaussians.max(1) as f64,
                r.write_seconds.map_or("-".into(), |s| format!("{s:.2}")),
                r.read_seconds,
                r.gaussians as f64 / r.read_seconds / 1e6,
                r.peak_bytes.map_or("-".into(), |p| format!("{:.2}x", p as f64 / r.scene_bytes.max(1) as f64)),
            );
        }
        Ok(())
    }
}

fn tempfile_dir() -> Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("srug-bench-formats-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(srug::Error::io(&dir))?;
    Ok(dir)
}
