//! The crate's error type.

use std::path::PathBuf;

/// Errors from loading and checking a graph warm-start model.
#[derive(Debug, thiserror::Error)]
pub enum GraphError {
    /// Reading a file failed.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The weights file is not a safetensors file of this model format.
    #[error("model {path}: {reason}")]
    Format {
        /// The weights file (or `<embedded>`).
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A weight tensor is missing, has the wrong dtype or shape, or holds a non-finite value.
    #[error("model {path}: tensor `{name}` {reason}")]
    Tensor {
        /// The weights file (or `<embedded>`).
        path: PathBuf,
        /// The tensor's name.
        name: String,
        /// What is wrong (expected and found shape, dtype, value).
        reason: String,
    },
    /// The model card is missing, not valid JSON, or of another format.
    #[error("model card {path}: {reason}")]
    Card {
        /// The card file (or `<embedded>`).
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The weights file is not the one its card was written for.
    #[error(
        "model {path} is not the model of its card: SHA-256 {found} differs from the card's {expected}"
    )]
    HashMismatch {
        /// The weights file.
        path: PathBuf,
        /// The card's `sha256`.
        expected: String,
        /// SHA-256 of the file.
        found: String,
    },
}
