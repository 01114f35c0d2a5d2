//! `deepcontact compare`: the thesis's provider comparison.
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

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use deepcontact_core::{StepReport, WorldSettings, scene};
use deepcontact_pgs::PgsPositionSolver;
use deepcontact_warmstart::{Registry, Spec, split_spec_list};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;

use crate::common::{CliError, SolverArgs};
use crate::plots::{self, Figure, Panel, Scale, Series};

/// The thesis's providers, the default of `--warm-starts`.
pub const DEFAULT_WARM_STARTS: &str = "none,builtin,random,bad,copy,copy2,copy0,pressure,peak";
/// The thesis's comparison seeds, the default of `--seeds` (end exclusive: 10 seeds).
pub const DEFAULT_SEEDS: &str = "12345..12355";
/// Iterations shown in the residual figure (the thesis's window).
pub const RESIDUAL_FIGURE_ITERATIONS: usize = 500;

/// Options of `compare`.
#[derive(Debug, Clone, Args)]
pub struct CompareArgs {
    /// Warm starts to compare: comma-separated registry specs (`random:seed=3,normal_max=4`
    /// keeps its parameters together).
    #[arg(long, default_value = DEFAULT_WARM_STARTS)]
    pub warm_starts: String,
    /// Seeds of the pile: `a..b` (end exclusive), `a..=b`, or a comma-separated list.
    #[arg(long, default_value = DEFAULT_SEEDS)]
    pub seeds: String,
    /// Steps per world.
    #[arg(long, default_value_t = 250)]
    pub steps: u64,
    /// Circles in the pile (the box grows to keep the density).
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Velocity solver and stop rule (`--solver` is replaced by `--solvers` when given).
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Several velocity solvers (comma-separated registry specs): one table of solver × warm start.
    #[arg(long)]
    pub solvers: Option<String>,
    /// Worker threads (default: one per core). Each world runs on one thread.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output directory (created if missing).
    #[arg(long, default_value = "results")]
    pub out: PathBuf,
    /// Skip the figures.
    #[arg(long)]
    pub no_plots: bool,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// What to run. [`Config::default`] is the thesis's comparison.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Config {
    /// Warm-start specs (default: `none, builtin, random, bad, copy, copy2, copy0`).
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
    /// World settings (default: the thesis's, cap 1000, tolerance 1e-4, ∞-norm).
    #[serde(skip)]
    pub world: WorldSettings,
    /// Worker threads; 0 (default) means one per core.
    pub threads: usize,
    /// Show a progress bar on stderr (default true; hidden anyway when stderr is not a terminal).
    #[serde(skip)]
    pub progress: bool,
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
            world: WorldSettings::default(),
            threads: 0,
            progress: true,
        }
    }
}

impl Config {
    /// The config described by command-line options.
    pub fn from_args(args: &CompareArgs) -> Result<Self, CliError> {
        let solvers = match &args.solvers {
            Some(list) => split_spec_list(list)?,
            None => vec![args.solver.solver.parse()?],
        };
        Ok(Self {
            warm_starts: split_spec_list(&args.warm_starts)?,
            solvers,
            seeds: parse_seeds(&args.seeds)?,
            steps: args.steps,
            bodies: args.bodies,
            world: args.solver.world_settings(),
            threads: args.threads.unwrap_or(0),
            progress: !args.quiet,
        })
    }

    /// Labels of the warm starts (their specs as text), in order.
    pub fn warm_start_labels(&self) -> Vec<String> {
        self.warm_starts.iter().map(Spec::to_string).collect()
    }

    /// Labels of the solvers, in order.
    pub fn solver_labels(&self) -> Vec<String> {
        self.solvers.iter().map(Spec::to_string).collect()
    }

    /// Rejects empty lists, duplicate labels, zero steps or bodies and invalid world settings.
    pub fn validate(&self) -> Result<(), CliError> {
        let usage = |m: &str| Err(CliError::Usage(m.to_string()));
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
                    return Err(CliError::Usage(format!("`{l}` is listed twice")));
                }
            }
        }
        let mut seeds = self.seeds.clone();
        seeds.sort_unstable();
        if seeds.windows(2).any(|w| w[0] == w[1]) {
            return usage("a seed is listed twice");
        }
        self.world.validate()?;
        Ok(())
    }
}

