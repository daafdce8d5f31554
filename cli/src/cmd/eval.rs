//! `srug eval`: PSNR and SSIM of rendered images against references (the
//! paper's relighting metrics): two files, or two folders paired by name.

use std::path::{Path, PathBuf};

use srug::{Error, Result};

/// Arguments of `srug eval`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct EvalArgs {
    /// Reference image or folder (.png, .exr, .hdr).
    reference: PathBuf,
    /// Rendered image or folder.
    rendered: PathBuf,
    /// Peak value (data range): 1 for PNGs; for linear EXR, the value that counts as white.
    #[arg(long, default_value_t = 1.0)]
    peak: f64,
    /// Also write the per-image figures as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
}

impl EvalArgs {
    /// Runs `srug eval`.
    pub(super) fn run(&self) -> Result<()> {
        evaluate(&self.reference, &self.rendered, self.peak, self.csv.as_deref())
    }
}

/// Image pairs for `srug eval`: two files, or the images of two folders matched by file stem.
fn eval_pairs(reference: &Path, rendered: &Path) -> Result<Vec<(String, PathBuf, PathBuf)>> {
    let is_image = |p: &Path| {
        matches!(
            p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(),
            Some("png" | "exr" | "hdr")
        )
    };
    if reference.is_file() && rendered.is_file() {
        let name = rendered.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        return Ok(vec![(name, reference.to_path_buf(), rendered.to_path_buf())]);
    }
    if !(reference.is_dir() && rendered.is_dir()) {
        return Err(Error::invalid(
            format!("{} and {}", reference.display(), rendered.display()),
            "must both be image files or both be folders",
        ));
    }
    let list = |dir: &Path| -> Result<Vec<PathBuf>> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(Error::io(dir))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| is_image(p))
            .collect();
        v.sort();
        Ok(v)
    };
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let refs = list(reference)?;
    let mut pairs = Vec::new();
    for r in list(rendered)? {
        if let Some(q) = refs.iter().find(|q| stem(q) == stem(&r)) {
            pairs.push((stem(&r), q.clone(), r));
        } else {
            eprintln!("warning: {} has no reference in {}", r.display(), reference.display());
        }
    }
    if pairs.is_empty() {
        return Err(Error::invalid(
            rendered.display().to_string(),
            format!("no image has a reference of the same name in {}", reference.display()),
        ));
    }
    Ok(pairs)
}

/// `srug eval`: PSNR and SSIM per image pair and their means.
fn evaluate(reference: &Path, rendered: &Path, peak: f64, csv: Option<&Path>) -> Result<()> {
    if !(peak > 0.0 && peak.is_finite()) {
        return Err(Error::invalid(format!("--peak {peak}"), "must be positive"));
    }
    let mut rows = Vec::new();
    println!("| image | PSNR (dB) | SSIM |\n|---|---:|---:|");
    for (name, r, q) in eval_pairs(reference, rendered)? {
        let (a, b) = (srug::metrics::read_image(&r)?, srug::metrics::read_image(&q)?);
        let pair = format!("{} against {}", q.display(), r.display());
        let context = |e: Error| match e {
            Error::InvalidArgument { what, why } => Error::invalid(format!("{pair}: {what}"), why),
            other => Error::invalid(pair.clone(), other.to_string()),
        };
        let p = srug::metrics::psnr(&a, &b, peak).map_err(context)?;
        let s = srug::metrics::ssim(&a, &b, peak).map_err(context)?;
        println!("| {name} | {p:.3} | {s:.4} |");
        rows.push((name, p, s));
    }
    let n = rows.len() as f64;
    // The mean PSNR of identical pairs is infinite; say so rather than average it away.
    let mean_p = rows.iter().map(|r| r.1).sum::<f64>() / n;
    let mean_s = rows.iter().map(|r| r.2).sum::<f64>() / n;
    println!("| mean of {} | {mean_p:.3} | {mean_s:.4} |", rows.len());
    if let Some(path) = csv {
        let mut text = String::from("image,psnr_db,ssim\n");
        for (name, p, s) in &rows {
            text += &format!("{name},{p},{s}\n");
        }
        srug::io::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}
