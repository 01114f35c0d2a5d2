//! The crate's error type.

/// Everything that can go wrong in this crate. Every variant carries the offending data;
/// nothing in the crate panics on bad input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// Node spacing not finite or not > 0.
    #[error("grid spacing {spacing} must be finite and > 0")]
    InvalidSpacing {
        /// The spacing given.
        spacing: f64,
    },
    /// Grid origin not finite.
    #[error("grid origin ({x}, {y}) must be finite")]
    InvalidOrigin {
        /// x of the origin.
        x: f64,
        /// y of the origin.
        y: f64,
    },
    /// Zero nodes along an axis, or more nodes in all than [`crate::GridSpec::MAX_NODES`].
    #[error("grid of {nx} x {ny} nodes: {reason}")]
    InvalidNodeCount {
        /// Nodes along x.
        nx: usize,
        /// Nodes along y.
        ny: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// A region whose corners are not finite or not ordered (`min <= max` per axis).
    #[error("region [{min_x}, {max_x}] x [{min_y}, {max_y}] must be finite with min <= max")]
    InvalidRegion {
        /// Lower x.
        min_x: f64,
        /// Lower y.
        min_y: f64,
        /// Upper x.
        max_x: f64,
        /// Upper y.
        max_y: f64,
    },
    /// Kernel support radius not finite or not > 0.
    #[error("support radius h = {h} must be finite and > 0")]
    InvalidSupport {
        /// The radius given.
        h: f64,
    },
    /// A kernel parameter out of range (e.g. the Gaussian's sigma).
    #[error("kernel `{kernel}`: {param} = {value} is invalid: {reason}")]
    InvalidKernel {
        /// Kernel name.
        kernel: &'static str,
        /// Parameter name.
        param: &'static str,
        /// Value given.
        value: f64,
        /// Why it was rejected.
        reason: &'static str,
    },
    /// Another numeric setting out of range (wall mass, wall band, ...).
    #[error("{name} = {value} is invalid: {reason}")]
    InvalidSetting {
        /// Setting name.
        name: &'static str,
        /// Value given.
        value: f64,
        /// Why it was rejected.
        reason: &'static str,
    },
    /// A name (kernel, transfer, search) that is not known.
    #[error("unknown {what} `{value}` (accepted: {accepted})")]
    UnknownName {
        /// What was being named.
        what: &'static str,
        /// The name given.
        value: String,
        /// Accepted names.
        accepted: &'static str,
    },
    /// A NaN or infinite input value.
    #[error("non-finite {what} {value} at index {index}")]
    NonFinite {
        /// Which input (`"particle position"`, `"particle value"`, `"grid value"`, ...).
        what: &'static str,
        /// Index of the particle or grid entry.
        index: usize,
        /// The value found.
        value: f64,
    },
    /// A buffer of the wrong length.
    #[error("{what}: expected length {expected}, got {got}")]
    LengthMismatch {
        /// Which buffer.
        what: &'static str,
        /// Length required.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A layout whose channel list is not the one this crate computes.
    #[error("{which} channels {got:?} do not match the supported {expected:?}")]
    ChannelMismatch {
        /// `"input"` or `"output"`.
        which: &'static str,
        /// The supported list.
        expected: Vec<String>,
        /// The list found.
        got: Vec<String>,
    },
    /// A layout file of an unsupported format version.
    #[error("layout version {got} is not supported (this build reads version {supported})")]
    UnsupportedVersion {
        /// Version found.
        got: u32,
        /// Version this build reads and writes.
        supported: u32,
    },
    /// Malformed layout JSON.
    #[error("layout JSON: {0}")]
    Json(String),
    /// Reading or writing a layout file.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The OS error, as text.
        reason: String,
    },
    /// The k-d tree could not be built.
    #[error("k-d tree construction failed: {0}")]
    KdTree(String),
}
