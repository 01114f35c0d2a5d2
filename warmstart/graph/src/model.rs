//! The contact-graph model: architecture, weights and the forward pass (the Rust mirror of
//! `ContactGraph` in `models/train/graph.py`).
//!
//! Per contact point, 15 features ([`FEATURES`], standardised with the training set's mean
//! and deviation) are encoded to `hidden` numbers; `rounds` rounds of message passing
//! follow. In each, a contact sends `channels` scalars and `channels` impulse-like vectors
//! `qn n + qt t` (sign of an impulse: + on body B, − on body A) to its moving bodies, which
//! sum them; the contact reads its two bodies' sums (vectors projected on its normal and
//! tangent) and adds `relu(update([h, read]))` to its state. A linear head gives the
//! correction `(dn, dt)` in units of `impulse_scale` N·s.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use safetensors::SafeTensors;
use safetensors::tensor::Dtype;

use crate::GraphError;

/// The per-contact input features, in order (the same names as the training script's).
pub const FEATURES: [&str; 15] = [
    "carried_normal",
    "carried_tangent",
    "carried",
    "normal_x",
    "normal_y",
    "separation",
    "relative_velocity_normal",
    "relative_velocity_tangent",
    "velocity_bias",
    "normal_mass",
    "tangent_mass",
    "inverse_mass_a",
    "inverse_mass_b",
    "lever_normal_a",
    "lever_normal_b",
];

/// Number of input features per contact point.
pub const FEATURE_COUNT: usize = FEATURES.len();

/// The `format` metadata field of a weights file.
pub const MODEL_FORMAT: &str = "deepcontact-graph-model";

/// The model's shape, from the `architecture` metadata (JSON) of its weights file.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct Architecture {
    /// Always `contact-graph`.
    pub model: String,
    /// Feature names, in order; must equal [`FEATURES`].
    pub features: Vec<String>,
    /// Width of a contact's state.
    pub hidden: usize,
    /// Scalar and vector message channels per round.
    pub channels: usize,
    /// Rounds of message passing.
    pub rounds: usize,
    /// Unit of the predicted correction (N·s; the training labels' RMS).
    pub impulse_scale: f64,
}

/// A dense layer `y = W x + b`, `W` kept transposed (`[inputs][outputs]`) so the forward
/// pass adds one row per input to all outputs at once.
#[derive(Debug, Clone)]
struct Linear {
    outputs: usize,
    transposed: Vec<f32>,
    bias: Vec<f32>,
}

impl Linear {
    fn apply(&self, x: &[f32], y: &mut [f32]) {
        y.copy_from_slice(&self.bias);
        for (&xi, row) in x.iter().zip(self.transposed.chunks_exact(self.outputs)) {
            for (yo, w) in y.iter_mut().zip(row) {
                *yo += xi * w;
            }
        }
    }
}

/// One contact point's input to [`ContactGraphModel::corrections`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointInput {
    /// The raw (not standardised) features, in [`FEATURES`] order.
    pub features: [f32; FEATURE_COUNT],
    /// The point's bodies A and B (indices into the `moving` slice).
    pub bodies: [u32; 2],
}

impl PointInput {
    /// The unit normal (from A to B) among the features.
    fn normal(&self) -> [f32; 2] {
        [self.features[3], self.features[4]]
    }
}

/// Buffers of the forward pass, kept between calls so that a call allocates only when an
/// island is larger than every island before.
#[derive(Debug, Clone, Default)]
pub struct Scratch {
    h: Vec<f32>,
    x: Vec<f32>,
    message: Vec<f32>,
    sums: Vec<f32>,
    vectors: Vec<f32>,
    joined: Vec<f32>,
    step: Vec<f32>,
}

/// A loaded contact-graph model.
#[derive(Debug, Clone)]
pub struct ContactGraphModel {
    architecture: Architecture,
    mean: Vec<f32>,
    inverse_std: Vec<f32>,
    encoder: Linear,
    message: Vec<Linear>,
    update: Vec<Linear>,
    head: Linear,
}

