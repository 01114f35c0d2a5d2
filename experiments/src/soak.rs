//! The soak (what `deepcontact soak` runs): the thesis pile for a long time with each warm start, checked every
//! step. A long-run health check cheap enough for CI (release build, about a minute on 2 cores
//! with the defaults).
//!
//! Per step: every dynamic body finite and inside the box, no warm-start fallback. After
//! settling (`--settle` steps): the kinetic energy stays under 1 % of the pile's
//! potential-energy scale (`Σ m g h` at the start), and the deepest penetration under 5 cm.
//! The first violation stops that provider's run with an error naming the step and body.

use std::time::Instant;

use deepcontact_core::registry::{Spec, split_spec_list};
use deepcontact_core::{BodyKind, Real, Registry, World, WorldSettings, scene};
use rayon::prelude::*;

use crate::ExperimentError;

/// Kinetic energy allowed after settling, as a fraction of the potential-energy scale.
pub const KE_FRACTION: Real = 1e-2;
/// Deepest penetration allowed after settling, in metres.
pub const MAX_PENETRATION: Real = 0.05;

/// What to soak. [`SoakConfig::default`] is what `.ci/run` runs.
#[derive(Debug, Clone, PartialEq)]
pub struct SoakConfig {
    /// Warm starts to soak (default `none, builtin, random, bad, copy`).
    pub warm_starts: Vec<Spec>,
    /// Steps per warm start (default 20 000: 200 s of simulated time at dt = 0.01).
    pub steps: u64,
    /// Steps for oracle providers ([`deepcontact_core::ProviderInfo::oracle`]), which solve
    /// every step twice (default 2 000).
    pub oracle_steps: u64,
    /// Steps after which the pile counts as settled (default 1 000).
    pub settle: u64,
    /// Seed of the pile (default 12345).
    pub seed: u64,
    /// Circles in the pile (default 100).
    pub bodies: usize,
    /// Worker threads, one provider per thread; 0 (default) means one per core.
    pub threads: usize,
}

/// The default of [`SoakConfig::warm_starts`].
pub const DEFAULT_SOAK_WARM_STARTS: &str = "none,builtin,random,bad,copy";

impl Default for SoakConfig {
    fn default() -> Self {
        Self {
            warm_starts: split_spec_list(DEFAULT_SOAK_WARM_STARTS).unwrap_or_default(),
            steps: 20_000,
            oracle_steps: 2_000,
            settle: 1_000,
            seed: 12345,
            bodies: 100,
            threads: 0,
        }
    }
}

/// What one provider's soak measured.
#[derive(Debug, Clone, PartialEq)]
pub struct SoakRun {
    /// The provider spec.
    pub warm_start: String,
    /// Steps run.
    pub steps: u64,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Mean velocity iterations per step (slowest island).
    pub mean_iterations: Real,
    /// Largest kinetic energy after settling (J).
    pub max_kinetic_energy: Real,
    /// Potential-energy scale of the pile at the start (J).
    pub potential_energy: Real,
    /// Deepest contact separation after settling (m, negative = penetration).
    pub min_separation: Real,
}

fn potential_energy(world: &World) -> Real {
    let g = world.settings().gravity.norm();
    world
        .bodies()
        .iter()
        .filter(|b| b.kind == BodyKind::Dynamic)
        .map(|b| b.mass * g * b.position.y)
        .sum()
}

fn violation(spec: &str, step: u64, what: String) -> ExperimentError {
    ExperimentError::Soak {
        warm_start: spec.to_string(),
        step,
        what,
    }
}

