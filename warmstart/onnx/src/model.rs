//! A checked ONNX model: one session, its card, and the shapes it was verified against.

use std::path::{Path, PathBuf};

use ort::session::Session;
use ort::value::{TensorElementType, TensorRef};

use crate::backend::{self, Backend};
use crate::card::{LayoutExpectation, ModelCard, check_shape};
use crate::error::OnnxError;

/// An ONNX model whose card and tensor shapes match the grid layout, with one backend
/// session that is reused for every call.
#[derive(Debug)]
pub struct OnnxModel {
    session: Session,
    card: ModelCard,
    backend: Backend,
    path: PathBuf,
    input_shape: [usize; 4],
    output_len: usize,
}

/// Where a model comes from.
#[derive(Debug, Clone, Copy)]
pub enum ModelSource<'a> {
    /// A `.onnx` file; the card is read from `card`, or from the same path with `.json`.
    Files {
        /// The model file.
        model: &'a Path,
        /// The card file (default: `model` with the extension `.json`).
        card: Option<&'a Path>,
    },
    /// Model bytes and card text in memory (e.g. `include_bytes!`); `name` labels errors.
    Memory {
        /// ONNX protobuf bytes.
        model: &'a [u8],
        /// Card JSON.
        card: &'a str,
        /// Label used in error messages.
        name: &'a str,
    },
}

impl OnnxModel {
    /// Loads a model and its card, and checks both against `layout`:
    /// card channels and shapes, card grid layout, then the model's real input/output
    /// shapes and element types. Any difference is a typed error naming it.
    pub fn load(
        source: ModelSource<'_>,
        backend: Backend,
        layout: &LayoutExpectation,
    ) -> Result<Self, OnnxError> {
        let (bytes, card, path): (std::borrow::Cow<'_, [u8]>, ModelCard, PathBuf) = match source {
            ModelSource::Files { model, card } => {
                let card_path = card
                    .map(Path::to_path_buf)
                    .unwrap_or_else(|| model.with_extension("json"));
                if !model.exists() {
                    return Err(OnnxError::ModelMissing {
                        path: model.to_path_buf(),
                    });
                }
                let card = ModelCard::load(&card_path)?;
                card.check_layout(layout)?;
                let bytes = std::fs::read(model).map_err(|e| match e.kind() {
                    std::io::ErrorKind::NotFound => OnnxError::ModelMissing {
                        path: model.to_path_buf(),
                    },
                    _ => OnnxError::Io {
                        path: model.to_path_buf(),
                        source: e,
                    },
                })?;
                card.check_model_bytes(&bytes, model)?;
                (bytes.into(), card, model.to_path_buf())
            }
            ModelSource::Memory { model, card, name } => {
                let path = PathBuf::from(format!("<{name}>"));
                let card = ModelCard::from_json(card, &path)?;
                card.check_layout(layout)?;
                card.check_model_bytes(model, &path)?;
                (model.into(), card, path)
            }
        };
        // A residual model reads two more channels (checked against the card above).
        let layout = &card.expectation(layout);
        if bytes.is_empty() {
            return Err(OnnxError::ModelInvalid {
                path,
                backend: backend.name(),
                reason: "empty file".into(),
            });
        }
        let session = backend::session(backend, &bytes, &path, 1)?;
        if session.inputs().len() != 1 || session.outputs().len() != 1 {
            return Err(OnnxError::Arity {
                path,
                inputs: session.inputs().len(),
                outputs: session.outputs().len(),
            });
        }
        for (what, outlet, expected) in [
            ("model input", &session.inputs()[0], layout.input_shape()),
            ("model output", &session.outputs()[0], layout.output_shape()),
        ] {
            let dtype = outlet.dtype();
            match dtype.tensor_type() {
                Some(TensorElementType::Float32) => {}
                Some(t) => {
                    return Err(OnnxError::ElementType {
                        what: what.into(),
                        found: t.to_string(),
                    });
                }
                None => {
                    return Err(OnnxError::ElementType {
                        what: what.into(),
                        found: dtype.to_string(),
                    });
                }
            }
            let shape: Vec<i64> = dtype.tensor_shape().map(|s| s.to_vec()).unwrap_or_default();
            check_shape(what, &expected, &shape)?;
        }
        let input_shape = layout.input_shape();
        let input_shape = [
            input_shape[0] as usize,
            input_shape[1] as usize,
            input_shape[2] as usize,
            input_shape[3] as usize,
        ];
        let output_len = layout.output_shape().iter().product::<i64>() as usize;
        Ok(Self {
            session,
            card,
            backend,
            path,
            input_shape,
            output_len,
        })
    }

    /// The model's card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// The backend running the model.
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// The model file (or `<name>` for an embedded model).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Number of input values (`C_in × ny × nx`).
    pub fn input_len(&self) -> usize {
        self.input_shape.iter().product()
    }

    /// Number of output values (`C_out × ny × nx`).
    pub fn output_len(&self) -> usize {
        self.output_len
    }

    /// Runs the model on `input` (NCHW, batch 1) and writes the result into `output`.
    /// The input is passed to the backend by reference; the only allocations are the backend's own.
    pub fn run(&mut self, input: &[f32], output: &mut [f32]) -> Result<(), OnnxError> {
        if input.len() != self.input_len() {
            return Err(OnnxError::ShapeMismatch {
                what: "input buffer".into(),
                expected: vec![self.input_len() as i64],
                found: vec![input.len() as i64],
            });
        }
        if output.len() != self.output_len {
            return Err(OnnxError::ShapeMismatch {
                what: "output buffer".into(),
                expected: vec![self.output_len as i64],
                found: vec![output.len() as i64],
            });
        }
        let fail = |e: ort::Error| OnnxError::Inference {
            reason: e.to_string(),
        };
        let tensor = TensorRef::from_array_view((self.input_shape, input)).map_err(fail)?;
        let outputs = self.session.run(ort::inputs![tensor]).map_err(fail)?;
        let (_, data) = outputs[0].try_extract_tensor::<f32>().map_err(fail)?;
        if data.len() != output.len() {
            return Err(OnnxError::ShapeMismatch {
                what: "model output".into(),
                expected: vec![output.len() as i64],
                found: vec![data.len() as i64],
            });
        }
        output.copy_from_slice(data);
        Ok(())
    }
}
