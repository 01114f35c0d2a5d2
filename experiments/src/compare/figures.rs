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

/// The groups of providers with a figure of their own, `(file stem, members)`: the thesis's
/// (Figures 20–28), then the classical contenders of docs/RESEARCH.md. Each group present gets
/// its own iterations figure, with `none` and `builtin` as references.
pub const FIGURE_GROUPS: [(&str, &[&str]); 8] = [
    ("iterations_none_builtin", &["none", "builtin"]),
    ("iterations_random_bad_copy", &["random", "bad", "copy"]),
    ("iterations_copy2_copy0", &["copy2", "copy0"]),
    ("iterations_grid", &["grid"]),
    ("iterations_cnn", &["pressure", "peak"]),
    (
        "iterations_contenders",
        &[
            "extrapolate",
            "shock",
            "tail",
            "krylov",
            "best",
            "presolve",
            "sor",
        ],
    ),
    ("iterations_graph", &["graph"]),
    ("iterations_learned_sor", &["sor", "learned-sor"]),
];

const STEP_LABEL: &str = "step (dt = 0.01 s)";

/// The results of one solver, as the figures read them.
struct View<'a> {
    results: &'a Results,
    curves: &'a [Curve],
    s: usize,
}

impl View<'_> {
    fn providers(&self) -> usize {
        self.results.warm_starts.len()
    }

    fn curve(&self, w: usize) -> &Curve {
        &self.curves[self.s * self.providers() + w]
    }

    /// The providers whose registry name is `name` (`copy:tolerance=…` counts as `copy`).
    fn named(&self, name: &str) -> Vec<usize> {
        (0..self.providers())
            .filter(|&w| base_name(&self.results.warm_starts[w]) == name)
            .collect()
    }

    /// One series per provider of `ws`, coloured by its position in the comparison.
    fn series(&self, ws: &[usize], f: &dyn Fn(usize) -> Vec<(f64, f64)>) -> Vec<Series> {
        ws.iter()
            .map(|&w| Series {
                label: self.results.warm_starts[w].clone(),
                color: plots::color(w),
                points: f(w),
            })
            .collect()
    }

    /// Per step, the mean over seeds of `f` for provider `w`.
    fn per_step(
        &self,
        w: usize,
        keep: fn(&StepRecord) -> bool,
        f: fn(&StepRecord) -> f64,
    ) -> Vec<(f64, f64)> {
        per_step(
            self.results.group(self.s, w),
            self.results.config.steps,
            keep,
            f,
        )
    }

    fn contacts(&self, ws: &[usize]) -> Panel {
        Panel {
            title: "Contact points per step".into(),
            x_label: STEP_LABEL.into(),
            y_label: "contact points".into(),
            series: self.series(ws, &|w| self.per_step(w, |_| true, |r| r.contacts as f64)),
            ..Panel::default()
        }
    }

    fn iterations(&self, ws: &[usize], scale: Scale) -> Panel {
        Panel {
            title: format!(
                "Velocity iterations per step (steps with contacts), {} scale",
                if scale == Scale::Log { "log" } else { "linear" }
            ),
            x_label: STEP_LABEL.into(),
            y_label: "iterations".into(),
            y_scale: scale,
            series: self.series(ws, &|w| {
                self.per_step(w, has_contacts, |r| f64::from(r.iterations))
            }),
            ..Panel::default()
        }
    }

    fn iterators_left(&self, ws: &[usize]) -> Panel {
        let seeds = self.results.config.seeds.len().max(1) as f64;
        Panel {
            title: "Steps still iterating after i iterations, mean per simulation".into(),
            x_label: "iteration i".into(),
            y_label: "iterators left (steps per simulation)".into(),
            series: self.series(ws, &|w| {
                let c = self.curve(w);
                std::iter::once((0.0, c.steps as f64 / seeds))
                    .chain(
                        c.iterators_left
                            .iter()
                            .enumerate()
                            .map(|(i, &n)| ((i + 1) as f64, n as f64 / seeds)),
                    )
                    .collect()
            }),
            ..Panel::default()
        }
    }

    fn residual(&self, ws: &[usize]) -> Panel {
        let window = RESIDUAL_FIGURE_ITERATIONS as f64;
        Panel {
            title: format!("Median ∞-norm residual, first {RESIDUAL_FIGURE_ITERATIONS} iterations"),
            x_label: "iteration i".into(),
            y_label: "median max |Δλ| (N·s)".into(),
            y_scale: Scale::Log,
            x_range: Some((1.0, window)),
            reference: Some((
                self.results.config.world.solver.tolerance,
                "tolerance".into(),
            ))
            .filter(|(t, _)| *t > 0.0),
            y_min: None,
            series: self.series(ws, &|w| {
                let mut pts: Vec<(f64, f64)> = self
                    .curve(w)
                    .median_residual
                    .iter()
                    .take(RESIDUAL_FIGURE_ITERATIONS)
                    .enumerate()
                    .map(|(i, &r)| ((i + 1) as f64, r))
                    .collect();
                // A finished curve stays at its last value to the end of the window.
                if let Some(&(x, y)) = pts.last() {
                    if x < window {
                        pts.push((window, y));
                    }
                }
                pts
            }),
        }
    }

    fn mse(&self, ws: &[usize], title: &str, f: fn(&StepRecord) -> f64) -> Panel {
        Panel {
            title: title.into(),
            x_label: STEP_LABEL.into(),
            y_label: "MSE ((N·s)²)".into(),
            y_scale: Scale::Log,
            // Exact starts (copy on the first contact steps) would stretch the axis to 1e-30.
            y_min: Some(1e-16),
            series: self.series(ws, &|w| self.per_step(w, has_contacts, f)),
            ..Panel::default()
        }
    }
}

