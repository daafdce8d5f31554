//! Atomic writes: every writer writes a temporary file beside its target and
//! renames it, so a failure leaves nothing behind.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

pub(crate) fn temp_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

pub(crate) fn finish(tmp: &Path, path: &Path, written: Result<()>) -> Result<()> {
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
