//! The relaxation policy: six features of a contact point, a logistic map to its ω.

use std::path::{Path, PathBuf};

use deepcontact_core::{ProblemBody, Real, WarmStartContext, WarmStartError};
use deepcontact_warmstart::Relaxation;
use serde::{Deserialize, Serialize};

use crate::RelaxError;

/// The policy file format this build reads.
pub const FORMAT: &str = "deepcontact-relax/1";

/// The features of point *i*, in weight order:
/// - `one`: 1 (the intercept);
/// - `abs_normal_y`: |n_y| of the contact normal (1 for a vertical contact, 0 for a side one);
/// - `log_carried_normal`: ln(1 + 10 · max(λn, 0)), λn the carried normal impulse in N·s (0
///   for a new point);
/// - `new`: 1 for a point without a carried impulse, else 0;
/// - `wall`: 1 when either body is immovable (ground, walls), else 0;
/// - `log_island_points`: ln(points of the island) − 4 (0 at about 55 points).
pub const FEATURES: [&str; 6] = [
    "one",
    "abs_normal_y",
    "log_carried_normal",
    "new",
    "wall",
    "log_island_points",
];

/// A relaxation policy: ω_i = 1 + span · σ(w · g_i), σ the logistic function, g_i the
/// [`FEATURES`] of point *i*; so ω_i ∈ (1, 1 + span) ⊂ (1, 2).
///
/// ```
/// use deepcontact_relax::RelaxationPolicy;
///
/// // Intercept only: the same ω everywhere, 1 + 0.95 · σ(0) = 1.475.
/// let policy = RelaxationPolicy::new([0.0; 6], 0.95).unwrap();
/// assert_eq!(policy.omega(&[1.0, 0.3, 2.0, 0.0, 1.0, 0.5]), 1.475);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct RelaxationPolicy {
    weights: [Real; 6],
    span: Real,
}

/// The JSON file of a policy (`models/learned-sor.json`): the format, the feature names (must
/// be [`FEATURES`]), the weights, the span, and free-form training facts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolicyFile {
    /// [`FORMAT`].
    pub format: String,
    /// [`FEATURES`], in weight order.
    pub features: Vec<String>,
    /// One weight per feature.
    pub weights: Vec<Real>,
    /// ω_i ∈ (1, 1 + `omega_span`); in (0, 1).
    pub omega_span: Real,
    /// How the weights were fitted (seeds, objective, history); not read by the policy.
    #[serde(default)]
    pub training: serde_json::Value,
}

impl RelaxationPolicy {
    /// A policy from its weights (finite) and span (in (0, 1), so that every ω < 2).
    pub fn new(weights: [Real; 6], span: Real) -> Result<Self, RelaxError> {
        Self::checked(weights, span, Path::new("<given>"))
    }

    fn checked(weights: [Real; 6], span: Real, path: &Path) -> Result<Self, RelaxError> {
        let policy = |reason: String| RelaxError::Policy {
            path: path.to_path_buf(),
            reason,
        };
        if let Some((i, w)) = weights.iter().enumerate().find(|(_, w)| !w.is_finite()) {
            return Err(policy(format!("weight {i} ({}) is {w}", FEATURES[i])));
        }
        if !(span > 0.0 && span < 1.0) {
            return Err(policy(format!("omega_span {span} is not in (0, 1)")));
        }
        Ok(Self { weights, span })
    }

    /// Reads a policy from JSON text (`path` names it in errors).
    pub fn from_json(text: &str, path: &Path) -> Result<Self, RelaxError> {
        let file: PolicyFile = serde_json::from_str(text).map_err(|e| RelaxError::Format {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        if file.format != FORMAT {
            return Err(RelaxError::Format {
                path: path.to_path_buf(),
                reason: format!("format `{}`, this build reads `{FORMAT}`", file.format),
            });
        }
        if file.features != FEATURES {
            return Err(RelaxError::Policy {
                path: path.to_path_buf(),
                reason: format!(
                    "features {:?}, this build computes {FEATURES:?}",
                    file.features
                ),
            });
        }
        let weights: [Real; 6] =
            file.weights
                .as_slice()
                .try_into()
                .map_err(|_| RelaxError::Policy {
                    path: path.to_path_buf(),
                    reason: format!(
                        "{} weights for {} features",
                        file.weights.len(),
                        FEATURES.len()
                    ),
                })?;
        Self::checked(weights, file.omega_span, path)
    }

    /// Reads a policy file.
    pub fn from_file(path: &Path) -> Result<Self, RelaxError> {
        let text = std::fs::read_to_string(path).map_err(|source| RelaxError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text, path)
    }

    /// The shipped policy (`models/learned-sor.json`, built into the crate).
    pub fn shipped() -> Result<Self, RelaxError> {
        Self::from_json(
            include_str!("../model/learned-sor.json"),
            &PathBuf::from("<embedded>/models/learned-sor.json"),
        )
    }

    /// The weights, in [`FEATURES`] order.
    pub fn weights(&self) -> &[Real; 6] {
        &self.weights
    }

    /// ω for features `g` ([`FEATURES`] order).
    pub fn omega(&self, g: &[Real; 6]) -> Real {
        let z: Real = self.weights.iter().zip(g).map(|(w, x)| w * x).sum();
        1.0 + self.span / (1.0 + (-z).exp())
    }

    /// The [`FEATURES`] of point `i` of the context's island.
    pub fn features(ctx: &WarmStartContext<'_>, i: usize) -> [Real; 6] {
        Self::point_features(ctx, i, Self::island_size(ctx))
    }

    /// The `log_island_points` feature, the same for every point of an island.
    fn island_size(ctx: &WarmStartContext<'_>) -> Real {
        (ctx.problem.len() as Real).ln() - 4.0
    }

    /// [`Self::features`] with the island's size feature given.
    fn point_features(ctx: &WarmStartContext<'_>, i: usize, size: Real) -> [Real; 6] {
        let problem = ctx.problem;
        let p = &problem.points[i];
        let carried = ctx.carried.get(i).copied().flatten();
        let fixed = |b: &ProblemBody| b.inv_mass == 0.0 && b.inv_inertia == 0.0;
        let wall =
            fixed(&problem.bodies[p.body_a as usize]) || fixed(&problem.bodies[p.body_b as usize]);
        [
            1.0,
            p.normal.y.abs(),
            (1.0 + 10.0 * carried.map_or(0.0, |c| c.normal.max(0.0))).ln(),
            if carried.is_none() { 1.0 } else { 0.0 },
            if wall { 1.0 } else { 0.0 },
            size,
        ]
    }
}

impl Relaxation for RelaxationPolicy {
    fn omegas(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut Vec<Real>,
    ) -> Result<(), WarmStartError> {
        out.clear();
        let size = Self::island_size(ctx);
        out.extend((0..ctx.problem.len()).map(|i| self.omega(&Self::point_features(ctx, i, size))));
        Ok(())
    }
}