/// Soaks one provider for `steps` steps; the first violated check is an error.
pub fn soak_one(
    registry: &Registry,
    spec: &str,
    steps: u64,
    settle: u64,
    seed: u64,
    bodies: usize,
) -> Result<SoakRun, ExperimentError> {
    let scene = scene::pile(seed, bodies)?;
    let (lo, hi) = (scene.min, scene.max);
    let mut world = scene.build(WorldSettings::default())?;
    let pe0 = potential_energy(&world);
    let mut warm = registry.build_provider(spec)?;
    let mut solver = registry.build_solver("pgs")?;
    let mut position = deepcontact_pgs::PgsPositionSolver::new();
    let (mut max_ke, mut min_sep): (Real, Real) = (0.0, 0.0);
    let mut iterations = 0u64;
    let start = Instant::now();
    for _ in 0..steps {
        let r = world.step(warm.as_mut(), solver.as_mut(), &mut position)?;
        for (i, b) in world.bodies().iter().enumerate() {
            if b.kind != BodyKind::Dynamic {
                continue;
            }
            let state = b.state();
            if !state.iter().all(|v| v.is_finite()) {
                return Err(violation(
                    spec,
                    r.step,
                    format!("body {i} not finite: {state:?}"),
                ));
            }
            let p = b.position;
            if !((lo.x..=hi.x).contains(&p.x) && (lo.y..=hi.y).contains(&p.y)) {
                return Err(violation(
                    spec,
                    r.step,
                    format!("body {i} escaped the box to ({}, {})", p.x, p.y),
                ));
            }
        }
        if r.fallbacks > 0 {
            return Err(violation(
                spec,
                r.step,
                format!("{} warm-start fallback(s)", r.fallbacks),
            ));
        }
        iterations += u64::from(r.velocity_iterations);
        if r.step >= settle {
            let ke = world.kinetic_energy();
            max_ke = max_ke.max(ke);
            min_sep = min_sep.min(r.min_separation);
            if ke >= KE_FRACTION * pe0 {
                return Err(violation(
                    spec,
                    r.step,
                    format!(
                        "kinetic energy {ke:.3e} J after settling (limit {:.3e} J)",
                        KE_FRACTION * pe0
                    ),
                ));
            }
            if r.min_separation <= -MAX_PENETRATION {
                return Err(violation(
                    spec,
                    r.step,
                    format!("penetration {:.4} m after settling", -r.min_separation),
                ));
            }
        }
    }
    Ok(SoakRun {
        warm_start: spec.to_string(),
        steps,
        seconds: start.elapsed().as_secs_f64(),
        mean_iterations: iterations as Real / steps.max(1) as Real,
        max_kinetic_energy: max_ke,
        potential_energy: pe0,
        min_separation: min_sep,
    })
}

/// Soaks every provider of `config` (in parallel, one per thread); the first violation of
/// any provider is the error. Returns the runs in the order of `config.warm_starts` and the
/// number of threads used.
pub fn run_soak(
    config: &SoakConfig,
    registry: &Registry,
) -> Result<(Vec<SoakRun>, usize), ExperimentError> {
    if config.steps <= config.settle {
        return Err(ExperimentError::Invalid(format!(
            "soak steps {} must exceed settle {}",
            config.steps, config.settle
        )));
    }
    crate::limits::check_threads(config.threads)?;
    let threads = crate::threads(config.threads);
    let pool = crate::pool(threads)?;
    let runs: Vec<Result<SoakRun, ExperimentError>> = pool.install(|| {
        config
            .warm_starts
            .par_iter()
            .with_max_len(1)
            .map(|spec| {
                let steps = if registry.is_oracle(spec) {
                    config.oracle_steps.max(config.settle + 1)
                } else {
                    config.steps
                };
                soak_one(
                    registry,
                    &spec.to_string(),
                    steps,
                    config.settle,
                    config.seed,
                    config.bodies,
                )
            })
            .collect()
    });
    Ok((runs.into_iter().collect::<Result<Vec<_>, _>>()?, threads))
}

/// The soak's report: a Markdown table of `runs` under one line of settings.
pub fn soak_table(
    config: &SoakConfig,
    runs: &[SoakRun],
    threads: usize,
    wall_seconds: f64,
) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Soak: pile of {} circles, seed {}, checks from step {} on; {threads} threads, {wall_seconds:.1} s wall\n",
        config.bodies, config.seed, config.settle
    );
    let _ = writeln!(
        s,
        "| warm_start | steps | seconds | mean_iterations | max KE after settling (J) | KE / PE scale | min separation (m) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|");
    for r in runs {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {:.3e} | {:.1e} | {:.4} |",
            r.warm_start,
            r.steps,
            r.seconds,
            r.mean_iterations,
            r.max_kinetic_energy,
            r.max_kinetic_energy / r.potential_energy,
            r.min_separation
        );
    }
    let _ = writeln!(
        s,
        "\nall checks passed (no fallback, no escape, no NaN at any step)"
    );
    s
}
