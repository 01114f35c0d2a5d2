//! Files that are either the old version or the complete new one, never half written.

use std::io::Write as _;
use std::path::Path;

use crate::ExperimentError;

/// Writes `bytes` to `path` through a temporary file in the same directory (named after
/// `path`, ending in the same extension, so encoders that look at it still work) and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    write_atomic_with(path, |tmp| {
        let mut f = std::fs::File::create(tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })
}

/// Creates `dir` and writes each `(name, bytes)` into it with [`write_atomic`]; returns the
/// paths written, in order.
pub fn write_files<'a>(
    dir: &Path,
    files: impl IntoIterator<Item = (&'a str, Vec<u8>)>,
) -> Result<Vec<std::path::PathBuf>, ExperimentError> {
    std::fs::create_dir_all(dir).map_err(|e| ExperimentError::io(dir, e))?;
    files
        .into_iter()
        .map(|(name, bytes)| {
            let path = dir.join(name);
            write_atomic(&path, &bytes)?;
            Ok(path)
        })
        .collect()
}

/// `value` as pretty JSON with a final newline; `what` names the file in the error.
pub fn json_bytes(value: &serde_json::Value, what: &str) -> Result<Vec<u8>, ExperimentError> {
    serde_json::to_string_pretty(value)
        .map(|json| (json + "\n").into_bytes())
        .map_err(|e| ExperimentError::Invalid(format!("{what}: {e}")))
}

/// `label` with every character but ASCII letters, digits, `-` and `_` replaced by `_`: a
/// file name (figures named after a solver or scene spec).
pub fn file_safe(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The temporary name `path` is written under before the rename.
pub fn temporary_path(path: &Path) -> std::path::PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".tmp-{}-{name}", std::process::id()))
}

/// Lets `write` produce the file at a temporary path, then renames it to `path`; on any
/// failure the temporary file is removed and `path` is untouched.
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&Path) -> std::io::Result<()>,
) -> Result<(), ExperimentError> {
    let tmp = temporary_path(path);
    if let Err(e) = write(&tmp).and_then(|_| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(ExperimentError::io(path, e));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = std::env::temp_dir().join(format!("dc-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.txt");
        write_atomic(&path, b"old").unwrap();
        let failed = write_atomic_with(&path, |tmp| {
            std::fs::write(tmp, b"half")?;
            Err(std::io::Error::other("disk full"))
        });
        assert!(matches!(failed, Err(ExperimentError::Io { .. })));
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert!(!temporary_path(&path).exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