/// Parses `a..b` (end exclusive), `a..=b`, a single seed or a comma-separated list.
pub fn parse_seeds(text: &str) -> Result<Vec<u64>, CliError> {
    let bad = |why: &str| CliError::Usage(format!("--seeds `{text}`: {why}"));
    let num = |s: &str| s.trim().parse::<u64>().map_err(|e| bad(&e.to_string()));
    let t = text.trim();
    let seeds: Vec<u64> = if let Some((a, b)) = t.split_once("..=") {
        (num(a)?..=num(b)?).collect()
    } else if let Some((a, b)) = t.split_once("..") {
        (num(a)?..num(b)?).collect()
    } else {
        t.split(',')
            .filter(|s| !s.trim().is_empty())
            .map(num)
            .collect::<Result<_, _>>()?
    };
    if seeds.is_empty() {
        return Err(bad("no seed in range"));
    }
    if seeds.len() > 1_000_000 {
        return Err(bad("more than a million seeds"));
    }
    Ok(seeds)
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
    /// Threads used.
    pub threads: usize,
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

/// Runs the comparison with the CLI's registry ([`crate::common::registry`]).
pub fn run_experiment(config: &Config) -> Result<Results, CliError> {
    run_experiment_with(config, &crate::common::registry())
}

/// Runs the comparison with providers and solvers from `registry` (so a third-party
/// provider registered there can be compared with the baselines).
pub fn run_experiment_with(config: &Config, registry: &Registry) -> Result<Results, CliError> {
    config.validate()?;
    // Build every provider and solver once up front: spec errors surface before any work.
    for s in &config.warm_starts {
        registry.provider_from_spec(s)?;
    }
    for s in &config.solvers {
        registry.solver_from_spec(s)?;
    }
    for &seed in &config.seeds {
        scene::pile(seed, config.bodies)?;
    }

    let jobs: Vec<(usize, usize, u64)> = (0..config.solvers.len())
        .flat_map(|s| {
            (0..config.warm_starts.len())
                .flat_map(move |w| config.seeds.iter().map(move |&k| (s, w, k)))
        })
        .collect();
    let threads = if config.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        config.threads
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CliError::Usage(format!("cannot start {threads} threads: {e}")))?;

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
    let runs: Vec<Result<Run, CliError>> = pool.install(|| {
        jobs.par_iter()
            .with_max_len(1)
            .map(|&(s, w, seed)| run_world(config, registry, s, w, seed, &bar))
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
    solver: usize,
    warm_start: usize,
    seed: u64,
    bar: &ProgressBar,
) -> Result<Run, CliError> {
    let mut world = scene::pile(seed, config.bodies)?.build(config.world)?;
    let mut provider = registry.provider_from_spec(&config.warm_starts[warm_start])?;
    let mut velocity = registry.solver_from_spec(&config.solvers[solver])?;
    let mut position = PgsPositionSolver::new();
    let mut run = Run {
        solver,
        warm_start,
        seed,
        steps: Vec::with_capacity(config.steps as usize),
        curves: Vec::with_capacity(config.steps as usize),
    };
    for _ in 0..config.steps {
        let report = world.step(&mut provider, &mut velocity, &mut position)?;
        run.steps.push(StepRecord::from(&report));
        run.curves.push(if report.contacts > 0 {
            report.residual_curve
        } else {
            Vec::new()
        });
        bar.inc(1);
    }
    Ok(run)
}

/// One row of the summary: a solver and a warm start over all seeds.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Solver label.
    pub solver: String,
    /// Warm-start label.
    pub warm_start: String,
    /// Worlds (seeds).
    pub seeds: usize,
    /// Steps over all seeds.
    pub steps: usize,
    /// Steps with at least one contact (the ones iteration statistics use).
    pub contact_steps: usize,
    /// Mean velocity iterations per contact step.
    pub mean_iterations: f64,
    /// Median velocity iterations per contact step.
    pub median_iterations: f64,
    /// Most velocity iterations of any step.
    pub max_iterations: u32,
    /// Contact steps in which an island hit the iteration cap.
    pub capped_steps: usize,
    /// Mean contact points per step (all steps).
    pub mean_contacts: f64,
    /// Mean milliseconds per step in the provider (all steps).
    pub warm_start_ms: f64,
    /// Mean milliseconds per step in the velocity solver.
    pub solve_ms: f64,
    /// Mean milliseconds per step in total.
    pub step_ms: f64,
    /// Mean over contact steps of the normal MSE between warm start and final impulse ((N·s)²).
    pub mse_normal: f64,
    /// Same, tangent.
    pub mse_tangent: f64,
    /// Islands whose warm start was rejected, summed.
    pub fallbacks: usize,
    /// Total step time of `none` (same solver) divided by this one's; `None` without `none`.
    pub speedup_vs_none: Option<f64>,
    /// Total step time of `builtin` (same solver) divided by this one's; `None` without `builtin`.
    pub speedup_vs_builtin: Option<f64>,
}

/// Median of `v` (mean of the two middle values for an even count; 0 when empty). Reorders `v`.
pub fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    let (_, &mut hi, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    if n % 2 == 1 {
        return hi;
    }
    let lo = v[..n / 2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
    0.5 * (lo + hi)
}

fn mean(sum: f64, n: usize) -> f64 {
    if n == 0 { 0.0 } else { sum / n as f64 }
}

/// The summary rows, ordered by solver, then warm start.
pub fn summarize(results: &Results) -> Vec<Summary> {
    let mut rows = Vec::new();
    for s in 0..results.solvers.len() {
        let first = rows.len();
        for w in 0..results.warm_starts.len() {
            let runs = results.group(s, w);
            let steps: Vec<&StepRecord> = runs.iter().flat_map(|r| &r.steps).collect();
            let contact: Vec<&StepRecord> =
                steps.iter().copied().filter(|r| r.contacts > 0).collect();
            let mut iterations: Vec<f64> =
                contact.iter().map(|r| f64::from(r.iterations)).collect();
            let sum = |f: fn(&StepRecord) -> f64, of: &[&StepRecord]| {
                of.iter().map(|r| f(r)).sum::<f64>()
            };
            rows.push(Summary {
                solver: results.solvers[s].clone(),
                warm_start: results.warm_starts[w].clone(),
                seeds: runs.len(),
                steps: steps.len(),
                contact_steps: contact.len(),
                mean_iterations: mean(iterations.iter().sum(), iterations.len()),
                median_iterations: median(&mut iterations),
                max_iterations: contact.iter().map(|r| r.iterations).max().unwrap_or(0),
                capped_steps: contact.iter().filter(|r| r.capped_islands > 0).count(),
                mean_contacts: mean(sum(|r| r.contacts as f64, &steps), steps.len()),
                warm_start_ms: 1e3 * mean(sum(|r| r.warm_start_seconds, &steps), steps.len()),
                solve_ms: 1e3 * mean(sum(|r| r.solve_seconds, &steps), steps.len()),
                step_ms: 1e3 * mean(sum(|r| r.step_seconds, &steps), steps.len()),
                mse_normal: mean(sum(|r| r.mse_normal, &contact), contact.len()),
                mse_tangent: mean(sum(|r| r.mse_tangent, &contact), contact.len()),
                fallbacks: steps.iter().map(|r| r.fallbacks).sum(),
                speedup_vs_none: None,
                speedup_vs_builtin: None,
            });
        }
        // Speedups in total step time against the references of the same solver.
        let reference = |name: &str| {
            rows[first..]
                .iter()
                .find(|r| r.warm_start == name)
                .map(|r| r.step_ms)
        };
        let (none, builtin) = (reference("none"), reference("builtin"));
        for row in &mut rows[first..] {
            let ratio =
                |base: Option<f64>| base.filter(|_| row.step_ms > 0.0).map(|b| b / row.step_ms);
            row.speedup_vs_none = ratio(none);
            row.speedup_vs_builtin = ratio(builtin);
        }
    }
    rows
}

/// Convergence curves of one solver and warm start over all contact steps of all seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// Solver label.
    pub solver: String,
    /// Warm-start label.
    pub warm_start: String,
    /// Contact steps the curve summarises.
    pub steps: usize,
    /// `median_residual[i]`: median over steps of the ∞-norm residual after iteration `i + 1`
    /// (a step that finished earlier repeats its last value).
    pub median_residual: Vec<f64>,
    /// `iterators_left[i]`: steps still iterating after `i + 1` iterations.
    pub iterators_left: Vec<usize>,
}

/// The curves, ordered by solver, then warm start.
pub fn curves(results: &Results) -> Vec<Curve> {
    let mut out = Vec::new();
    let mut column = Vec::new();
    for s in 0..results.solvers.len() {
        for w in 0..results.warm_starts.len() {
            let steps: Vec<&[f64]> = results
                .group(s, w)
                .iter()
                .flat_map(|r| &r.curves)
                .filter(|c| !c.is_empty())
                .map(Vec::as_slice)
                .collect();
            let len = steps.iter().map(|c| c.len()).max().unwrap_or(0);
            let mut curve = Curve {
                solver: results.solvers[s].clone(),
                warm_start: results.warm_starts[w].clone(),
                steps: steps.len(),
                median_residual: Vec::with_capacity(len),
                iterators_left: Vec::with_capacity(len),
            };
            for i in 0..len {
                column.clear();
                column.extend(
                    steps
                        .iter()
                        .map(|c| c.get(i).or(c.last()).copied().unwrap_or(0.0)),
                );
                curve.median_residual.push(median(&mut column));
                curve
                    .iterators_left
                    .push(steps.iter().filter(|c| c.len() > i + 1).count());
            }
            out.push(curve);
        }
    }
    out
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename,
/// so that `path` is either the old file or the complete new one, never half written.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    let io = |source| CliError::Io {
        path: path.display().to_string(),
        source,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let written = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })();
    if let Err(e) = written.and_then(|_| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    Ok(())
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn csv(field: &str) -> String {
    if field.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_string()
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(String::new, |x| format!("{x:.digits$}"))
}

/// Column names of `steps.csv`.
pub const STEPS_COLUMNS: &str = "solver,warm_start,seed,step,contacts,islands,iterations,iterations_sum,capped_islands,\
residual_inf,natural_residual,mse_normal,mse_tangent,fallbacks,warm_start_ms,solve_ms,step_ms";
/// Column names of `curves.csv`.
pub const CURVES_COLUMNS: &str =
    "solver,warm_start,iteration,median_residual_inf,iterators_left,steps";
/// Column names of `summary.csv`.
pub const SUMMARY_COLUMNS: &str = "solver,warm_start,seeds,steps,contact_steps,mean_iterations,median_iterations,\
max_iterations,capped_steps,mean_contacts,warm_start_ms,solve_ms,step_ms,mse_normal,mse_tangent,fallbacks,\
speedup_vs_none,speedup_vs_builtin";

/// `steps.csv`: one row per solver, warm start, seed and step.
pub fn steps_csv(results: &Results) -> String {
    let mut s = String::with_capacity(160 * results.runs.len() * results.config.steps as usize);
    s.push_str(STEPS_COLUMNS);
    s.push('\n');
    for run in &results.runs {
        let (solver, warm) = (
            csv(&results.solvers[run.solver]),
            csv(&results.warm_starts[run.warm_start]),
        );
        for r in &run.steps {
            let _ = writeln!(
                s,
                "{solver},{warm},{},{},{},{},{},{},{},{:e},{:e},{:e},{:e},{},{:.4},{:.4},{:.4}",
                run.seed,
                r.step,
                r.contacts,
                r.islands,
                r.iterations,
                r.iterations_sum,
                r.capped_islands,
                r.final_residual,
                r.natural_residual,
                r.mse_normal,
                r.mse_tangent,
                r.fallbacks,
                1e3 * r.warm_start_seconds,
                1e3 * r.solve_seconds,
                1e3 * r.step_seconds,
            );
        }
    }
    s
}

/// `curves.csv`: per solver, warm start and iteration (1-based), the median ∞-norm residual
/// and the steps still iterating.
pub fn curves_csv(curves: &[Curve]) -> String {
    let mut s = String::new();
    s.push_str(CURVES_COLUMNS);
    s.push('\n');
    for c in curves {
        let (solver, warm) = (csv(&c.solver), csv(&c.warm_start));
        for (i, (r, left)) in c.median_residual.iter().zip(&c.iterators_left).enumerate() {
            let _ = writeln!(s, "{solver},{warm},{},{r:e},{left},{}", i + 1, c.steps);
        }
    }
    s
}

/// `summary.csv`: one row per solver and warm start.
pub fn summary_csv(rows: &[Summary]) -> String {
    let mut s = String::new();
    s.push_str(SUMMARY_COLUMNS);
    s.push('\n');
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{:.3},{:.1},{},{},{:.2},{:.4},{:.4},{:.4},{:e},{:e},{},{},{}",
            csv(&r.solver),
            csv(&r.warm_start),
            r.seeds,
            r.steps,
            r.contact_steps,
            r.mean_iterations,
            r.median_iterations,
            r.max_iterations,
            r.capped_steps,
            r.mean_contacts,
            r.warm_start_ms,
            r.solve_ms,
            r.step_ms,
            r.mse_normal,
            r.mse_tangent,
            r.fallbacks,
            opt(r.speedup_vs_none, 3),
            opt(r.speedup_vs_builtin, 3),
        );
    }
    s
}

