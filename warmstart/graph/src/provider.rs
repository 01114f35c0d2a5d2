//! [`GraphWarmStart`]: the carried impulses plus the model's correction.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use deepcontact_core::math::{Real, cross};
use deepcontact_core::{Impulse, WarmStart, WarmStartContext, WarmStartError};

use crate::GraphError;
use crate::card::GraphCard;
use crate::model::{ContactGraphModel, PointInput, Scratch, embedded_path};

/// The shipped model's weights (`models/graph.safetensors`), built into the crate.
const SHIPPED_WEIGHTS: &[u8] = include_bytes!("../model/graph.safetensors");
/// The shipped model's card (`models/graph.json`).
const SHIPPED_CARD: &str = include_str!("../model/graph.json");

/// Carried impulses corrected by a contact-graph model: per point,
/// `(max(0, carried_n + dn), carried_t + dt)` with `(dn, dt)` from
/// [`ContactGraphModel::corrections`]; new points are carried as zero. One forward pass per
/// island, no allocation once the buffers have grown to the largest island.
#[derive(Debug, Clone)]
pub struct GraphWarmStart {
    name: String,
    model: Arc<ContactGraphModel>,
    scratch: Scratch,
    points: Vec<PointInput>,
    moving: Vec<bool>,
    corrections: Vec<[f32; 2]>,
    evaluated: u64,
    corrected: Real,
}

impl GraphWarmStart {
    /// A provider named `name` running `model`.
    pub fn new(name: impl Into<String>, model: Arc<ContactGraphModel>) -> Self {
        Self {
            name: name.into(),
            model,
            scratch: Scratch::default(),
            points: Vec::new(),
            moving: Vec::new(),
            corrections: Vec::new(),
            evaluated: 0,
            corrected: 0.0,
        }
    }

    /// The shipped model (`graph`), checked against its card.
    pub fn shipped() -> Result<Self, GraphError> {
        let path = embedded_path();
        GraphCard::parse(SHIPPED_CARD, &path)?.check(SHIPPED_WEIGHTS, &path)?;
        let model = ContactGraphModel::from_safetensors(SHIPPED_WEIGHTS, &path)?;
        Ok(Self::new("graph", Arc::new(model)))
    }

    /// A model from disk with its card (default: the weights path with `.json`).
    pub fn from_files(
        name: impl Into<String>,
        weights: &Path,
        card: Option<&Path>,
    ) -> Result<Self, GraphError> {
        let card_path: PathBuf =
            card.map_or_else(|| weights.with_extension("json"), Path::to_path_buf);
        let text = std::fs::read_to_string(&card_path).map_err(|source| GraphError::Io {
            path: card_path.clone(),
            source,
        })?;
        let card = GraphCard::parse(&text, &card_path)?;
        let bytes = std::fs::read(weights).map_err(|source| GraphError::Io {
            path: weights.to_path_buf(),
            source,
        })?;
        card.check(&bytes, weights)?;
        let model = ContactGraphModel::from_safetensors(&bytes, weights)?;
        if model.architecture() != &card.architecture {
            return Err(GraphError::Card {
                path: card_path,
                reason: "its architecture differs from the weights file's".into(),
            });
        }
        Ok(Self::new(name, Arc::new(model)))
    }

    /// The model.
    pub fn model(&self) -> &ContactGraphModel {
        &self.model
    }
}

/// The model's inputs for every point of the context's problem, in point order, into `out`
/// (cleared first): the raw features in [`crate::FEATURES`] order and the point's bodies
/// (indices into `ctx.problem.bodies`), exactly as [`GraphWarmStart`] computes them. A body
/// moves, for [`ContactGraphModel::corrections`], when its inverse mass is positive.
///
/// Only `ctx.problem` and `ctx.carried` are read, so a recorded island gives the same inputs
/// when replayed through [`WarmStartContext::new`].
pub fn point_inputs(ctx: &WarmStartContext<'_>, out: &mut Vec<PointInput>) {
    out.clear();
    out.extend((0..ctx.problem.len()).map(|i| point_input(ctx, i)));
}

/// The model's input for point `i` of the context's problem (features in
/// [`crate::FEATURES`] order).
fn point_input(ctx: &WarmStartContext<'_>, i: usize) -> PointInput {
    let problem = ctx.problem;
    let p = &problem.points[i];
    let (a, b) = (
        &problem.bodies[p.body_a as usize],
        &problem.bodies[p.body_b as usize],
    );
    let carried = ctx.carried.get(i).copied().flatten();
    let c = carried.unwrap_or(Impulse::ZERO);
    let dv = problem.relative_velocity(i);
    let f = [
        c.normal,
        c.tangent,
        if carried.is_some() { 1.0 } else { 0.0 },
        p.normal.x,
        p.normal.y,
        p.separation,
        dv.dot(&p.normal),
        dv.dot(&p.tangent()),
        p.velocity_bias,
        p.normal_mass,
        p.tangent_mass,
        a.inv_mass,
        b.inv_mass,
        cross(&p.r_a, &p.normal),
        cross(&p.r_b, &p.normal),
    ];
    PointInput {
        features: f.map(|x| x as f32),
        bodies: [p.body_a, p.body_b],
    }
}

impl WarmStart for GraphWarmStart {
    fn name(&self) -> &str {
        &self.name
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let problem = ctx.problem;
        point_inputs(ctx, &mut self.points);
        self.moving.clear();
        self.moving
            .extend(problem.bodies.iter().map(|b| b.inv_mass > 0.0));
        self.corrections.clear();
        self.corrections.resize(problem.len(), [0.0; 2]);
        self.model.corrections(
            &self.points,
            &self.moving,
            &mut self.scratch,
            &mut self.corrections,
        );
        for (i, (o, d)) in out.iter_mut().zip(&self.corrections).enumerate() {
            let c = ctx.carried_or_zero(i);
            let (dn, dt) = (Real::from(d[0]), Real::from(d[1]));
            if !(dn.is_finite() && dt.is_finite()) {
                return Err(WarmStartError::Provider(format!(
                    "{}: non-finite correction ({dn}, {dt}) at point {i}",
                    self.name
                )));
            }
            *o = Impulse::new((c.normal + dn).max(0.0), c.tangent + dt);
            self.corrected += dn.abs();
        }
        self.evaluated += problem.len() as u64;
        Ok(())
    }

    fn reset(&mut self) {
        self.evaluated = 0;
        self.corrected = 0.0;
    }

    fn diagnostics(&self) -> Vec<(String, Real)> {
        let mean = if self.evaluated == 0 {
            0.0
        } else {
            self.corrected / self.evaluated as Real
        };
        vec![
            ("points_evaluated".into(), self.evaluated as Real),
            ("mean_abs_normal_correction".into(), mean),
        ]
    }
}
