//! Model cards: what a weights file is, how it was trained, and its SHA-256.

use std::path::Path;

use crate::GraphError;
use crate::model::Architecture;

/// The `format` field of a card.
pub const CARD_FORMAT: &str = "deepcontact-graph-card";

/// The fields of a card (`<model>.json`, written by `models/train/graph.py`) that loading
/// checks; the rest (training history, hyperparameters) is for people.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
pub struct GraphCard {
    /// Always [`CARD_FORMAT`].
    pub format: String,
    /// Model name.
    pub name: String,
    /// Lower-case hex SHA-256 of the weights file.
    pub sha256: String,
    /// The model's shape (must equal the weights file's).
    pub architecture: Architecture,
    /// The loss it was trained with.
    pub loss: String,
    /// Training seeds (the seeds grammar).
    pub train_seeds: String,
    /// Validation seeds.
    pub validation_seeds: String,
}

impl GraphCard {
    /// Parses a card (`path` labels errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, GraphError> {
        let bad = |reason: String| GraphError::Card {
            path: path.to_path_buf(),
            reason,
        };
        // The format first, so that another kind of card is named as such.
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        match value.get("format").and_then(|f| f.as_str()) {
            Some(CARD_FORMAT) => {}
            Some(other) => return Err(bad(format!("format `{other}`, not `{CARD_FORMAT}`"))),
            None => {
                return Err(bad(format!(
                    "no `format` field (a graph card has `{CARD_FORMAT}`)"
                )));
            }
        }
        serde_json::from_value(value).map_err(|e| bad(e.to_string()))
    }

    /// Checks that `bytes` (the weights file at `path`) is the file this card describes.
    pub fn check(&self, bytes: &[u8], path: &Path) -> Result<(), GraphError> {
        let found = sha256_hex(bytes);
        if found != self.sha256 {
            return Err(GraphError::HashMismatch {
                path: path.to_path_buf(),
                expected: self.sha256.clone(),
                found,
            });
        }
        Ok(())
    }
}

/// Lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
