//! The warm-start comparison of the thesis (what `deepcontact compare` runs).
//!
//! Every (solver, warm start, seed) triple is one world of the thesis pile (100 circles),
//! stepped `steps` times on one thread; the worlds run in parallel on a rayon pool. The
//! results are collected by job index, so every number except the wall times is the same
//! whatever the number of threads.
//!
//! Outputs (in `--out`, each written to a temporary file and renamed into place):
//! * `steps.csv` — one row per solver, warm start, seed and step;
//! * `curves.csv` — per solver, warm start and iteration: median ∞-norm residual and
//!   "iterators left";
//! * `summary.csv`, `summary.md`, `summary.json` — one row per solver and warm start;
//! * `figures/*.png|svg` — contacts, iterations, iterators left, residual and MSE figures.
//!
//! **Steps without contacts** (the free fall before the circles first touch) run no
//! velocity iteration. They are left out of every iteration and MSE statistic (mean and
//! median iterations, capped steps, curves, iterators left, MSE), and counted in the
//! contact and time statistics (mean contacts, milliseconds per step, speedups).
//!
//! **Iterations of a step** are those of its slowest island (`StepReport::velocity_iterations`),
//! and its residual at iteration *i* is the largest ∞-norm impulse change over the islands
//! still iterating, as in the world's `StepReport::residual_curve`.

mod figures;
mod output;
mod runner;
mod stats;

use deepcontact_core::registry::{Spec, split_spec_list};
use deepcontact_core::{StepReport, WorldSettings};

use crate::ExperimentError;

pub use figures::figures;
pub use output::{
    CURVES_COLUMNS, Outputs, STEPS_COLUMNS, SUMMARY_COLUMNS, curves_csv, steps_csv, summary_csv,
    summary_md, write_outputs,
};
pub use runner::{run_experiment, run_experiment_until, run_experiment_with};
pub use stats::{Curve, Summary, curves, median, summarize};

/// The thesis's providers and the classical contenders of docs/RESEARCH.md, the default of
/// `--warm-starts`.
pub const DEFAULT_WARM_STARTS: &str = "none,builtin,random,bad,copy,copy2,copy0,grid,pressure,peak,extrapolate,shock,tail,krylov,best,presolve,sor,graph,learned-sor";
/// The thesis's comparison seeds, the default of `--seeds` (end exclusive: 10 seeds).
pub const DEFAULT_SEEDS: &str = "12345..12355";
/// Iterations shown in the residual figure (the thesis's window).
pub const RESIDUAL_FIGURE_ITERATIONS: usize = 500;

/// What to run. [`Config::default`] is the thesis's comparison.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Config {
    /// Warm-start specs (default: the 19 of [`DEFAULT_WARM_STARTS`]).
    #[serde(serialize_with = "specs_as_strings")]
    pub warm_starts: Vec<Spec>,
    /// Velocity solver specs (default: `pgs`).
    #[serde(serialize_with = "specs_as_strings")]
    pub solvers: Vec<Spec>,
    /// Seeds of the pile (default 12345 to 12354).
    pub seeds: Vec<u64>,
    /// Steps per world (default 250).
    pub steps: u64,
    /// Circles in the pile (default 100).
    pub bodies: usize,
    /// Scene of every world, see [`deepcontact_core::scene::by_name`] (default `pile`;
    /// `thesis` starts from the original code's exact initial positions, seeds 12345–12354).
    pub scene: String,
    /// A registered scene spec (`box-pile:bodies=1000,friction=0.3`, see
    /// [`deepcontact_core::scene`]); when set it replaces `scene` and `bodies` (default
    /// `None`).
    #[serde(serialize_with = "spec_as_string")]
    pub scene_spec: Option<Spec>,
    /// World settings (default: the thesis's, cap 1000, tolerance 1e-4, ∞-norm).
    #[serde(skip)]
    pub world: WorldSettings,
    /// Worker threads; 0 (default) means one per core.
    pub threads: usize,
    /// Show a progress bar on stderr (default true; hidden anyway when stderr is not a terminal).
    #[serde(skip)]
    pub progress: bool,
    /// Same problems for every provider (default `None`: each provider steps its own world).
    /// `Some(label)`: the world of the warm start labelled `label` (one of `warm_starts`)
    /// sets every step's problem. Each step, every other provider's world is first made a
    /// copy of that world, so all providers start, solve and are measured on the same
    /// contacts, the same carried impulses (the driver's last solution) and the same
    /// positions: the figures compare starts, not the trajectories they lead to. Providers
    /// that remember earlier steps remember the driver's.
    pub same_problems: Option<String>,
}

