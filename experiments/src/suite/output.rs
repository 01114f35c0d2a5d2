//! The suite's files: `summary.csv|md|json` with a scene and a budget column, `steps.csv`,
//! and per scene a figure of residual and penetration against the budget.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{Budget, EqualAccuracy, SuiteResults, SuiteRow, equal_accuracy, suite_rows};
use crate::atomic::{file_safe, json_bytes, write_files};
use crate::plots::{self, Figure, Panel, Scale, Series};
use crate::{ExperimentError, csv_bytes};

/// Column names of the suite's `steps.csv`.
pub const SUITE_STEPS_COLUMNS: &str = "scene,budget,solver,warm_start,seed,step,contacts,islands,iterations,iterations_sum,\
provider_passes,natural_residual,penetration_mean,penetration_max,normal_velocity_error_mean,\
normal_velocity_error_max,kinetic_energy,warm_start_ms,solve_ms,step_ms";

#[derive(Serialize)]
struct StepRow<'a> {
    scene: &'a str,
    budget: Budget,
    solver: &'a str,
    warm_start: &'a str,
    seed: u64,
    step: u64,
    contacts: usize,
    islands: usize,
    iterations: u32,
    iterations_sum: u64,
    provider_passes: u64,
    natural_residual: f64,
    penetration_mean: f64,
    penetration_max: f64,
    normal_velocity_error_mean: f64,
    normal_velocity_error_max: f64,
    kinetic_energy: f64,
    warm_start_ms: f64,
    solve_ms: f64,
    step_ms: f64,
}

/// `steps.csv`: one row per scene, budget, solver, warm start, seed and step (columns
/// [`SUITE_STEPS_COLUMNS`]).
pub fn suite_steps_csv(results: &SuiteResults) -> Result<Vec<u8>, ExperimentError> {
    let ms = |s: f64| (1e7 * s).round() / 1e4;
    csv_bytes(results.cells.iter().flat_map(|cell| {
        let r = &cell.results;
        r.runs.iter().flat_map(move |run| {
            run.steps.iter().map(move |s| StepRow {
                scene: &cell.scene,
                budget: cell.budget,
                solver: &r.solvers[run.solver],
                warm_start: &r.warm_starts[run.warm_start],
                seed: run.seed,
                step: s.step,
                contacts: s.contacts,
                islands: s.islands,
                iterations: s.iterations,
                iterations_sum: s.iterations_sum,
                provider_passes: s.provider_passes,
                natural_residual: s.natural_residual,
                penetration_mean: s.penetration_mean,
                penetration_max: s.penetration_max,
                normal_velocity_error_mean: s.normal_velocity_error_mean,
                normal_velocity_error_max: s.normal_velocity_error_max,
                kinetic_energy: s.kinetic_energy,
                warm_start_ms: ms(s.warm_start_seconds),
                solve_ms: ms(s.solve_seconds),
                step_ms: ms(s.step_seconds),
            })
        })
    }))
}

/// `summary.md`: one table per scene, rows by budget, solver and warm start, then the table
/// at equal accuracy ([`equal_accuracy`]) when builtin ran at two caps or more.
pub fn suite_md(results: &SuiteResults, rows: &[SuiteRow]) -> String {
    md_with(results, rows, &accuracy_of(results, rows))
}

/// The equal-accuracy rows of a suite's summary rows.
fn accuracy_of(results: &SuiteResults, rows: &[SuiteRow]) -> Vec<EqualAccuracy> {
    equal_accuracy(rows, results.config.base.world.solver.max_iterations)
}

fn md_with(results: &SuiteResults, rows: &[SuiteRow], accuracy: &[EqualAccuracy]) -> String {
    let c = &results.config;
    let b = &c.base;
    let mut s = String::new();
    let _ = writeln!(s, "# Scene suite\n");
    let seeds = match (b.seeds.first(), b.seeds.last()) {
        (Some(x), Some(y)) if b.seeds.len() > 1 => format!("{} seeds ({x} to {y})", b.seeds.len()),
        (Some(x), _) => format!("seed {x}"),
        _ => String::new(),
    };
    let _ = writeln!(
        s,
        "{} scene{} × {} budget{}, {seeds}, {} steps each, {:.1} s wall time. Under a budget K every \
         island gets K passes per step: the provider's own (`provider_passes`) and the solver's \
         (`solver_passes`), and the position pass runs {} iterations in full. `tolerance`: the \
         solver iterates until max |Δλ| < {:e} or {} iterations, the position pass until its own \
         stop rule (cap {}); `tolerance@N`: the same with a cap of N iterations.\n",
        c.scenes.len(),
        if c.scenes.len() == 1 { "" } else { "s" },
        c.budgets.len(),
        if c.budgets.len() == 1 { "" } else { "s" },
        b.steps,
        results.wall_seconds,
        c.position_passes,
        b.world.solver.tolerance,
        b.world.solver.max_iterations,
        b.world.position.max_iterations,
    );
    let head = "| budget | solver | warm_start | provider_passes | solver_passes | residual_mean | \
                residual_p99 | residual_max | penetration_mean (m) | penetration_max (m) | \
                vn_error_mean (m/s) | final_KE (J) | step_ms | vs builtin |";
    let mut scene = None;
    for r in rows {
        if scene != Some(&r.scene) {
            scene = Some(&r.scene);
            let _ = writeln!(s, "\n## `{}`\n\n{head}", r.scene);
            let _ = writeln!(s, "|---|---|---|{}", "---:|".repeat(11));
        }
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.1} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {:.3e} | {:.3} | {} |",
            r.budget,
            r.solver,
            r.warm_start,
            r.provider_passes,
            r.solver_passes,
            r.natural_residual_mean,
            r.natural_residual_p99,
            r.natural_residual_max,
            r.penetration_mean,
            r.penetration_max,
            r.normal_velocity_error_mean,
            r.final_kinetic_energy,
            r.step_ms,
            r.step_vs_builtin
                .map_or_else(String::new, |x| format!("{x:.2}")),
        );
    }
    let _ = writeln!(
        s,
        "\nresidual: the natural-map residual of the final impulses (N·s, largest over a step's islands), \
         mean, 99th percentile and maximum over contact steps. penetration: over contact points at the \
         start of each step. vn_error: the normal velocity error after the solve. final_KE: kinetic \
         energy after the last step, mean over seeds. vs builtin: total step time (the provider's \
         included) over the first solver's `builtin` in the same scene and budget."
    );
    accuracy_md(&mut s, accuracy);
    s
}

