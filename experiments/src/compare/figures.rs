//! The thesis's figures of a comparison, as plot specs.

use super::{Curve, RESIDUAL_FIGURE_ITERATIONS, Results, Run, StepRecord};
use crate::plots::{self, Figure, Panel, Scale, Series};

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

/// The thesis's groups of providers (Figures 20–28): each group gets its own iterations
/// figure, `iterations_<group>.{png,svg}`, with `none` and `builtin` as references.
pub const THESIS_GROUPS: [(&str, &[&str]); 5] = [
    ("none_builtin", &["none", "builtin"]),
    ("random_bad_copy", &["random", "bad", "copy"]),
    ("copy2_copy0", &["copy2", "copy0"]),
    ("grid", &["grid"]),
    ("cnn", &["pressure", "peak"]),
];

/// The registry name of a warm-start label (`copy:tolerance=…` → `copy`).
fn base_name(label: &str) -> &str {
    label.split(':').next().unwrap_or(label)
}

/// The thesis's figures for solver `s`: `(file stem, figure)`.
pub fn figures(results: &Results, curves: &[Curve], s: usize) -> Vec<(&'static str, Figure)> {
    let solver = &results.solvers[s];
    let n_seeds = results.config.seeds.len();
    let steps = results.config.steps;
    let nw = results.warm_starts.len();
    let all_providers: Vec<usize> = (0..nw).collect();
    let series_of = |ws: &[usize], f: &dyn Fn(usize) -> Vec<(f64, f64)>| -> Vec<Series> {
        ws.iter()
            .map(|&w| Series {
                label: results.warm_starts[w].clone(),
                color: plots::color(w),
                points: f(w),
            })
            .collect()
    };
    let series = |f: &dyn Fn(usize) -> Vec<(f64, f64)>| series_of(&all_providers, f);
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
    let iterations_of = |ws: &[usize], scale: Scale| Panel {
        title: format!(
            "Velocity iterations per step (steps with contacts), {} scale",
            if scale == Scale::Log { "log" } else { "linear" }
        ),
        x_label: step_label.clone(),
        y_label: "iterations".into(),
        y_scale: scale,
        series: series_of(ws, &|w| {
            per_step(results.group(s, w), steps, contact, |r| {
                f64::from(r.iterations)
            })
        }),
        ..Panel::default()
    };
    let left = Panel {
        title: "Steps still iterating after i iterations, mean per simulation".into(),
        x_label: "iteration i".into(),
        y_label: "iterators left (steps per simulation)".into(),
        series: series(&|w| {
            let c = curve(w);
            let per_sim = |n: usize| n as f64 / n_seeds.max(1) as f64;
            std::iter::once((0.0, per_sim(c.steps)))
                .chain(
                    c.iterators_left
                        .iter()
                        .enumerate()
                        .map(|(i, &n)| ((i + 1) as f64, per_sim(n))),
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
    let mut out = vec![
        (
            "contacts",
            Figure::new(format!("Contacts per step — {of}"), vec![contacts]),
        ),
        (
            "iterations",
            Figure::new(
                format!("Iterations per step — {of}"),
                vec![
                    iterations_of(&all_providers, Scale::Log),
                    iterations_of(&all_providers, Scale::Linear),
                ],
            ),
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
    ];
    // One iterations figure per thesis group present, none and builtin as references.
    let find =
        |name: &'static str| (0..nw).filter(move |&w| base_name(&results.warm_starts[w]) == name);
    for (group, members) in THESIS_GROUPS {
        let own: Vec<usize> = members.iter().flat_map(|m| find(m)).collect();
        if own.is_empty() {
            continue;
        }
        let mut ws: Vec<usize> = ["none", "builtin"].iter().flat_map(|m| find(m)).collect();
        ws.extend(own.iter().filter(|w| !ws.contains(w)).collect::<Vec<_>>());
        let stem = match group {
            "none_builtin" => "iterations_none_builtin",
            "random_bad_copy" => "iterations_random_bad_copy",
            "copy2_copy0" => "iterations_copy2_copy0",
            "grid" => "iterations_grid",
            _ => "iterations_cnn",
        };
        out.push((
            stem,
            Figure::new(
                format!("Iterations per step, {} — {of}", members.join(", ")),
                vec![
                    iterations_of(&ws, Scale::Log),
                    iterations_of(&ws, Scale::Linear),
                ],
            ),
        ));
    }
    out
}
