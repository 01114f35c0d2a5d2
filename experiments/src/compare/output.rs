//! The comparison's files: CSV tables (the `csv` crate over serde rows), Markdown, JSON and
//! figures, each written atomically.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{Curve, Results, Summary, curves, figures, summarize};
use crate::atomic::{file_safe, json_bytes, write_files};
use crate::{ExperimentError, plots};

/// Column names of `steps.csv`.
pub const STEPS_COLUMNS: &str = "solver,warm_start,seed,step,contacts,islands,iterations,iterations_sum,capped_islands,\
residual_inf,natural_residual,mse_normal,mse_tangent,fallbacks,warm_start_ms,solve_ms,step_ms";
/// Column names of `curves.csv`.
pub const CURVES_COLUMNS: &str =
    "solver,warm_start,iteration,median_residual_inf,iterators_left,steps";
/// Column names of `summary.csv`.
pub const SUMMARY_COLUMNS: &str = "solver,warm_start,seeds,steps,contact_steps,mean_iterations,median_iterations,\
max_iterations,capped_steps,mean_contacts,warm_start_ms,solve_ms,step_ms,mse_normal,mse_tangent,\
natural_residual_mean,natural_residual_max,fallbacks,speedup_vs_none,speedup_vs_builtin";

/// `x` rounded to `digits` decimals (times in the tables carry no more precision than that).
fn round(x: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (x * k).round() / k
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(String::new, |x| format!("{x:.digits$}"))
}

#[derive(Serialize)]
struct StepRow<'a> {
    solver: &'a str,
    warm_start: &'a str,
    seed: u64,
    step: u64,
    contacts: usize,
    islands: usize,
    iterations: u32,
    iterations_sum: u64,
    capped_islands: usize,
    residual_inf: f64,
    natural_residual: f64,
    mse_normal: f64,
    mse_tangent: f64,
    fallbacks: usize,
    warm_start_ms: f64,
    solve_ms: f64,
    step_ms: f64,
}

/// `steps.csv`: one row per solver, warm start, seed and step (columns [`STEPS_COLUMNS`]).
pub fn steps_csv(results: &Results) -> Result<Vec<u8>, ExperimentError> {
    crate::csv_bytes(results.runs.iter().flat_map(|run| {
        run.steps.iter().map(move |r| StepRow {
            solver: &results.solvers[run.solver],
            warm_start: &results.warm_starts[run.warm_start],
            seed: run.seed,
            step: r.step,
            contacts: r.contacts,
            islands: r.islands,
            iterations: r.iterations,
            iterations_sum: r.iterations_sum,
            capped_islands: r.capped_islands,
            residual_inf: r.final_residual,
            natural_residual: r.natural_residual,
            mse_normal: r.mse_normal,
            mse_tangent: r.mse_tangent,
            fallbacks: r.fallbacks,
            warm_start_ms: round(1e3 * r.warm_start_seconds, 4),
            solve_ms: round(1e3 * r.solve_seconds, 4),
            step_ms: round(1e3 * r.step_seconds, 4),
        })
    }))
}

#[derive(Serialize)]
struct CurveRow<'a> {
    solver: &'a str,
    warm_start: &'a str,
    iteration: usize,
    median_residual_inf: f64,
    iterators_left: usize,
    steps: usize,
}

/// `curves.csv`: per solver, warm start and iteration (1-based), the median ∞-norm residual
/// and the steps still iterating (columns [`CURVES_COLUMNS`]).
pub fn curves_csv(curves: &[Curve]) -> Result<Vec<u8>, ExperimentError> {
    crate::csv_bytes(curves.iter().flat_map(|c| {
        c.median_residual
            .iter()
            .zip(&c.iterators_left)
            .enumerate()
            .map(move |(i, (&r, &left))| CurveRow {
                solver: &c.solver,
                warm_start: &c.warm_start,
                iteration: i + 1,
                median_residual_inf: r,
                iterators_left: left,
                steps: c.steps,
            })
    }))
}

/// `summary.csv`: one row per solver and warm start (columns [`SUMMARY_COLUMNS`]; an empty
/// speedup where the reference provider was not run).
pub fn summary_csv(rows: &[Summary]) -> Result<Vec<u8>, ExperimentError> {
    crate::csv_bytes(rows)
}

/// `summary.md`: the summary as a Markdown table with a few lines on how it was measured.
pub fn summary_md(results: &Results, rows: &[Summary]) -> String {
    let several = results.solvers.len() > 1;
    let mut s = String::new();
    let _ = writeln!(s, "# Warm-start comparison\n");
    md_setup(&mut s, results);
    md_table_head(&mut s, several);
    for r in rows {
        md_table_row(&mut s, r, several);
    }
    md_notes(&mut s, rows);
    s
}