/// The equal-accuracy table ([`equal_accuracy`]), when builtin ran at two caps or more.
fn accuracy_md(s: &mut String, found: &[EqualAccuracy]) {
    if found.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## At equal accuracy\n\nFor each tolerance-mode row, the cap at which the first solver's \
         `builtin` stops at the same natural residual (mean or p99): ln residual linear in the cap \
         between the first two of builtin's caps that bracket it, the step time linear between \
         them (each cap is another trajectory: the crossing is rough). step ×: the row's step over \
         builtin's there.\n\n| scene | solver | warm_start | cap | measure | residual | builtin's \
         cap there | builtin's step_ms there | step × |\n|---|---|---|---:|---|---:|---:|---:|---:|"
    );
    for e in found {
        let (cap, step, ratio) = match (e.builtin_cap, e.builtin_step_ms, e.step_vs_builtin) {
            (Some(c), Some(m), r) => (
                format!("{c:.0}"),
                format!("{m:.3}"),
                r.map_or_else(String::new, |x| format!("{x:.2}")),
            ),
            _ => (
                format!("not within {}–{}", e.builtin_caps.0, e.builtin_caps.1),
                String::new(),
                String::new(),
            ),
        };
        let _ = writeln!(
            s,
            "| `{}` | {} | {} | {} | {} | {:.2e} | {cap} | {step} | {ratio} |",
            e.scene,
            e.solver,
            e.warm_start,
            e.cap,
            e.measure.name(),
            e.residual,
        );
    }
}

/// Per scene, residual p99 and deepest penetration against the pass budget, one line per
/// solver and warm start (the tolerance mode has no pass count and is left out).
pub fn suite_figures(rows: &[SuiteRow]) -> Vec<(String, Figure)> {
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    scenes
        .into_iter()
        .map(|scene| {
            let of_scene: Vec<&SuiteRow> = rows.iter().filter(|r| r.scene == scene).collect();
            let mut lines: Vec<(String, String)> = Vec::new();
            for r in &of_scene {
                let key = (r.solver.clone(), r.warm_start.clone());
                if !lines.contains(&key) {
                    lines.push(key);
                }
            }
            let series = |f: fn(&SuiteRow) -> f64| -> Vec<Series> {
                lines
                    .iter()
                    .enumerate()
                    .map(|(i, (solver, warm_start))| Series {
                        label: format!("{solver} + {warm_start}"),
                        color: plots::color(i),
                        points: of_scene
                            .iter()
                            .filter(|r| &r.solver == solver && &r.warm_start == warm_start)
                            .filter_map(|r| match r.budget {
                                Budget::Passes(k) => Some((f64::from(k), f(r))),
                                Budget::Tolerance | Budget::Capped(_) => None,
                            })
                            .collect(),
                    })
                    .collect()
            };
            let panel = |title: &str, y_label: &str, f: fn(&SuiteRow) -> f64| Panel {
                title: title.into(),
                x_label: "passes per step (provider + solver)".into(),
                y_label: y_label.into(),
                y_scale: Scale::Log,
                series: series(f),
                ..Panel::default()
            };
            let figure = Figure::new(
                format!("{scene}: where the solver stopped, against the budget"),
                vec![
                    panel("natural residual, 99th percentile", "N·s", |r| {
                        r.natural_residual_p99
                    }),
                    panel("deepest penetration", "m", |r| r.penetration_max),
                ],
            );
            (format!("budget_{}", file_safe(scene)), figure)
        })
        .collect()
}

/// Writes the suite's tables (and, with `plots`, its figures) into `dir`; returns the
/// files written and the Markdown summary.
pub fn write_suite(
    results: &SuiteResults,
    dir: &Path,
    plots: bool,
) -> Result<(Vec<PathBuf>, String), ExperimentError> {
    let rows = suite_rows(results);
    let accuracy = accuracy_of(results, &rows);
    let md = md_with(results, &rows, &accuracy);
    let json = serde_json::json!({ "config": &results.config, "wall_seconds": results.wall_seconds,
        "summary": &rows, "equal_accuracy": &accuracy });
    let mut files = write_files(
        dir,
        [
            ("steps.csv", suite_steps_csv(results)?),
            ("summary.csv", csv_bytes(&rows)?),
            ("summary.md", md.clone().into_bytes()),
            ("summary.json", json_bytes(&json, "summary.json")?),
        ],
    )?;
    if plots {
        let fig_dir = dir.join("figures");
        std::fs::create_dir_all(&fig_dir).map_err(|e| ExperimentError::io(&fig_dir, e))?;
        for (name, figure) in suite_figures(&rows) {
            files.extend(plots::draw(&figure, &fig_dir, &name)?);
        }
    }
    Ok((files, md))
}
