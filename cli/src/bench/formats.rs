//! Scene-file load times and host memory per format: the same scene written
//! by srug in every format it writes (plus any files given), each read back
//! whole several times (wall clock, median), with the host's peak resident
//! memory during the read measured against the decoded scene's bytes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use srug::io::{self, SceneFormat};
use srug::scene::Scene;
use srug::Result;

/// One file's row of the table.
#[derive(Clone, Debug)]
pub struct FormatRow {
    /// What was read.
    pub label: String,
    /// Its format.
    pub format: SceneFormat,
    /// File bytes.
    pub file_bytes: u64,
    /// Gaussians in it.
    pub gaussians: usize,
    /// Seconds to write it (None for files given on the command line).
    pub write_seconds: Option<f64>,
    /// Median seconds to read it.
    pub read_seconds: f64,
    /// Host memory the read added at its peak over what was resident before,
    /// bytes (None where /proc cannot reset the peak).
    pub peak_bytes: Option<u64>,
    /// Bytes the decoded scene holds.
    pub scene_bytes: u64,
}

/// Bytes of a scene's arrays on the host.
pub fn scene_bytes(s: &Scene) -> u64 {
    (s.len() * s.floats_per_gaussian() * 4) as u64
}

/// Resident and peak resident bytes of this process (Linux).
fn rss() -> Option<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        line.split_whitespace().nth(1)?.parse::<u64>().ok().map(|kb| kb * 1024)
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

/// Reads `path` `repeats` times; the median time and the peak memory the read added.
fn time_read(path: &Path, repeats: usize) -> Result<(f64, Option<u64>, Scene)> {
    let mut times = Vec::new();
    let mut peak = None;
    let mut scene = None;
    for _ in 0..repeats.max(1) {
        drop(scene.take());
        // Writing 5 to clear_refs resets the peak-RSS counter (Linux 4.0+).
        let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
        let before = rss();
        let t = Instant::now();
        let s = io::read_scene(path)?;
        times.push(t.elapsed().as_secs_f64());
        if let (true, Some((rss0, _)), Some((_, hwm))) = (reset, before, rss()) {
            let added = hwm.saturating_sub(rss0);
            peak = Some(peak.map_or(added, |p: u64| p.min(added)));
        }
        scene = Some(s);
    }
    times.sort_by(f64::total_cmp);
    let scene = scene.ok_or_else(|| srug::Error::Internal("no read ran".into()))?;
    Ok((times[times.len() / 2], peak, scene))
}

/// Writes `scene` in every format srug writes into `dir`, then times reading each and each of `extra`.
pub fn format_bench(
    scene: &Scene,
    dir: &Path,
    extra: &[PathBuf],
    repeats: usize,
    mut progress: impl FnMut(&str),
) -> Result<Vec<FormatRow>> {
    let mut rows = Vec::new();
    let mut files: Vec<(PathBuf, Option<f64>)> = Vec::new();
    for format in SceneFormat::ALL.into_iter().filter(|f| f.writable()) {
        let ext = match format {
            SceneFormat::Ply => "ply",
            SceneFormat::CompressedPly => "compressed.ply",
            SceneFormat::Splat => "splat",
            SceneFormat::Spz => "spz",
            SceneFormat::Sog => "sog",
            SceneFormat::Glb => "glb",
        };
        let path = dir.join(format!("scene.{ext}"));
        progress(&format!("writing {format}"));
        let t = Instant::now();
        io::write_scene(&path, scene, format)?;
        files.push((path, Some(t.elapsed().as_secs_f64())));
    }
    files.extend(extra.iter().map(|p| (p.clone(), None)));
    for (path, write_seconds) in files {
        progress(&format!("reading {}", path.display()));
        let bytes = io::read_file(&path).map(|b| b.len() as u64)?;
        let (read_seconds, peak_bytes, back) = time_read(&path, repeats)?;
        let format = SceneFormat::detect(&io::read_file(&path)?).unwrap_or(SceneFormat::Ply);
        rows.push(FormatRow {
            label: path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
            format,
            file_bytes: bytes,
            gaussians: back.len(),
            write_seconds,
            read_seconds,
            peak_bytes,
            scene_bytes: scene_bytes(&back),
        });
    }
    Ok(rows)
}
