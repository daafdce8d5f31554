//! Atomic writes: every writer writes a temporary file beside its target and
//! renames it, so a failure leaves nothing behind.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

pub(crate) fn temp_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

pub(crate) fn finish(tmp: &Path, path: &Path, written: Result<()>) -> Result<()> {
    // Errors name the output the caller asked for, never the hidden temporary file.
    let written = written.map_err(|e| match e {
        Error::Io { path: p, source } if p == tmp => Error::Io { path: path.to_path_buf(), source },
        other => other,
    });
    let result = written.and_then(|()| std::fs::rename(tmp, path).map_err(Error::io(path)));
    if result.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    result
}

/// Writes `bytes` to `path` through a temporary file beside it.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = temp_beside(path);
    let written = std::fs::write(&tmp, bytes).map_err(Error::io(&tmp));
    finish(&tmp, path, written)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    /// A write that fails names the output path, not the temporary file, and leaves nothing.
    #[test]
    fn failures_name_the_output_and_leave_nothing() {
        let dir = std::env::temp_dir().join(format!("srug-atomic-{}", std::process::id()));
        let missing = dir.join("no-such-folder").join("a.png");
        let e = write_atomic(&missing, b"x").unwrap_err().to_string();
        assert!(e.contains("no-such-folder/a.png") && !e.contains(".tmp-"), "{e}");
        assert!(!missing.exists());
    }
}
