//! The CNN warm-start provider: particles → grid → model → grid → particles.

use std::path::{Path, PathBuf};

use deepcontact_core::{ContactId, Impulse, Vector, WarmStart, WarmStartContext, WarmStartError};

use crate::backend::Backend;
use crate::error::OnnxError;
use crate::features::{self, GridFeatures, GridLayout};
use crate::model::{ModelSource, OnnxModel};

/// A model shipped in the repository's `models/` directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShippedModel {
    /// Provider name (`pressure`, `peak`).
    pub name: &'static str,
    /// File name of the model inside the models directory; the card is the same name with `.json`.
    pub file: &'static str,
}

/// The shipped Pressure model (`models/pressure.onnx`).
pub const PRESSURE: ShippedModel = ShippedModel {
    name: "pressure",
    file: "pressure.onnx",
};
/// The shipped residual Pressure model (`models/pressure-residual.onnx`): reads the carried
/// impulses as two more grids and predicts the correction to them.
pub const PRESSURE_RESIDUAL: ShippedModel = ShippedModel {
    name: "pressure-residual",
    file: "pressure-residual.onnx",
};
/// The shipped Peak model (`models/peak.onnx`).
pub const PEAK: ShippedModel = ShippedModel {
    name: "peak",
    file: "peak.onnx",
};

impl ShippedModel {
    /// The models directory: `$DEEPCONTACT_MODELS_DIR` if set, else the workspace's `models/`
    /// (resolved at compile time from this crate's manifest directory).
    pub fn models_dir() -> PathBuf {
        match std::env::var_os("DEEPCONTACT_MODELS_DIR") {
            Some(d) if !d.is_empty() => PathBuf::from(d),
            _ => Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("..")
                .join("..")
                .join("models"),
        }
    }

    /// Path of the model file.
    pub fn path(&self) -> PathBuf {
        Self::models_dir().join(self.file)
    }
}

/// Options of a CNN provider.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProviderOptions {
    /// Inference backend.
    pub backend: Backend,
}

impl Default for ProviderOptions {
    fn default() -> Self {
        Self {
            backend: Backend::default_for_build(),
        }
    }
}

/// A warm start predicted by a CNN on grids.
///
/// Per step (on the first island, or whenever the step index changes) it spreads the whole
/// world onto the input grids, runs the model once, and reads the impulse grids back at every
/// contact point of the step; each island then takes its points' values by contact id. Without a
/// world (hand-built problems) the island's own bodies and points are used.
///
/// A residual model ([`crate::card::ModelCard::residual`]) also reads the carried impulses,
/// spread onto two more input grids, and predicts corrections: each contact's start is its
/// own carried impulse (exact, not through the grid) plus the correction read back at it.
///
/// Negative predicted normal impulses are clamped to 0 (a normal impulse is never negative, and
/// the world rejects a warm start that has one); tangents are passed as predicted. A non-finite
/// prediction is an error (the world then starts that island from zeros and counts a fallback).
#[derive(Debug)]
pub struct CnnWarmStart {
    name: String,
    model: OnnxModel,
    features: GridFeatures,
    input: Vec<f32>,
    output: Vec<f32>,
    ids: Vec<ContactId>,
    positions: Vec<Vector>,
    impulses: Vec<Impulse>,
    /// The carried impulse of each point in `ids` (read by residual models).
    carried: Vec<Impulse>,
    /// Predictions of the current step, sorted by contact id.
    predicted: Vec<(ContactId, Impulse)>,
    /// Step index `predicted` belongs to.
    step: Option<u64>,
}

impl CnnWarmStart {
    /// Loads a model (checked against the thesis grid layout) as a provider called `name`.
    pub fn new(
        name: &str,
        source: ModelSource<'_>,
        options: ProviderOptions,
    ) -> Result<Self, OnnxError> {
        let layout = GridLayout::thesis();
        let model = OnnxModel::load(source, options.backend, &features::expectation(&layout))?;
        let carried_grids = if model.card().residual {
            layout.output_len()
        } else {
            0
        };
        Ok(Self {
            name: name.to_string(),
            input: vec![0.0; layout.input_len() + carried_grids],
            output: vec![0.0; layout.output_len()],
            ids: Vec::new(),
            positions: Vec::new(),
            impulses: Vec::new(),
            carried: Vec::new(),
            predicted: Vec::new(),
            step: None,
            model,
            features: GridFeatures::new(layout)?,
        })
    }

