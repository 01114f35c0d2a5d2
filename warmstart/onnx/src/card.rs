//! Model cards: the JSON that travels with every `.onnx` file.
//!
//! A card says what the model reads and writes: the grid layout it was trained on (the grid
//! crate's layout JSON, verbatim), the channel order of its input and output, their shapes, and
//! how it was trained. [`ModelCard::check_layout`] compares a card with this build's layout and
//! names the first difference.

use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::OnnxError;

/// The `format` field every card carries.
pub const CARD_FORMAT: &str = "deepcontact-model-card";
/// The card format version this crate reads.
pub const CARD_FORMAT_VERSION: u32 = 1;

/// The input channels a residual model ([`ModelCard::residual`]) reads after the layout's:
/// the carried impulses, spread onto the grid as the labels are.
pub const RESIDUAL_CHANNELS: [&str; 2] = ["carried_normal", "carried_tangent"];

/// One tensor of the model as the card describes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TensorCard {
    /// The ONNX tensor name.
    pub name: String,
    /// Dimensions, NCHW (`-1` = dynamic).
    pub shape: Vec<i64>,
    /// Channel names, in order.
    pub channels: Vec<String>,
}

/// A model card (see `models/README.md` for the full format).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelCard {
    /// Always [`CARD_FORMAT`].
    pub format: String,
    /// Card format version ([`CARD_FORMAT_VERSION`]).
    pub format_version: u32,
    /// Model name (`pressure`, `peak`, ...).
    pub name: String,
    /// One-paragraph description of the architecture.
    #[serde(default)]
    pub architecture: String,
    /// Number of trainable parameters.
    #[serde(default)]
    pub parameters: u64,
    /// SHA-256 of the `.onnx` file the card describes, lower-case hex (default: absent, not
    /// checked). When present, loading a different model file with this card is an error
    /// ([`OnnxError::ModelHashMismatch`]): cards of models with the same shapes are otherwise
    /// interchangeable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_sha256: Option<String>,
    /// The grid layout the model was trained on (the grid crate's layout JSON).
    pub grid_layout: Value,
    /// The model's input.
    pub input: TensorCard,
    /// The model's output.
    pub output: TensorCard,
    /// Training facts (seeds, losses, epochs, wall time, hardware, versions); free-form.
    #[serde(default)]
    pub training: Value,
    /// Whether the model is residual (default false): it reads the carried impulses as two
    /// more input channels ([`RESIDUAL_CHANNELS`]) and predicts the *correction* to them, which
    /// the provider reads back at each contact and adds to that contact's carried impulse.
    #[serde(default)]
    pub residual: bool,
}

/// What this build's grid layout expects of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct LayoutExpectation {
    /// The layout as JSON (compared field by field with the card's `grid_layout`).
    pub json: Value,
    /// Input channel names, in order.
    pub input_channels: Vec<String>,
    /// Output channel names, in order.
    pub output_channels: Vec<String>,
    /// Grid nodes along x (columns, the last tensor dimension).
    pub nx: usize,
    /// Grid nodes along y (rows).
    pub ny: usize,
}

impl LayoutExpectation {
    /// Expected input shape `[1, C_in, ny, nx]`.
    pub fn input_shape(&self) -> Vec<i64> {
        vec![
            1,
            self.input_channels.len() as i64,
            self.ny as i64,
            self.nx as i64,
        ]
    }

    /// Expected output shape `[1, C_out, ny, nx]`.
    pub fn output_shape(&self) -> Vec<i64> {
        vec![
            1,
            self.output_channels.len() as i64,
            self.ny as i64,
            self.nx as i64,
        ]
    }
}