impl ContactGraphModel {
    /// Loads a weights file written by `models/train/graph.py` (`path` labels errors).
    pub fn from_safetensors(bytes: &[u8], path: &Path) -> Result<Self, GraphError> {
        let architecture = read_architecture(bytes, path)?;
        let file = SafeTensors::deserialize(bytes).map_err(|e| GraphError::Format {
            path: path.to_path_buf(),
            reason: format!("not safetensors: {e}"),
        })?;
        let tensor = |name: &str, shape: &[usize]| read_tensor(&file, path, name, shape);
        let linear = |name: &str, inputs: usize, outputs: usize| -> Result<Linear, GraphError> {
            let w = tensor(&format!("{name}.weight"), &[outputs, inputs])?;
            let mut transposed = vec![0.0; inputs * outputs];
            for o in 0..outputs {
                for i in 0..inputs {
                    transposed[i * outputs + o] = w[o * inputs + i];
                }
            }
            Ok(Linear {
                outputs,
                transposed,
                bias: tensor(&format!("{name}.bias"), &[outputs])?,
            })
        };
        let (h, k, rounds) = (
            architecture.hidden,
            architecture.channels,
            architecture.rounds,
        );
        let std = tensor("feature_std", &[FEATURE_COUNT])?;
        if let Some(i) = std.iter().position(|&s| s <= 0.0) {
            return Err(GraphError::Tensor {
                path: path.to_path_buf(),
                name: "feature_std".into(),
                reason: format!("entry {i} is {} (must be positive)", std[i]),
            });
        }
        Ok(Self {
            mean: tensor("feature_mean", &[FEATURE_COUNT])?,
            inverse_std: std.iter().map(|s| 1.0 / s).collect(),
            encoder: linear("encoder", FEATURE_COUNT, h)?,
            message: (0..rounds)
                .map(|r| linear(&format!("message.{r}"), h, 3 * k))
                .collect::<Result<_, _>>()?,
            update: (0..rounds)
                .map(|r| linear(&format!("update.{r}"), h + 6 * k, h))
                .collect::<Result<_, _>>()?,
            head: linear("head", h, 2)?,
            architecture,
        })
    }