    /// A shipped model from the models directory.
    pub fn shipped(model: ShippedModel, options: ProviderOptions) -> Result<Self, OnnxError> {
        let path = model.path();
        Self::new(
            model.name,
            ModelSource::Files {
                model: &path,
                card: None,
            },
            options,
        )
    }

    /// Length of the carried-impulse grids at the end of the input (0 unless residual).
    fn carried_grids(&self) -> usize {
        if self.model.card().residual {
            self.output.len()
        } else {
            0
        }
    }

    /// The model.
    pub fn model(&self) -> &OnnxModel {
        &self.model
    }

    /// The grid layout.
    pub fn layout(&self) -> &GridLayout {
        self.features.layout()
    }

    /// The last input grids (`[6, ny, nx]`, `[8, ny, nx]` for a residual model).
    pub fn last_input(&self) -> &[f32] {
        &self.input
    }

    /// The last output grids (`[2, ny, nx]`).
    pub fn last_output(&self) -> &[f32] {
        &self.output
    }

    /// Runs the model on the current input grids (for a residual model, after spreading
    /// `self.carried` onto its last two) and reads the output at `self.positions` (ids in
    /// `self.ids`), replacing `self.predicted`.
    fn predict(&mut self) -> Result<(), WarmStartError> {
        let fail = |e: OnnxError| WarmStartError::Provider(e.to_string());
        let residual = self.model.card().residual;
        if residual {
            let base = self.input.len() - self.output.len();
            self.features
                .encode_impulses(&self.positions, &self.carried, &mut self.input[base..])
                .map_err(fail)?;
        }
        self.model
            .run(&self.input, &mut self.output)
            .map_err(fail)?;
        self.impulses.clear();
        self.impulses.resize(self.positions.len(), Impulse::ZERO);
        if residual {
            self.features
                .decode_signed(&self.output, &self.positions, &mut self.impulses)
                .map_err(fail)?;
            for (i, c) in self.impulses.iter_mut().zip(&self.carried) {
                *i = Impulse::new((c.normal + i.normal).max(0.0), c.tangent + i.tangent);
            }
        } else {
            self.features
                .decode(&self.output, &self.positions, &mut self.impulses)
                .map_err(fail)?;
        }
        self.predicted.clear();
        self.predicted
            .extend(self.ids.iter().copied().zip(self.impulses.iter().copied()));
        self.predicted.sort_unstable_by_key(|a| a.0);
        Ok(())
    }
}

impl WarmStart for CnnWarmStart {
    fn name(&self) -> &str {
        &self.name
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        if out.len() != ctx.problem.points.len() {
            return Err(WarmStartError::WrongLength {
                expected: ctx.problem.points.len(),
                got: out.len(),
            });
        }
        let fail = |e: OnnxError| WarmStartError::Provider(e.to_string());
        match ctx.world {
            Some(world) => {
                if ctx.island == 0 || self.step != Some(ctx.step) {
                    let base = self.input.len() - self.carried_grids();
                    self.features
                        .encode_world(world, &mut self.input[..base])
                        .map_err(fail)?;
                    self.ids.clear();
                    self.positions.clear();
                    self.carried.clear();
                    // The world's contacts are still last step's: its final impulses by id
                    // are this step's carried impulses (what builtin starts from).
                    let last = world.contacts();
                    for c in world.raw_contacts() {
                        self.ids.push(c.id);
                        self.positions.push(c.point);
                        self.carried
                            .push(match last.binary_search_by(|(k, _)| k.cmp(&c.id)) {
                                Ok(i) => last[i].1,
                                Err(_) => Impulse::ZERO,
                            });
                    }
                    self.predict()?;
                    self.step = Some(ctx.step);
                }
            }
            None => {
                let p = ctx.problem;
                let base = self.input.len() - self.carried_grids();
                self.features
                    .encode_problem(p, &mut self.input[..base])
                    .map_err(fail)?;
                self.ids.clear();
                self.positions.clear();
                self.carried.clear();
                for (i, c) in p.points.iter().enumerate() {
                    self.ids.push(c.id);
                    self.positions.push(c.point);
                    self.carried.push(ctx.carried_or_zero(i));
                }
                self.predict()?;
                self.step = None;
            }
        }
        for (o, point) in out.iter_mut().zip(&ctx.problem.points) {
            *o = match self.predicted.binary_search_by(|(k, _)| k.cmp(&point.id)) {
                Ok(i) => self.predicted[i].1,
                Err(_) => Impulse::ZERO,
            };
        }
        Ok(())
    }
}
