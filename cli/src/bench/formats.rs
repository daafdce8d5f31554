//! Scene-file load times and host memory per format: the same scene written
//! by srug in every format it writes (plus any files given), each read back
//! several times, each in a fresh child process (wall clock, median), with
//! the peak resident memory the read added to that process measured against
//! the decoded scene's bytes.

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
pub fn rss() -> Option<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        line.split_whitespace().nth(1)?.parse::<u64>().ok().map(|kb| kb * 1024)
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

/// Reads `path` once in this process and prints `seconds baseline_bytes peak_bytes`: what
/// `srug bench formats --measure-read` runs in a fresh child, so the peak is the read's own.
pub fn measure_read(path: &Path) -> Result<()> {
    let (baseline, _) = rss().unwrap_or((0, 0));
    let t = Instant::now();
    let scene = io::read_scene(path)?;
    let seconds = t.elapsed().as_secs_f64();
    let (_, peak) = rss().unwrap_or((0, 0));
    println!("{seconds} {baseline} {peak} {}", scene_bytes(&scene));
    Ok(())
}

/// Reads `path` `repeats` times, each in a fresh child process; the median
/// time, the smallest peak memory a read added, and the decoded scene's bytes.
fn time_read(path: &Path, repeats: usize) -> Result<(f64, Option<u64>, u64, usize)> {
    let exe = std::env::current_exe().map_err(|e| srug::Error::Internal(format!("no path to srug: {e}")))?;
    let mut times = Vec::new();
    let mut peak: Option<u64> = None;
    let mut bytes = 0;
    for _ in 0..repeats.max(1) {
        let out = std::process::Command::new(&exe)
            .args(["bench", "formats", "--measure-read"])
            .arg(path)
            .output()
            .map_err(|e| srug::Error::Internal(format!("cannot run srug: {e}")))?;
        let text = String::from_utf8_lossy(&out.stdout);
        let v: Vec<f64> = text.split_whitespace().filter_map(|w| w.parse().ok()).collect();
        if !out.status.success() || v.len() != 4 {
            return Err(srug::Error::Internal(format!(
                "reading {} in a child failed: {}",
                path.display(),
                String::from_utf8_lossy(&out.stderr)
            )));
        }
        times.push(v[0]);
        if v[2] > 0.0 {
            let added = (v[2] - v[1]).max(0.0) as u64;
            peak = Some(peak.map_or(added, |p| p.min(added)));
        }
        bytes = v[3] as u64;
    }
    times.sort_by(f64::total_cmp);
    let back = io::read_scene(path)?.len();
    Ok((times[times.len() / 2], peak, bytes, back))
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
        let (read_seconds, peak_bytes, decoded_bytes, gaussians) = time_read(&path, repeats)?;
        let format = SceneFormat::detect(&io::read_file(&path)?).unwrap_or(SceneFormat::Ply);
        rows.push(FormatRow {
            label: path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
            format,
            file_bytes: bytes,
            gaussians,
            write_seconds,
            read_seconds,
            peak_bytes,
            scene_bytes: decoded_bytes,
        });
    }
    Ok(rows)
}
