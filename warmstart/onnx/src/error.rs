//! The crate's error type.

use std::path::PathBuf;

/// Errors from loading, checking and running an ONNX warm-start model.
///
/// Every variant carries the data needed to say what went wrong without a debugger:
/// the file, the tensor, the channel index, the expected and the found value.
#[derive(Debug, thiserror::Error)]
pub enum OnnxError {
    /// The model file does not exist.
    #[error("model file {path} not found")]
    ModelMissing {
        /// The path that was looked up.
        path: PathBuf,
    },
    /// The model file is not the one its card was written for (SHA-256 differs).
    #[error(
        "model {path} is not the model of card `{card}`: SHA-256 {found} differs from the card's {expected}"
    )]
    ModelHashMismatch {
        /// The model file.
        path: PathBuf,
        /// The card's model name.
        card: String,
        /// The card's `model_sha256`.
        expected: String,
        /// SHA-256 of the file.
        found: String,
    },
    /// The model card (JSON) does not exist.
    #[error("model card {path} not found (every model needs a card: the same path with `.json`)")]
    CardMissing {
        /// The path that was looked up.
        path: PathBuf,
    },
    /// Reading a file failed for another reason.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The model card is not valid JSON or lacks a field.
    #[error("model card {path} is invalid: {reason}")]
    CardInvalid {
        /// The card file (or `<embedded>`).
        path: PathBuf,
        /// What the JSON parser said.
        reason: String,
    },
    /// The backend could not load the model (corrupt or unsupported ONNX).
    #[error("model {path} cannot be loaded by {backend}: {reason}")]
    ModelInvalid {
        /// The model file (or `<embedded>`).
        path: PathBuf,
        /// Backend that tried.
        backend: &'static str,
        /// The backend's message.
        reason: String,
    },
    /// The model has not exactly one input and one output.
    #[error("model {path} has {inputs} inputs and {outputs} outputs; expected 1 and 1")]
    Arity {
        /// The model file.
        path: PathBuf,
        /// Number of inputs.
        inputs: usize,
        /// Number of outputs.
        outputs: usize,
    },
    /// A tensor's shape differs from what the grid layout needs.
    #[error("{what}: shape {found:?} differs from the expected {expected:?} (-1 = any)")]
    ShapeMismatch {
        /// Which tensor (`model input`, `card output`, ...).
        what: String,
        /// Expected dimensions.
        expected: Vec<i64>,
        /// Found dimensions (`-1` for a dynamic one).
        found: Vec<i64>,
    },
    /// A tensor's element type is not f32.
    #[error("{what}: element type {found} is not f32")]
    ElementType {
        /// Which tensor.
        what: String,
        /// The element type found.
        found: String,
    },
    /// The card lists a different number of channels than the grid layout.
    #[error("card {tensor} channels: {found} listed, the grid layout has {expected}")]
    ChannelCount {
        /// `input` or `output`.
        tensor: &'static str,
        /// Channels of the grid layout.
        expected: usize,
        /// Channels of the card.
        found: usize,
    },
    /// A channel of the card is not the grid layout's channel at that position.
    #[error("card {tensor} channel {index} is `{found}`, the grid layout has `{expected}` there")]
    ChannelMismatch {
        /// `input` or `output`.
        tensor: &'static str,
        /// Channel index.
        index: usize,
        /// Layout's channel name.
        expected: String,
        /// Card's channel name.
        found: String,
    },
    /// The card's grid layout differs from this build's grid layout.
    #[error("card grid layout differs at `{field}`: card has {found}, this build has {expected}")]
    GridMismatch {
        /// JSON path of the first difference.
        field: String,
        /// This build's value (JSON).
        expected: String,
        /// The card's value (JSON).
        found: String,
    },
    /// The requested backend is not compiled into this build.
    #[error("backend `{backend}` is not available: {reason}")]
    BackendUnavailable {
        /// The requested backend.
        backend: &'static str,
        /// Why (which cargo feature to enable).
        reason: String,
    },
    /// Another backend already owns this process (ort's API is process-global).
    #[error(
        "backend `{requested}` requested, but this process already runs `{active}` (one backend per process)"
    )]
    BackendConflict {
        /// The backend initialised first.
        active: &'static str,
        /// The backend asked for now.
        requested: &'static str,
    },
    /// Initialising the backend failed (e.g. `ORT_DYLIB_PATH` does not point at a usable library).
    #[error("cannot initialise backend `{backend}`: {reason}")]
    BackendInit {
        /// The backend.
        backend: &'static str,
        /// What failed.
        reason: String,
    },
    /// Running the model failed.
    #[error("inference failed: {reason}")]
    Inference {
        /// The backend's message.
        reason: String,
    },
    /// An unknown backend name in a spec.
    #[error("unknown backend `{name}` (known: tract, onnxruntime)")]
    UnknownBackend {
        /// The name given.
        name: String,
    },
    /// The grid transfer failed.
    #[error("grid transfer: {reason}")]
    Grid {
        /// The grid crate's message.
        reason: String,
    },
}