/// `summary.md`: the summary as a Markdown table with a few lines on how it was measured.
pub fn summary_md(results: &Results, rows: &[Summary]) -> String {
    let c = &results.config;
    let several = results.solvers.len() > 1;
    let mut s = String::new();
    let _ = writeln!(s, "# Warm-start comparison\n");
    let seeds = match (c.seeds.first(), c.seeds.last()) {
        (Some(a), Some(b)) if c.seeds.len() > 1 => format!("{} seeds ({a} to {b})", c.seeds.len()),
        (Some(a), _) => format!("seed {a}"),
        _ => String::new(),
    };
    let _ = writeln!(
        s,
        "Pile of {} circles, {seeds}, {} steps each; velocity iterations capped at {}, tolerance {:e} ({:?} norm); \
         {} threads, {:.1} s wall time.\n",
        c.bodies,
        c.steps,
        c.world.solver.max_iterations,
        c.world.solver.tolerance,
        c.world.solver.norm,
        results.threads,
        results.wall_seconds,
    );
    let head = [
        "warm_start",
        "mean_iterations",
        "median_iterations",
        "capped_steps",
        "mean_contacts",
        "warm_start_ms",
        "solve_ms",
        "step_ms",
        "mse_normal",
        "mse_tangent",
        "fallbacks",
        "speedup_vs_none",
        "speedup_vs_builtin",
    ];
    let _ = writeln!(
        s,
        "| {}{} |",
        if several { "solver | " } else { "" },
        head.join(" | ")
    );
    let _ = writeln!(
        s,
        "|{}{}|",
        if several { "---|" } else { "" },
        ["---:"; 13].join("|").replacen("---:", "---", 1)
    );
    for r in rows {
        let solver = if several {
            format!("{} | ", r.solver)
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "| {solver}{} | {:.1} | {:.0} | {} | {:.1} | {:.3} | {:.3} | {:.3} | {:.3e} | {:.3e} | {} | {} | {} |",
            r.warm_start,
            r.mean_iterations,
            r.median_iterations,
            r.capped_steps,
            r.mean_contacts,
            r.warm_start_ms,
            r.solve_ms,
            r.step_ms,
            r.mse_normal,
            r.mse_tangent,
            r.fallbacks,
            opt(r.speedup_vs_none, 2),
            opt(r.speedup_vs_builtin, 2),
        );
    }
    let _ = writeln!(
        s,
        "\nIterations are those of a step's slowest island. Steps without contacts ({} of {} per warm start here) \
         are left out of the iteration and MSE columns and counted in mean_contacts and the times. Times are means \
         per step, measured while the worlds ran in parallel; speedups are ratios of total step time against the \
         same solver's `none` / `builtin`. The `copy` providers' warm-start time includes the oracle's own solve.",
        rows.first().map_or(0, |r| r.steps - r.contact_steps),
        rows.first().map_or(0, |r| r.steps),
    );
    s
}

