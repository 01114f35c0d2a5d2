//! `deepcontact soak`: the thesis pile for a long time with each warm start, checked every
//! step. A long-run health check cheap enough for CI (release build, about a minute on 2 cores
//! with the defaults).
//!
//! Per step: every dynamic body finite and inside the box, no warm-start fallback. After
//! settling (`--settle` steps): the kinetic energy stays under 1 % of the pile's
//! potential-energy scale (`Σ m g h` at the start), and the deepest penetration under 5 cm.
//! The first violation stops that provider's run with an error naming the step and body.

use std::time::Instant;

use clap::Args;
use deepcontact_core::{BodyKind, Real, World, WorldSettings, scene};
use deepcontact_warmstart::{Registry, split_spec_list};
use rayon::prelude::*;

use crate::common::{CliError, registry};

/// Kinetic energy allowed after settling, as a fraction of the potential-energy scale.
pub const KE_FRACTION: Real = 1e-2;
/// Deepest penetration allowed after settling, in metres.
pub const MAX_PENETRATION: Real = 0.05;

/// Options of `soak`.
#[derive(Debug, Clone, Args)]
pub struct SoakArgs {
    /// Warm starts to soak (comma-separated registry specs).
    #[arg(long, default_value = "none,builtin,random,bad,copy")]
    pub warm_starts: String,
    /// Steps per warm start (200 s of simulated time at dt = 0.01).
    #[arg(long, default_value_t = 20_000)]
    pub steps: u64,
    /// Steps for the oracle providers (`copy…`, `grid`), which solve every step twice.
    #[arg(long, default_value_t = 2_000)]
    pub oracle_steps: u64,
    /// Steps after which the pile counts as settled (energy and penetration checked from here).
    #[arg(long, default_value_t = 1_000)]
    pub settle: u64,
    /// Seed of the pile.
    #[arg(long, default_value_t = 12345)]
    pub seed: u64,
    /// Circles in the pile.
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Worker threads (default: one per core); one provider per thread.
    #[arg(long)]
    pub threads: Option<usize>,
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

fn violation(spec: &str, step: u64, what: String) -> CliError {
    CliError::Soak {
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
) -> Result<SoakRun, CliError> {
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

/// Whether a provider solves every step itself (and gets `--oracle-steps`).
fn is_oracle(spec: &str) -> bool {
    spec.starts_with("copy") || spec.starts_with("grid")
}

/// Runs `soak`.
pub fn run(args: SoakArgs) -> Result<(), CliError> {
    let specs = split_spec_list(&args.warm_starts)?;
    if args.steps <= args.settle {
        return Err(CliError::Usage(format!(
            "--steps {} must exceed --settle {}",
            args.steps, args.settle
        )));
    }
    let registry = registry();
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CliError::Usage(format!("cannot start {threads} threads: {e}")))?;
    let t0 = Instant::now();
    let runs: Vec<Result<SoakRun, CliError>> = pool.install(|| {
        specs
            .par_iter()
            .with_max_len(1)
            .map(|spec| {
                let spec = spec.to_string();
                let steps = if is_oracle(&spec) {
                    args.oracle_steps.max(args.settle + 1)
                } else {
                    args.steps
                };
                soak_one(&registry, &spec, steps, args.settle, args.seed, args.bodies)
            })
            .collect()
    });
    let runs = runs.into_iter().collect::<Result<Vec<_>, _>>()?;
    println!(
        "Soak: pile of {} circles, seed {}, checks from step {} on; {threads} threads, {:.1} s wall\n",
        args.bodies,
        args.seed,
        args.settle,
        t0.elapsed().as_secs_f64()
    );
    println!(
        "| warm_start | steps | seconds | mean_iterations | max KE after settling (J) | KE / PE scale | min separation (m) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for r in &runs {
        println!(
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
    println!("\nall checks passed (no fallback, no escape, no NaN at any step)");
    Ok(())
}