fn spec_as_string<S: serde::Serializer>(spec: &Option<Spec>, s: S) -> Result<S::Ok, S::Error> {
    match spec {
        Some(spec) => s.serialize_some(&spec.to_string()),
        None => s.serialize_none(),
    }
}

fn specs_as_strings<S: serde::Serializer>(specs: &[Spec], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(specs.iter().map(|x| x.to_string()))
}

impl Default for Config {
    fn default() -> Self {
        Self {
            warm_starts: split_spec_list(DEFAULT_WARM_STARTS).unwrap_or_default(),
            solvers: vec![Spec {
                name: "pgs".into(),
                params: Default::default(),
            }],
            seeds: (12345..12355).collect(),
            steps: 250,
            bodies: 100,
            scene: "pile".into(),
            scene_spec: None,
            world: WorldSettings::default(),
            threads: 0,
            progress: true,
            same_problems: None,
        }
    }
}

impl Config {
    /// The default comparison with the warm starts of `list` (a comma-separated spec list).
    pub fn with_warm_starts(list: &str) -> Result<Self, ExperimentError> {
        Ok(Self {
            warm_starts: split_spec_list(list)?,
            ..Self::default()
        })
    }

    /// Labels of the warm starts (their specs as text), in order.
    pub fn warm_start_labels(&self) -> Vec<String> {
        self.warm_starts.iter().map(Spec::to_string).collect()
    }

    /// Index of the warm start whose world sets the problems ([`Config::same_problems`]), if
    /// any and listed.
    pub fn driver(&self) -> Option<usize> {
        let label = self.same_problems.as_ref()?;
        self.warm_start_labels().iter().position(|l| l == label)
    }

    /// The world of `seed`: [`Self::scene_spec`] built by `registry`, else [`Self::scene`]
    /// with [`Self::bodies`] ([`crate::scene_for`]).
    pub fn scene_of(
        &self,
        registry: &deepcontact_core::Registry,
        seed: u64,
    ) -> Result<deepcontact_core::scene::Scene, ExperimentError> {
        Ok(match &self.scene_spec {
            Some(spec) => registry.scene_from_spec(spec, seed)?,
            None => crate::scene_for(registry, &self.scene, seed, self.bodies)?,
        })
    }

    /// Labels of the solvers, in order.
    pub fn solver_labels(&self) -> Vec<String> {
        self.solvers.iter().map(Spec::to_string).collect()
    }

    /// Rejects empty lists, duplicate labels, zero steps or bodies and invalid world settings.
    pub fn validate(&self) -> Result<(), ExperimentError> {
        let usage = |m: &str| Err(ExperimentError::Invalid(m.to_string()));
        if self.warm_starts.is_empty() {
            return usage("no warm start to compare");
        }
        if self.solvers.is_empty() {
            return usage("no solver given");
        }
        if self.seeds.is_empty() {
            return usage("no seed given");
        }
        if self.steps == 0 {
            return usage("--steps must be at least 1");
        }
        if self.bodies == 0 {
            return usage("--bodies must be at least 1");
        }
        for labels in [self.warm_start_labels(), self.solver_labels()] {
            for (i, l) in labels.iter().enumerate() {
                if labels[..i].contains(l) {
                    return Err(ExperimentError::Invalid(format!("`{l}` is listed twice")));
                }
            }
        }
        if let Some(driver) = &self.same_problems {
            if self.driver().is_none() {
                return Err(ExperimentError::Invalid(format!(
                    "--same-problems `{driver}` is not one of the warm starts ({})",
                    self.warm_start_labels().join(", ")
                )));
            }
        }
        let mut seeds = self.seeds.clone();
        seeds.sort_unstable();
        if seeds.windows(2).any(|w| w[0] == w[1]) {
            return usage("a seed is listed twice");
        }
        self.world.validate()?;
        crate::limits::check_threads(self.threads)?;
        // Per step a record and, in the worst case, a residual for every iteration up to the cap.
        let runs = (self.solvers.len() * self.warm_starts.len() * self.seeds.len()) as u128;
        let per_step = std::mem::size_of::<StepRecord>() as u128
            + 8 * u128::from(self.world.solver.max_iterations);
        crate::limits::check_memory(
            "this comparison",
            runs * u128::from(self.steps) * per_step,
            "lower --steps, the seeds, the providers or --max-iterations",
        )?;
        Ok(())
    }
}

