//! Runs every (solver, warm start, seed) world in parallel, results in job order.

use std::time::Instant;

use deepcontact_core::Registry;
use deepcontact_core::scene;
use deepcontact_pgs::PgsPositionSolver;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;

use super::{Config, Results, Run, StepRecord};
use crate::ExperimentError;

/// Runs the comparison with [`crate::full_registry`].
pub fn run_experiment(config: &Config) -> Result<Results, ExperimentError> {
    run_experiment_with(config, &crate::full_registry())
}

/// Runs the comparison with providers and solvers from `registry` (so a third-party
/// provider registered there can be compared with the baselines).
pub fn run_experiment_with(
    config: &Config,
    registry: &Registry,
) -> Result<Results, ExperimentError> {
    run_experiment_until(config, registry, &|| false)
}

/// [`run_experiment_with`] that asks `stop` before every step of every world: once it answers
/// `true`, no further step starts, the running worlds end after their current step and the
/// call returns [`ExperimentError::Stopped`] (an embedding uses it for Ctrl-C; nothing has been
/// written, since outputs are written only from finished [`Results`]).
pub fn run_experiment_until(
    config: &Config,
    registry: &Registry,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Results, ExperimentError> {
    config.validate()?;
    // Build every provider and solver once up front: spec errors surface before any work.
    for s in &config.warm_starts {
        registry.provider_from_spec(s)?;
    }
    for s in &config.solvers {
        registry.solver_from_spec(s)?;
    }
    for &seed in &config.seeds {
        scene::by_name(&config.scene, seed, config.bodies)?;
    }

    let jobs: Vec<(usize, usize, u64)> = (0..config.solvers.len())
        .flat_map(|s| {
            (0..config.warm_starts.len())
                .flat_map(move |w| config.seeds.iter().map(move |&k| (s, w, k)))
        })
        .collect();
    let threads = crate::threads(config.threads);
    let pool = crate::pool(threads)?;

    let total = jobs.len() as u64 * config.steps;
    let bar = if config.progress {
        ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    if let Ok(style) = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40}] {pos}/{len} steps, eta {eta} {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }

    let t0 = Instant::now();
    // `collect` keeps the job order whatever thread ran which job.
    let runs: Vec<Result<Run, ExperimentError>> = pool.install(|| {
        jobs.par_iter()
            .with_max_len(1)
            .map(|&(s, w, seed)| run_world(config, registry, (s, w, seed), stop, &bar))
            .collect()
    });
    let wall_seconds = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let runs = runs.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(Results {
        config: config.clone(),
        solvers: config.solver_labels(),
        warm_starts: config.warm_start_labels(),
        runs,
        threads,
        wall_seconds,
    })
}

fn run_world(
    config: &Config,
    registry: &Registry,
    (solver, warm_start, seed): (usize, usize, u64),
    stop: &(dyn Fn() -> bool + Sync),
    bar: &ProgressBar,
) -> Result<Run, ExperimentError> {
    let mut world = scene::by_name(&config.scene, seed, config.bodies)?.build(config.world)?;
    let mut provider = registry.provider_from_spec(&config.warm_starts[warm_start])?;
    let mut velocity = registry.solver_from_spec(&config.solvers[solver])?;
    let mut position = PgsPositionSolver::new();
    let mut run = Run {
        solver,
        warm_start,
        seed,
        steps: Vec::with_capacity(config.steps as usize),
        curves: Vec::with_capacity(config.steps as usize),
        diagnostics: Vec::new(),
    };
    for _ in 0..config.steps {
        if stop() {
            return Err(ExperimentError::Stopped);
        }
        let report = world.step(&mut provider, &mut velocity, &mut position)?;
        run.steps.push(StepRecord::from(&report));
        run.curves.push(if report.contacts > 0 {
            report.residual_curve
        } else {
            Vec::new()
        });
        bar.inc(1);
    }
    run.diagnostics = provider.diagnostics();
    Ok(run)
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    fn small() -> Config {
        Config {
            seeds: vec![12345, 12346],
            steps: 5,
            bodies: 30,
            threads: 1,
            progress: false,
            ..Config::with_warm_starts("none,builtin").unwrap()
        }
    }

    #[test]
    fn stop_ends_the_comparison_before_the_next_step() {
        let asked = AtomicUsize::new(0);
        let stop = || asked.fetch_add(1, Ordering::SeqCst) >= 3;
        let err = run_experiment_until(&small(), &crate::full_registry(), &stop).unwrap_err();
        assert!(matches!(err, ExperimentError::Stopped), "{err}");
        // One thread, jobs in order: the first world asked four times (three steps ran), each
        // of the three other worlds once, before its first step.
        assert_eq!(asked.load(Ordering::SeqCst), 4 + 3);
    }

    #[test]
    fn never_stopping_gives_the_plain_comparison() {
        let registry = crate::full_registry();
        let config = Config {
            steps: 40,
            ..small()
        };
        let a = run_experiment_until(&config, &registry, &|| false).unwrap();
        let b = run_experiment_with(&config, &registry).unwrap();
        let iterations = |r: &Results| -> Vec<u32> {
            r.runs
                .iter()
                .flat_map(|run| run.steps.iter().map(|s| s.iterations))
                .collect()
        };
        assert_eq!(iterations(&a), iterations(&b));
        assert!(
            iterations(&a).iter().any(|&i| i > 0),
            "no contact in 40 steps"
        );
        assert_eq!(a.runs.len(), 4);
    }
}
