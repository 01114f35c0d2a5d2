//! Summary rows and convergence curves of a comparison.

use super::{Results, StepRecord};

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
    /// Mean over contact steps of the natural-map residual at stop (N·s; the largest over
    /// a step's islands): how close to a solution the solver stopped.
    pub natural_residual_mean: f64,
    /// Largest natural-map residual at stop of any contact step (N·s).
    pub natural_residual_max: f64,
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
                natural_residual_mean: mean(sum(|r| r.natural_residual, &contact), contact.len()),
                natural_residual_max: contact
                    .iter()
                    .map(|r| r.natural_residual)
                    .fold(0.0, f64::max),
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