/// What one step did (a flat copy of the parts of [`StepReport`] the comparison uses).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StepRecord {
    /// Step index (0 = first step of the world).
    pub step: u64,
    /// Contact points.
    pub contacts: usize,
    /// Islands with contacts.
    pub islands: usize,
    /// Velocity iterations of the slowest island.
    pub iterations: u32,
    /// Velocity iterations summed over islands.
    pub iterations_sum: u64,
    /// Islands that hit the iteration cap.
    pub capped_islands: usize,
    /// ∞-norm residual (max |Δλ|, N·s) of the last iteration.
    pub final_residual: f64,
    /// Natural-map residual of the final impulses (N·s).
    pub natural_residual: f64,
    /// Mean squared difference between warm start and final impulse, normal rows ((N·s)²).
    pub mse_normal: f64,
    /// Same, tangent rows.
    pub mse_tangent: f64,
    /// Islands whose warm start was rejected (fell back to zeros).
    pub fallbacks: usize,
    /// Seconds in the provider.
    pub warm_start_seconds: f64,
    /// Seconds in the velocity solver.
    pub solve_seconds: f64,
    /// Seconds of the whole step.
    pub step_seconds: f64,
    /// Passes the provider spent, summed over islands.
    pub provider_passes: u64,
    /// Mean penetration depth over contact points at the start of the step (m).
    pub penetration_mean: f64,
    /// Deepest penetration at the start of the step (m).
    pub penetration_max: f64,
    /// Mean normal velocity error after the solve (m/s; see [`StepReport`]).
    pub normal_velocity_error_mean: f64,
    /// Largest normal velocity error after the solve (m/s).
    pub normal_velocity_error_max: f64,
    /// Kinetic energy at the end of the step (J).
    pub kinetic_energy: f64,
}

impl From<&StepReport> for StepRecord {
    fn from(r: &StepReport) -> Self {
        Self {
            step: r.step,
            contacts: r.contacts,
            islands: r.islands,
            iterations: r.velocity_iterations,
            iterations_sum: r.velocity_iterations_sum,
            capped_islands: r.capped_islands,
            final_residual: r.final_residual(),
            natural_residual: r.natural_residual,
            mse_normal: r.mse_normal,
            mse_tangent: r.mse_tangent,
            fallbacks: r.fallbacks,
            warm_start_seconds: r.warm_start_seconds,
            solve_seconds: r.solve_seconds,
            step_seconds: r.step_seconds,
            provider_passes: r.provider_passes,
            penetration_mean: r.penetration_mean,
            penetration_max: r.penetration_max,
            normal_velocity_error_mean: r.normal_velocity_error_mean,
            normal_velocity_error_max: r.normal_velocity_error_max,
            kinetic_energy: r.kinetic_energy,
        }
    }
}

/// One world: a solver, a warm start and a seed, stepped `steps` times.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Index into [`Results::solvers`].
    pub solver: usize,
    /// Index into [`Results::warm_starts`].
    pub warm_start: usize,
    /// Seed of the pile.
    pub seed: u64,
    /// One record per step.
    pub steps: Vec<StepRecord>,
    /// Per step, the ∞-norm residual of every iteration (empty for steps without contacts).
    pub curves: Vec<Vec<f64>>,
    /// The provider's [`deepcontact_core::WarmStart::diagnostics`] after the last step (its
    /// learned or adapted state; empty for most providers).
    pub diagnostics: Vec<(String, f64)>,
}

/// Everything a comparison measured.
#[derive(Debug, Clone)]
pub struct Results {
    /// The config it ran.
    pub config: Config,
    /// Solver labels.
    pub solvers: Vec<String>,
    /// Warm-start labels.
    pub warm_starts: Vec<String>,
    /// Runs ordered by solver, then warm start, then seed (the job order).
    pub runs: Vec<Run>,
    /// Worker threads in the pool (`Config::threads`, 0 resolved to the core count).
    pub threads: usize,
    /// Workers that ran at least one (solver, seed) job: at most `threads` and the job count.
    /// It depends on scheduling, like the wall times, and is not written to the outputs; 0
    /// when not known (results merged from parts run elsewhere).
    pub workers_used: usize,
    /// Wall time of the whole experiment, seconds.
    pub wall_seconds: f64,
}

impl Results {
    /// The runs of one solver and warm start, in seed order.
    pub fn group(&self, solver: usize, warm_start: usize) -> &[Run] {
        let n = self.config.seeds.len();
        let start = (solver * self.warm_starts.len() + warm_start) * n;
        &self.runs[start..start + n]
    }
}