/// What [`write_outputs`] wrote.
#[derive(Debug, Clone, Default)]
pub struct Outputs {
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// The text of `summary.md`.
    pub summary_md: String,
}

/// Writes the tables (and, with `plots`, the figures) of `results` into `dir`.
pub fn write_outputs(results: &Results, dir: &Path, plots: bool) -> Result<Outputs, CliError> {
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| CliError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let rows = summarize(results);
    let curves = curves(results);
    let summary_md = summary_md(results, &rows);
    let json = serde_json::json!({ "config": &results.config, "threads": results.threads,
        "wall_seconds": results.wall_seconds, "summary": &rows });
    let json = serde_json::to_string_pretty(&json)
        .map_err(|e| CliError::Usage(format!("summary.json: {e}")))?;
    let mut files = Vec::new();
    for (name, text) in [
        ("steps.csv", steps_csv(results)),
        ("curves.csv", curves_csv(&curves)),
        ("summary.csv", summary_csv(&rows)),
        ("summary.md", summary_md.clone()),
        ("summary.json", json + "\n"),
    ] {
        let path = dir.join(name);
        write_atomic(&path, text.as_bytes())?;
        files.push(path);
    }
    if plots {
        let fig_dir = dir.join("figures");
        std::fs::create_dir_all(&fig_dir).map_err(io(&fig_dir))?;
        for s in 0..results.solvers.len() {
            let suffix = if results.solvers.len() > 1 {
                format!("_{}", file_safe(&results.solvers[s]))
            } else {
                String::new()
            };
            for (name, figure) in figures(results, &curves, s) {
                files.extend(plots::draw(&figure, &fig_dir, &format!("{name}{suffix}"))?);
            }
        }
    }
    Ok(Outputs { files, summary_md })
}