/// `summary.md`'s paragraph on the run: the world, the seeds, the stop rule, the threads and
/// the wall time, and the same-problems note where the rows share one driver's problems.
fn md_setup(s: &mut String, results: &Results) {
    let c = &results.config;
    let seeds = match (c.seeds.first(), c.seeds.last()) {
        (Some(a), Some(b)) if c.seeds.len() > 1 => format!("{} seeds ({a} to {b})", c.seeds.len()),
        (Some(a), _) => format!("seed {a}"),
        _ => String::new(),
    };
    // The world: the thesis pile, another named scene, or a registered scene spec.
    let world = match (&c.scene_spec, c.scene.as_str()) {
        (Some(spec), _) => format!("Scene `{spec}`"),
        (None, "pile") => format!("Pile of {} circles", c.bodies),
        (None, name) => format!("Scene `{name}` ({} bodies)", c.bodies),
    };
    let _ = writeln!(
        s,
        "{world}, {seeds}, {} steps each; velocity iterations capped at {}, tolerance {:e} ({:?} norm); \
         {} threads, {:.1} s wall time.\n",
        c.steps,
        c.world.solver.max_iterations,
        c.world.solver.tolerance,
        c.world.solver.norm,
        results.threads,
        results.wall_seconds,
    );
    if let Some(driver) = &c.same_problems {
        let _ = writeln!(
            s,
            "Same problems: every step, each provider starts and solves on a copy of `{driver}`'s world \
             (its contacts, carried impulses and positions), so the rows compare starts on identical problems.\n"
        );
    }
}

/// `summary.md`'s table header and alignment row (a `solver` column when several ran).
fn md_table_head(s: &mut String, several: bool) {
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
        "natural_residual_mean",
        "natural_residual_max",
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
        ["---:"; 15].join("|").replacen("---:", "---", 1)
    );
}

/// One row of `summary.md`'s table.
fn md_table_row(s: &mut String, r: &Summary, several: bool) {
    let solver = if several {
        format!("{} | ", r.solver)
    } else {
        String::new()
    };
    let _ = writeln!(
        s,
        "| {solver}{} | {:.1} | {:.0} | {} | {:.1} | {:.3} | {:.3} | {:.3} | {:.3e} | {:.3e} | {:.2e} | {:.2e} | {} | {} | {} |",
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
        r.natural_residual_mean,
        r.natural_residual_max,
        r.fallbacks,
        opt(r.speedup_vs_none, 2),
        opt(r.speedup_vs_builtin, 2),
    );
}

/// `summary.md`'s closing notes: what the columns mean and how the times were taken.
fn md_notes(s: &mut String, rows: &[Summary]) {
    let _ = writeln!(
        s,
        "\nIterations are those of a step's slowest island. Steps without contacts ({} of {} per warm start here) \
         are left out of the iteration and MSE columns and counted in mean_contacts and the times. Times are means \
         per step, measured with every warm start's world of a seed stepped in turn (so a slow spell of the \
         machine touches them all alike) and the seeds in parallel; speedups are ratios of total step time against the \
         same solver's `none` / `builtin`. The `copy` providers' warm-start time includes the oracle's own solve. \
         natural_residual_mean / _max: the natural-map residual of the final impulses (N·s, largest over a step's \
         islands), mean and maximum over contact steps: where the solver stopped, beside how long it took.",
        rows.first().map_or(0, |r| r.steps - r.contact_steps),
        rows.first().map_or(0, |r| r.steps),
    );
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
pub fn write_outputs(
    results: &Results,
    dir: &Path,
    plots: bool,
) -> Result<Outputs, ExperimentError> {
    std::fs::create_dir_all(dir).map_err(|e| ExperimentError::io(dir, e))?;
    let rows = summarize(results);
    let curves = curves(results);
    let summary_md = summary_md(results, &rows);
    // Providers' learned state after each world, where they report one.
    let diagnostics: Vec<serde_json::Value> = results
        .runs
        .iter()
        .filter(|r| !r.diagnostics.is_empty())
        .map(|r| {
            serde_json::json!({ "solver": &results.solvers[r.solver],
                "warm_start": &results.warm_starts[r.warm_start], "seed": r.seed,
                "values": r.diagnostics.iter().cloned().collect::<std::collections::BTreeMap<_, _>>() })
        })
        .collect();
    let json = serde_json::json!({ "config": &results.config, "threads": results.threads,
        "wall_seconds": results.wall_seconds, "summary": &rows, "diagnostics": diagnostics });
    let mut files = write_files(
        dir,
        [
            ("steps.csv", steps_csv(results)?),
            ("curves.csv", curves_csv(&curves)?),
            ("summary.csv", summary_csv(&rows)?),
            ("summary.md", summary_md.clone().into_bytes()),
            ("summary.json", json_bytes(&json, "summary.json")?),
        ],
    )?;
    if plots {
        let fig_dir = dir.join("figures");
        std::fs::create_dir_all(&fig_dir).map_err(|e| ExperimentError::io(&fig_dir, e))?;
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