    /// Loads a weights file from disk.
    pub fn load(path: &Path) -> Result<Self, GraphError> {
        let bytes = std::fs::read(path).map_err(|source| GraphError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_safetensors(&bytes, path)
    }

    /// The model's shape.
    pub fn architecture(&self) -> &Architecture {
        &self.architecture
    }

    /// Number of trained numbers (weights and biases, not the feature statistics).
    pub fn parameter_count(&self) -> usize {
        let layer = |l: &Linear| l.transposed.len() + l.bias.len();
        layer(&self.encoder)
            + self.message.iter().map(layer).sum::<usize>()
            + self.update.iter().map(layer).sum::<usize>()
            + layer(&self.head)
    }

    /// The predicted corrections `(dn, dt)` in N·s, one per point, into `out`. `moving[b]`
    /// says whether body `b` can move (static bodies neither send nor receive messages).
    ///
    /// # Panics
    /// If `out` and `points` differ in length or a point names a body outside `moving`
    /// (the provider builds both from one problem).
    pub fn corrections(
        &self,
        points: &[PointInput],
        moving: &[bool],
        scratch: &mut Scratch,
        out: &mut [[f32; 2]],
    ) {
        assert_eq!(points.len(), out.len(), "one output per point");
        let (h, k, c) = (
            self.architecture.hidden,
            self.architecture.channels,
            points.len(),
        );
        let s = scratch;
        s.h.resize(c * h, 0.0);
        s.x.resize(FEATURE_COUNT, 0.0);
        s.message.resize(c * 3 * k, 0.0);
        s.sums.resize(moving.len() * k, 0.0);
        s.vectors.resize(moving.len() * 2 * k, 0.0);
        s.joined.resize(h + 6 * k, 0.0);
        s.step.resize(h, 0.0);
        for (p, state) in points.iter().zip(s.h.chunks_exact_mut(h)) {
            for (((x, f), m), is) in
                s.x.iter_mut()
                    .zip(&p.features)
                    .zip(&self.mean)
                    .zip(&self.inverse_std)
            {
                // Training standardised with (f - mean) / std; one rounding apart at most.
                *x = (f - m) * is;
            }
            self.encoder.apply(&s.x, state);
            relu(state);
        }
        for (message, update) in self.message.iter().zip(&self.update) {
            for (state, m) in s.h.chunks_exact(h).zip(s.message.chunks_exact_mut(3 * k)) {
                message.apply(state, m);
            }
            s.sums.fill(0.0);
            s.vectors.fill(0.0);
            for (p, m) in points.iter().zip(s.message.chunks_exact(3 * k)) {
                let [nx, ny] = p.normal();
                for (side, sign) in [(0, -1.0f32), (1, 1.0)] {
                    let b = p.bodies[side] as usize;
                    if !moving[b] {
                        continue;
                    }
                    let (sum, vec) = (
                        &mut s.sums[b * k..][..k],
                        &mut s.vectors[b * 2 * k..][..2 * k],
                    );
                    for j in 0..k {
                        let (qn, qt) = (m[k + j], m[2 * k + j]);
                        sum[j] += m[j];
                        // qn n + qt t with t = (-ny, nx).
                        vec[2 * j] += sign * (qn * nx - qt * ny);
                        vec[2 * j + 1] += sign * (qn * ny + qt * nx);
                    }
                }
            }
            for (p, state) in points.iter().zip(s.h.chunks_exact_mut(h)) {
                let [nx, ny] = p.normal();
                let (head, read) = s.joined.split_at_mut(h);
                head.copy_from_slice(state);
                read.fill(0.0);
                for (side, body) in p.bodies.iter().enumerate() {
                    let b = *body as usize;
                    if !moving[b] {
                        continue;
                    }
                    let (sum, vec) = (&s.sums[b * k..][..k], &s.vectors[b * 2 * k..][..2 * k]);
                    read[side * k..][..k].copy_from_slice(sum);
                    for j in 0..k {
                        let (vx, vy) = (vec[2 * j], vec[2 * j + 1]);
                        read[(2 + 2 * side) * k + j] = vx * nx + vy * ny;
                        read[(3 + 2 * side) * k + j] = -vx * ny + vy * nx;
                    }
                }
                update.apply(&s.joined, &mut s.step);
                for (x, u) in state.iter_mut().zip(&s.step) {
                    *x += u.max(0.0);
                }
            }
        }
        let scale = self.architecture.impulse_scale as f32;
        for (state, o) in s.h.chunks_exact(h).zip(out.iter_mut()) {
            let mut d = [0.0f32; 2];
            self.head.apply(state, &mut d);
            *o = [d[0] * scale, d[1] * scale];
        }
    }
}

/// The checked `architecture` of a weights file's metadata.
fn read_architecture(bytes: &[u8], path: &Path) -> Result<Architecture, GraphError> {
    let format = |reason: String| GraphError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let (_, meta) =
        SafeTensors::read_metadata(bytes).map_err(|e| format(format!("not safetensors: {e}")))?;
    let empty = HashMap::new();
    let meta = meta.metadata().as_ref().unwrap_or(&empty);
    if meta.get("format").map(String::as_str) != Some(MODEL_FORMAT) {
        return Err(format(format!(
            "metadata `format` is {:?}, not `{MODEL_FORMAT}`",
            meta.get("format")
        )));
    }
    let a: Architecture = meta
        .get("architecture")
        .ok_or_else(|| format("no `architecture` metadata".into()))
        .and_then(|a| serde_json::from_str(a).map_err(|e| format(format!("architecture: {e}"))))?;
    if a.model != "contact-graph" || a.features != FEATURES {
        return Err(format(format!(
            "architecture is `{}` on features {:?}; this build runs `contact-graph` on {:?}",
            a.model, a.features, FEATURES
        )));
    }
    if a.hidden == 0 || a.channels == 0 || a.hidden > 4096 || a.channels > 4096 || a.rounds > 64 {
        return Err(format(format!(
            "hidden {}, channels {}, rounds {}: out of range",
            a.hidden, a.channels, a.rounds
        )));
    }
    if !(a.impulse_scale.is_finite() && a.impulse_scale > 0.0) {
        return Err(format(format!(
            "impulse_scale {} is not positive",
            a.impulse_scale
        )));
    }
    Ok(a)
}

/// Tensor `name` of `file` as `f32`s, checked: present, F32 of `shape`, finite.
fn read_tensor(
    file: &SafeTensors<'_>,
    path: &Path,
    name: &str,
    shape: &[usize],
) -> Result<Vec<f32>, GraphError> {
    let bad = |reason: String| GraphError::Tensor {
        path: path.to_path_buf(),
        name: name.to_string(),
        reason,
    };
    let t = file.tensor(name).map_err(|_| bad("is missing".into()))?;
    if t.dtype() != Dtype::F32 || t.shape() != shape {
        return Err(bad(format!(
            "is {:?} {:?}, expected F32 {shape:?}",
            t.dtype(),
            t.shape()
        )));
    }
    let v: Vec<f32> = t
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(bad(format!("holds {} at {i}", v[i]))),
        None => Ok(v),
    }
}

fn relu(v: &mut [f32]) {
    for x in v {
        *x = x.max(0.0);
    }
}

/// Where a model came from, for error messages.
pub(crate) fn embedded_path() -> PathBuf {
    PathBuf::from("<embedded>")
}
