//! At equal accuracy instead of an equal cap: for each row of the tolerance mode, the cap at
//! which the first solver's `builtin` stops at the same natural residual (mean or 99th
//! percentile), and builtin's step time there.
//!
//! Builtin's residual is read off its rows at the suite's caps (`tolerance` and
//! `tolerance@N`): ln residual linear in the cap between the first two caps, in cap order, that
//! bracket the target (each cap is another trajectory, so the curve need not fall smoothly and
//! the crossing is rough), and the step time linear in the cap between the same two. A start
//! that stops lower than builtin at the same cap buys, at equal accuracy, the step builtin needs
//! to get there.

use super::SuiteRow;

/// Which statistic of the natural residual is matched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Measure {
    /// The mean over contact steps.
    Mean,
    /// The 99th percentile over contact steps.
    P99,
}

impl Measure {
    /// The row's value of this statistic (N·s).
    pub fn of(self, row: &SuiteRow) -> f64 {
        match self {
            Measure::Mean => row.natural_residual_mean,
            Measure::P99 => row.natural_residual_p99,
        }
    }

    /// The name the tables use.
    pub fn name(self) -> &'static str {
        match self {
            Measure::Mean => "mean",
            Measure::P99 => "p99",
        }
    }
}

/// One tolerance-mode row's residual, and what builtin needs to stop there.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EqualAccuracy {
    /// Scene label.
    pub scene: String,
    /// Solver label.
    pub solver: String,
    /// Warm-start label.
    pub warm_start: String,
    /// The row's iteration cap.
    pub cap: u32,
    /// The statistic matched.
    pub measure: Measure,
    /// The row's value of it (N·s).
    pub residual: f64,
    /// Builtin's caps run in the scene, lowest and highest.
    pub builtin_caps: (u32, u32),
    /// The cap at which builtin's residual reaches [`Self::residual`], interpolated; `None`
    /// when no two of builtin's caps bracket it.
    pub builtin_cap: Option<f64>,
    /// Builtin's step there (ms), interpolated.
    pub builtin_step_ms: Option<f64>,
    /// The row's step time over builtin's there (below 1: cheaper at equal accuracy).
    pub step_vs_builtin: Option<f64>,
}

/// Builtin's rows in `scene` with their caps, in cap order: the rows of the scene's first
/// solver, one per cap.
fn builtin_curve<'a>(
    rows: &'a [SuiteRow],
    scene: &str,
    world_cap: u32,
) -> Vec<(u32, &'a SuiteRow)> {
    let Some(first) = rows.iter().find(|r| r.scene == scene) else {
        return Vec::new();
    };
    let mut curve: Vec<(u32, &SuiteRow)> = rows
        .iter()
        .filter(|r| r.scene == scene && r.solver == first.solver && r.warm_start == "builtin")
        .filter_map(|r| r.budget.cap(world_cap).map(|c| (c, r)))
        .collect();
    curve.sort_by_key(|&(c, _)| c);
    curve.dedup_by_key(|&mut (c, _)| c);
    curve
}

/// The first crossing of `target` by builtin's curve: (cap, step ms).
fn crossing(curve: &[(u32, &SuiteRow)], measure: Measure, target: f64) -> Option<(f64, f64)> {
    if !(target > 0.0 && target.is_finite()) {
        return None;
    }
    let t = target.ln();
    curve.windows(2).find_map(|w| {
        let ((ca, a), (cb, b)) = (w[0], w[1]);
        let (ra, rb) = (measure.of(a), measure.of(b));
        if !(ra > 0.0 && rb > 0.0) {
            return None;
        }
        let (ya, yb) = (ra.ln(), rb.ln());
        if (ya - t) * (yb - t) > 0.0 {
            return None;
        }
        let f = if ya == yb { 0.0 } else { (ya - t) / (ya - yb) };
        let cap = f64::from(ca) + f * f64::from(cb - ca);
        Some((cap, a.step_ms + f * (b.step_ms - a.step_ms)))
    })
}