fn has_contacts(r: &StepRecord) -> bool {
    r.contacts > 0
}

/// The registry name of a warm-start label (`copy:tolerance=…` → `copy`).
fn base_name(label: &str) -> &str {
    label.split(':').next().unwrap_or(label)
}

/// The thesis's figures for solver `s`: `(file stem, figure)`.
pub fn figures(results: &Results, curves: &[Curve], s: usize) -> Vec<(&'static str, Figure)> {
    let v = View { results, curves, s };
    let solver = &results.solvers[s];
    let n_seeds = results.config.seeds.len();
    let of = format!(
        "{solver}, pile of {} circles, mean over {n_seeds} seeds",
        results.config.bodies
    );
    let all: Vec<usize> = (0..v.providers()).collect();
    let mut out = vec![
        (
            "contacts",
            Figure::new(format!("Contacts per step — {of}"), vec![v.contacts(&all)]),
        ),
        (
            "iterations",
            Figure::new(
                format!("Iterations per step — {of}"),
                vec![
                    v.iterations(&all, Scale::Log),
                    v.iterations(&all, Scale::Linear),
                ],
            ),
        ),
        (
            "iterators_left",
            Figure::new(
                format!("Iterators left — {solver}, all contact steps of {n_seeds} seeds"),
                vec![v.iterators_left(&all)],
            ),
        ),
        (
            "residual",
            Figure::new(
                format!("Convergence — {solver}, median over all contact steps"),
                vec![v.residual(&all)],
            ),
        ),
        (
            "mse",
            Figure::new(
                format!("Warm start vs final impulse — {of}"),
                vec![
                    v.mse(&all, "Normal impulses", |r| r.mse_normal),
                    v.mse(&all, "Tangent impulses", |r| r.mse_tangent),
                ],
            ),
        ),
    ];
    for (stem, members) in FIGURE_GROUPS {
        let own: Vec<usize> = members.iter().flat_map(|m| v.named(m)).collect();
        if own.is_empty() {
            continue;
        }
        let mut ws: Vec<usize> = ["none", "builtin"]
            .iter()
            .flat_map(|m| v.named(m))
            .collect();
        ws.extend(own.iter().filter(|w| !ws.contains(w)).collect::<Vec<_>>());
        out.push((
            stem,
            Figure::new(
                format!("Iterations per step, {} — {of}", members.join(", ")),
                vec![
                    v.iterations(&ws, Scale::Log),
                    v.iterations(&ws, Scale::Linear),
                ],
            ),
        ));
    }
    out
}