impl ModelCard {
    /// Parses a card from JSON text; `path` only names it in errors.
    pub fn from_json(text: &str, path: &Path) -> Result<Self, OnnxError> {
        let card: ModelCard = serde_json::from_str(text).map_err(|e| OnnxError::CardInvalid {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        if card.format != CARD_FORMAT {
            return Err(OnnxError::CardInvalid {
                path: path.to_path_buf(),
                reason: format!("format is `{}`, expected `{CARD_FORMAT}`", card.format),
            });
        }
        if card.format_version != CARD_FORMAT_VERSION {
            return Err(OnnxError::CardInvalid {
                path: path.to_path_buf(),
                reason: format!(
                    "format_version is {}, this build reads {CARD_FORMAT_VERSION}",
                    card.format_version
                ),
            });
        }
        Ok(card)
    }

    /// Reads a card from a file.
    pub fn load(path: &Path) -> Result<Self, OnnxError> {
        let text = std::fs::read_to_string(path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => OnnxError::CardMissing {
                path: path.to_path_buf(),
            },
            _ => OnnxError::Io {
                path: path.to_path_buf(),
                source: e,
            },
        })?;
        Self::from_json(&text, path)
    }

    /// Checks that `bytes` (the model file `path`) are the file the card was written for, when
    /// the card records its SHA-256.
    pub fn check_model_bytes(&self, bytes: &[u8], path: &Path) -> Result<(), OnnxError> {
        let Some(expected) = &self.model_sha256 else {
            return Ok(());
        };
        let found = sha256_hex(bytes);
        if !found.eq_ignore_ascii_case(expected.trim()) {
            return Err(OnnxError::ModelHashMismatch {
                path: path.to_path_buf(),
                card: self.name.clone(),
                expected: expected.clone(),
                found,
            });
        }
        Ok(())
    }

    /// What this build's `layout` expects of this card's model: the layout's channels, plus
    /// [`RESIDUAL_CHANNELS`] for a residual model.
    pub fn expectation(&self, layout: &LayoutExpectation) -> LayoutExpectation {
        let mut expected = layout.clone();
        if self.residual {
            expected
                .input_channels
                .extend(RESIDUAL_CHANNELS.map(String::from));
        }
        expected
    }

    /// Checks the card against this build's layout (with [`Self::expectation`]): channel names
    /// and order, shapes, and the grid layout JSON. The error names the first difference.
    pub fn check_layout(&self, layout: &LayoutExpectation) -> Result<(), OnnxError> {
        let layout = &self.expectation(layout);
        check_channels("input", &layout.input_channels, &self.input.channels)?;
        check_channels("output", &layout.output_channels, &self.output.channels)?;
        check_shape("card input", &layout.input_shape(), &self.input.shape)?;
        check_shape("card output", &layout.output_shape(), &self.output.shape)?;
        if let Some((field, expected, found)) =
            first_difference("grid_layout", &layout.json, &self.grid_layout)
        {
            return Err(OnnxError::GridMismatch {
                field,
                expected,
                found,
            });
        }
        Ok(())
    }
}

fn check_channels(
    tensor: &'static str,
    expected: &[String],
    found: &[String],
) -> Result<(), OnnxError> {
    for (index, (e, f)) in expected.iter().zip(found).enumerate() {
        if e != f {
            return Err(OnnxError::ChannelMismatch {
                tensor,
                index,
                expected: e.clone(),
                found: f.clone(),
            });
        }
    }
    if expected.len() != found.len() {
        return Err(OnnxError::ChannelCount {
            tensor,
            expected: expected.len(),
            found: found.len(),
        });
    }
    Ok(())
}

/// Checks a shape; a `-1` in `found` (a dynamic dimension) matches anything.
pub(crate) fn check_shape(what: &str, expected: &[i64], found: &[i64]) -> Result<(), OnnxError> {
    let ok = expected.len() == found.len()
        && expected.iter().zip(found).all(|(e, f)| *f == -1 || e == f);
    if ok {
        Ok(())
    } else {
        Err(OnnxError::ShapeMismatch {
            what: what.to_string(),
            expected: expected.to_vec(),
            found: found.to_vec(),
        })
    }
}

/// The JSON path and both values of the first difference between two JSON values, if any.
/// Numbers compare with a relative tolerance of 1e-9 (a layout written by Python round-trips).
pub(crate) fn first_difference(
    path: &str,
    expected: &Value,
    found: &Value,
) -> Option<(String, String, String)> {
    let differ = || Some((path.to_string(), expected.to_string(), found.to_string()));
    match (expected, found) {
        (Value::Object(e), Value::Object(f)) => {
            for (k, ev) in e {
                let sub = format!("{path}.{k}");
                match f.get(k) {
                    Some(fv) => {
                        if let Some(d) = first_difference(&sub, ev, fv) {
                            return Some(d);
                        }
                    }
                    None => return Some((sub, ev.to_string(), "nothing".into())),
                }
            }
            f.keys()
                .find(|k| !e.contains_key(*k))
                .map(|k| (format!("{path}.{k}"), "nothing".into(), f[k].to_string()))
        }
        (Value::Array(e), Value::Array(f)) => {
            for (i, (ev, fv)) in e.iter().zip(f).enumerate() {
                if let Some(d) = first_difference(&format!("{path}[{i}]"), ev, fv) {
                    return Some(d);
                }
            }
            if e.len() != f.len() {
                return Some((
                    format!("{path}.len()"),
                    e.len().to_string(),
                    f.len().to_string(),
                ));
            }
            None
        }
        (Value::Number(e), Value::Number(f)) => match (e.as_f64(), f.as_f64()) {
            (Some(a), Some(b)) if (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0) => None,
            _ => differ(),
        },
        (e, f) if e == f => None,
        _ => differ(),
    }
}

/// Lower-case hex SHA-256 of `bytes` (the `model_sha256` of a card).
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn first_difference_names_the_path() {
        let a = json!({"nx": 61, "channels": ["mass", "vx"], "h": 0.5});
        let b = json!({"nx": 61, "channels": ["mass", "vy"], "h": 0.5});
        let (field, e, f) = first_difference("grid_layout", &a, &b).unwrap();
        assert_eq!(field, "grid_layout.channels[1]");
        assert_eq!((e.as_str(), f.as_str()), ("\"vx\"", "\"vy\""));
        assert!(first_difference("g", &a, &a).is_none());
        let c = json!({"nx": 61, "channels": ["mass", "vx"], "h": 0.5000000000001});
        assert!(first_difference("g", &a, &c).is_none());
    }

    #[test]
    fn shapes_accept_dynamic_dims() {
        assert!(check_shape("x", &[1, 6, 61, 61], &[-1, 6, 61, 61]).is_ok());
        assert!(check_shape("x", &[1, 6, 61, 61], &[1, 6, 61]).is_err());
        assert!(check_shape("x", &[1, 6, 61, 61], &[1, 6, 61, 60]).is_err());
    }
}