/// For every tolerance-mode row but builtin's own, in each scene where builtin ran at two caps
/// or more: the cap and step at which builtin stops at the row's residual mean and p99.
/// `world_cap` is the cap of plain `tolerance` ([`deepcontact_core::SolverSettings`]).
pub fn equal_accuracy(rows: &[SuiteRow], world_cap: u32) -> Vec<EqualAccuracy> {
    let mut out = Vec::new();
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    for scene in scenes {
        let curve = builtin_curve(rows, scene, world_cap);
        if curve.len() < 2 {
            continue;
        }
        let ((lowest, reference), (highest, _)) = (curve[0], curve[curve.len() - 1]);
        for row in rows.iter().filter(|r| r.scene == scene) {
            let Some(cap) = row.budget.cap(world_cap) else {
                continue;
            };
            if row.solver == reference.solver && row.warm_start == "builtin" {
                continue;
            }
            for measure in [Measure::Mean, Measure::P99] {
                let residual = measure.of(row);
                let matched = crossing(&curve, measure, residual);
                out.push(EqualAccuracy {
                    scene: scene.to_string(),
                    solver: row.solver.clone(),
                    warm_start: row.warm_start.clone(),
                    cap,
                    measure,
                    residual,
                    builtin_caps: (lowest, highest),
                    builtin_cap: matched.map(|(c, _)| c),
                    builtin_step_ms: matched.map(|(_, s)| s),
                    step_vs_builtin: matched
                        .filter(|&(_, s)| s > 0.0)
                        .map(|(_, s)| row.step_ms / s),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::suite::Budget;

    fn row(budget: Budget, warm_start: &str, mean: f64, p99: f64, step_ms: f64) -> SuiteRow {
        SuiteRow {
            scene: "pile".into(),
            budget,
            solver: "pgs".into(),
            warm_start: warm_start.into(),
            seeds: 1,
            contact_steps: 1,
            provider_passes: 0.0,
            solver_passes: 0.0,
            natural_residual_mean: mean,
            natural_residual_p99: p99,
            natural_residual_max: p99,
            natural_residual_max_builtin_converged: None,
            penetration_mean: 0.0,
            penetration_max: 0.0,
            normal_velocity_error_mean: 0.0,
            normal_velocity_error_max: 0.0,
            final_kinetic_energy: 0.0,
            capped_steps: 0,
            fallbacks: 0,
            step_ms,
            step_vs_builtin: None,
        }
    }

    /// Builtin and `sor` at the world's cap of 1 000, then `more` rows.
    fn rows(more: &[SuiteRow]) -> Vec<SuiteRow> {
        let mut rows = vec![
            row(Budget::Tolerance, "builtin", 4e-3, 1e-2, 6.0),
            row(Budget::Tolerance, "sor", 1e-3, 1e-4, 7.0),
        ];
        rows.extend_from_slice(more);
        rows
    }

    #[test]
    fn builtin_is_matched_where_its_residual_crosses_the_rows_between_two_caps() {
        let rows = rows(&[
            row(Budget::Capped(2000), "builtin", 2e-3, 5e-3, 8.0),
            row(Budget::Capped(4000), "builtin", 5e-4, 2e-3, 12.0),
        ]);
        let found = equal_accuracy(&rows, 1000);
        let cap = |w: &str, c: u32, m: Measure| {
            found
                .iter()
                .find(|e| e.warm_start == w && e.cap == c && e.measure == m)
                .unwrap()
        };
        // ln(1e-3) lies halfway between ln(2e-3) and ln(5e-4): cap 3000, step 10 ms.
        let mean = cap("sor", 1000, Measure::Mean);
        assert!(
            (mean.builtin_cap.unwrap() - 3000.0).abs() < 1e-9,
            "{mean:?}"
        );
        assert!((mean.builtin_step_ms.unwrap() - 10.0).abs() < 1e-9);
        assert!((mean.step_vs_builtin.unwrap() - 0.7).abs() < 1e-12);
        assert_eq!(mean.builtin_caps, (1000, 4000));
        // Below every cap builtin ran: not matched.
        let p99 = cap("sor", 1000, Measure::P99);
        assert_eq!((p99.builtin_cap, p99.step_vs_builtin), (None, None));
        // Builtin's own rows are the curve, not rows to match.
        assert!(found.iter().all(|e| e.warm_start != "builtin"));
        assert_eq!(found.len(), 2);
    }

    #[test]
    fn one_cap_of_builtin_gives_no_match() {
        let rows = rows(&[row(Budget::Passes(8), "builtin", 4e-2, 1e-1, 1.0)]);
        assert!(equal_accuracy(&rows, 1000).is_empty());
    }
}
