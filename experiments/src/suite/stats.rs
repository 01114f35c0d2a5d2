//! The suite's summary rows: per scene, budget, solver and warm start, where the solver
//! stopped (natural residual, penetration, normal velocity error, energy), how the budget
//! was spent, and what the step cost.

use super::{Budget, Cell, SuiteResults};
use crate::compare::{Results, StepRecord};

/// One row of the suite's summary.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SuiteRow {
    /// Scene label (its spec).
    pub scene: String,
    /// Budget: passes per island and step, `tolerance`, or `tolerance@N`.
    pub budget: Budget,
    /// Solver label.
    pub solver: String,
    /// Warm-start label.
    pub warm_start: String,
    /// Worlds (seeds).
    pub seeds: usize,
    /// Steps with at least one contact, over all seeds (the ones the residual, penetration
    /// and velocity-error columns use).
    pub contact_steps: usize,
    /// Mean passes the provider spent per island (over the islands of contact steps).
    pub provider_passes: f64,
    /// Mean solver iterations per island (over the same islands); under a budget K,
    /// `provider_passes + solver_passes` = K unless the provider overspent.
    pub solver_passes: f64,
    /// Mean over contact steps of the natural-map residual at stop (N·s, largest over a
    /// step's islands).
    pub natural_residual_mean: f64,
    /// 99th percentile of the same over contact steps (nearest rank).
    pub natural_residual_p99: f64,
    /// Largest of the same.
    pub natural_residual_max: f64,
    /// Largest of the same over the steps where the first solver's `builtin` world of the
    /// same seed converged at the same step (tolerance mode only; `None` otherwise or
    /// without `builtin`).
    pub natural_residual_max_builtin_converged: Option<f64>,
    /// Mean over contact steps of the mean penetration depth (m).
    pub penetration_mean: f64,
    /// Deepest penetration of any step (m).
    pub penetration_max: f64,
    /// Mean over contact steps of the mean normal velocity error after the solve (m/s).
    pub normal_velocity_error_mean: f64,
    /// Largest normal velocity error of any step (m/s).
    pub normal_velocity_error_max: f64,
    /// Mean over seeds of the kinetic energy after the last step (J): what is left moving
    /// of a scene that should be at rest.
    pub final_kinetic_energy: f64,
    /// Contact steps in which an island hit the iteration cap (tolerance mode, any cap).
    pub capped_steps: usize,
    /// Islands whose warm start was rejected, summed.
    pub fallbacks: usize,
    /// Mean milliseconds per step, the provider's time included (all steps).
    pub step_ms: f64,
    /// This row's total step time over the first solver's `builtin` in the same cell
    /// (below 1: faster); `None` without `builtin`.
    pub step_vs_builtin: Option<f64>,
}

fn mean(sum: f64, n: usize) -> f64 {
    if n == 0 { 0.0 } else { sum / n as f64 }
}

/// Nearest-rank percentile `q` (in [0, 1]) of `v`; 0 when empty. Reorders `v`.
fn percentile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    *v.select_nth_unstable_by(rank, f64::total_cmp).1
}

/// The runs of `warm_start` under the first solver, in seed order, if listed.
fn builtin_runs(results: &Results) -> Option<&[crate::compare::Run]> {
    let w = results.warm_starts.iter().position(|l| l == "builtin")?;
    Some(results.group(0, w))
}

fn cell_rows(cell: &Cell) -> Vec<SuiteRow> {
    let results = &cell.results;
    let builtin = builtin_runs(results);
    let mut rows = Vec::new();
    for s in 0..results.solvers.len() {
        for w in 0..results.warm_starts.len() {
            let runs = results.group(s, w);
            let steps: Vec<&StepRecord> = runs.iter().flat_map(|r| &r.steps).collect();
            let contact: Vec<&StepRecord> =
                steps.iter().copied().filter(|r| r.contacts > 0).collect();
            let sum = |f: &dyn Fn(&StepRecord) -> f64, of: &[&StepRecord]| {
                of.iter().map(|r| f(r)).sum::<f64>()
            };
            let max =
                |f: &dyn Fn(&StepRecord) -> f64| contact.iter().map(|r| f(r)).fold(0.0, f64::max);
            let islands: f64 = sum(&|r| r.islands as f64, &contact);
            let per_island = |x: f64| if islands > 0.0 { x / islands } else { 0.0 };
            let mut residuals: Vec<f64> = contact.iter().map(|r| r.natural_residual).collect();
            let converged_max = match (cell.budget, builtin) {
                (Budget::Tolerance | Budget::Capped(_), Some(reference)) => Some(
                    runs.iter()
                        .zip(reference)
                        .flat_map(|(run, base)| run.steps.iter().zip(&base.steps))
                        .filter(|(r, b)| r.contacts > 0 && b.contacts > 0 && b.capped_islands == 0)
                        .map(|(r, _)| r.natural_residual)
                        .fold(0.0, f64::max),
                ),
                _ => None,
            };
            rows.push(SuiteRow {
                scene: cell.scene.clone(),
                budget: cell.budget,
                solver: results.solvers[s].clone(),
                warm_start: results.warm_starts[w].clone(),
                seeds: runs.len(),
                contact_steps: contact.len(),
                provider_passes: per_island(sum(&|r| r.provider_passes as f64, &contact)),
                solver_passes: per_island(sum(&|r| r.iterations_sum as f64, &contact)),
                natural_residual_mean: mean(residuals.iter().sum(), residuals.len()),
                natural_residual_p99: percentile(&mut residuals, 0.99),
                natural_residual_max: max(&|r| r.natural_residual),
                natural_residual_max_builtin_converged: converged_max,
                penetration_mean: mean(sum(&|r| r.penetration_mean, &contact), contact.len()),
                penetration_max: max(&|r| r.penetration_max),
                normal_velocity_error_mean: mean(
                    sum(&|r| r.normal_velocity_error_mean, &contact),
                    contact.len(),
                ),
                normal_velocity_error_max: max(&|r| r.normal_velocity_error_max),
                final_kinetic_energy: mean(
                    runs.iter()
                        .filter_map(|r| r.steps.last())
                        .map(|r| r.kinetic_energy)
                        .sum(),
                    runs.len(),
                ),
                capped_steps: contact.iter().filter(|r| r.capped_islands > 0).count(),
                fallbacks: steps.iter().map(|r| r.fallbacks).sum(),
                step_ms: 1e3 * mean(sum(&|r| r.step_seconds, &steps), steps.len()),
                step_vs_builtin: None,
            });
        }
    }
    // Step time against the first solver's builtin of the same cell.
    let reference = rows
        .iter()
        .find(|r| r.solver == results.solvers[0] && r.warm_start == "builtin")
        .map(|r| r.step_ms);
    if let Some(base) = reference.filter(|&b| b > 0.0) {
        for row in &mut rows {
            row.step_vs_builtin = Some(row.step_ms / base);
        }
    }
    rows
}

/// The summary rows of every cell, in (scene, budget, solver, warm start) order.
pub fn suite_rows(results: &SuiteResults) -> Vec<SuiteRow> {
    results.cells.iter().flat_map(cell_rows).collect()
}