fn file_safe(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Per step, the mean over seeds of `f`, over the seeds whose step passes `keep`.
fn per_step(
    runs: &[Run],
    steps: u64,
    keep: fn(&StepRecord) -> bool,
    f: fn(&StepRecord) -> f64,
) -> Vec<(f64, f64)> {
    (0..steps as usize)
        .filter_map(|k| {
            let vals: Vec<f64> = runs
                .iter()
                .filter_map(|r| r.steps.get(k))
                .filter(|r| keep(r))
                .map(f)
                .collect();
            (!vals.is_empty()).then(|| (k as f64, vals.iter().sum::<f64>() / vals.len() as f64))
        })
        .collect()
}

/// The thesis's figures for solver `s`: `(file stem, figure)`.
pub fn figures(results: &Results, curves: &[Curve], s: usize) -> Vec<(&'static str, Figure)> {
    let solver = &results.solvers[s];
    let n_seeds = results.config.seeds.len();
    let steps = results.config.steps;
    let nw = results.warm_starts.len();
    let series = |f: &dyn Fn(usize) -> Vec<(f64, f64)>| -> Vec<Series> {
        (0..nw)
            .map(|w| Series {
                label: results.warm_starts[w].clone(),
                color: plots::color(w),
                points: f(w),
            })
            .collect()
    };
    let all = |_: &StepRecord| true;
    let contact = |r: &StepRecord| r.contacts > 0;
    let curve = |w: usize| &curves[s * nw + w];
    let step_label = "step (dt = 0.01 s)".to_string();
    let of = format!(
        "{solver}, pile of {} circles, mean over {n_seeds} seeds",
        results.config.bodies
    );

    let contacts = Panel {
        title: "Contact points per step".into(),
        x_label: step_label.clone(),
        y_label: "contact points".into(),
        series: series(&|w| per_step(results.group(s, w), steps, all, |r| r.contacts as f64)),
        ..Panel::default()
    };
    let iterations = Panel {
        title: "Velocity iterations per step (steps with contacts)".into(),
        x_label: step_label.clone(),
        y_label: "iterations".into(),
        y_scale: Scale::Log,
        series: series(&|w| {
            per_step(results.group(s, w), steps, contact, |r| {
                f64::from(r.iterations)
            })
        }),
        ..Panel::default()
    };
    let left = Panel {
        title: "Steps still iterating after i iterations".into(),
        x_label: "iteration i".into(),
        y_label: "iterators left (steps)".into(),
        series: series(&|w| {
            let c = curve(w);
            std::iter::once((0.0, c.steps as f64))
                .chain(
                    c.iterators_left
                        .iter()
                        .enumerate()
                        .map(|(i, &n)| ((i + 1) as f64, n as f64)),
                )
                .collect()
        }),
        ..Panel::default()
    };
    let residual = Panel {
        title: format!("Median ∞-norm residual, first {RESIDUAL_FIGURE_ITERATIONS} iterations"),
        x_label: "iteration i".into(),
        y_label: "median max |Δλ| (N·s)".into(),
        y_scale: Scale::Log,
        x_range: Some((1.0, RESIDUAL_FIGURE_ITERATIONS as f64)),
        reference: Some((results.config.world.solver.tolerance, "tolerance".into()))
            .filter(|(t, _)| *t > 0.0),
        y_min: None,
        series: series(&|w| {
            let c = curve(w);
            let mut pts: Vec<(f64, f64)> = c
                .median_residual
                .iter()
                .take(RESIDUAL_FIGURE_ITERATIONS)
                .enumerate()
                .map(|(i, &r)| ((i + 1) as f64, r))
                .collect();
            // A finished curve stays at its last value to the end of the window.
            if let Some(&(x, y)) = pts.last() {
                if x < RESIDUAL_FIGURE_ITERATIONS as f64 {
                    pts.push((RESIDUAL_FIGURE_ITERATIONS as f64, y));
                }
            }
            pts
        }),
    };
    let mse = |title: &str, f: fn(&StepRecord) -> f64| Panel {
        title: title.into(),
        x_label: step_label.clone(),
        y_label: "MSE ((N·s)²)".into(),
        y_scale: Scale::Log,
        // Exact starts (copy on the first contact steps) would stretch the axis to 1e-30.
        y_min: Some(1e-16),
        series: series(&|w| per_step(results.group(s, w), steps, contact, f)),
        ..Panel::default()
    };
    vec![
        (
            "contacts",
            Figure::new(format!("Contacts per step — {of}"), vec![contacts]),
        ),
        (
            "iterations",
            Figure::new(format!("Iterations per step — {of}"), vec![iterations]),
        ),
        (
            "iterators_left",
            Figure::new(
                format!("Iterators left — {solver}, all contact steps of {n_seeds} seeds"),
                vec![left],
            ),
        ),
        (
            "residual",
            Figure::new(
                format!("Convergence — {solver}, median over all contact steps"),
                vec![residual],
            ),
        ),
        (
            "mse",
            Figure::new(
                format!("Warm start vs final impulse — {of}"),
                vec![
                    mse("Normal impulses", |r| r.mse_normal),
                    mse("Tangent impulses", |r| r.mse_tangent),
                ],
            ),
        ),
    ]
}

/// Runs `compare`: the experiment, the files, and `summary.md` on stdout.
pub fn run(args: CompareArgs) -> Result<(), CliError> {
    let config = Config::from_args(&args)?;
    let results = run_experiment(&config)?;
    let outputs = write_outputs(&results, &args.out, !args.no_plots)?;
    // A closed stdout (`| head`) is not an error worth a panic: the files are written.
    let _ = writeln!(std::io::stdout().lock(), "{}", outputs.summary_md);
    eprintln!(
        "wrote {} files to {}",
        outputs.files.len(),
        args.out.display()
    );
    Ok(())
}
