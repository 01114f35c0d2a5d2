//! How many substeps and relax passes one solve runs, from the solver's parameters and the
//! world's stop rule.
//!
//! A **pass** is one sweep over an island's contact rows: a solve pass (with the soft bias)
//! or a relax pass (without). The warm start and restitution are not passes (as in Box2D).
//! Each substep runs one solve pass and `relax` relax passes.
//!
//! * **Fixed budget** (`tolerance = 0`, `max_iterations = K`): at most `K` passes. With
//!   `K ≥ 1 + relax`: `max(1, K / (1 + relax))` substeps (integer division) of `1 + relax`
//!   passes each; with `K < 1 + relax`: one substep of one solve pass and `K − 1` relax
//!   passes. The `substeps` parameter is not used.
//! * **Tolerance mode** (`tolerance > 0`): the `substeps` parameter, each of `1 + relax`
//!   passes, but never more than `max_iterations` passes in all (fewer substeps, as in the
//!   fixed budget, when the cap is lower). The soft step has no stop rule of its own: the
//!   tolerance only decides whether the report says it converged.

use deepcontact_core::SolverSettings;

/// The substeps of one solve and their passes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Schedule {
    /// Substeps (≥ 1).
    pub substeps: u32,
    /// Relax passes per substep.
    pub relax: u32,
}

impl Schedule {
    /// The schedule for `substeps` and `relax` asked for under `settings` (see the module docs).
    pub fn new(substeps: u32, relax: u32, settings: &SolverSettings) -> Self {
        let cap = settings.max_iterations.max(1);
        let per_substep = relax.saturating_add(1);
        let fit = |wanted: u32| {
            if cap < per_substep {
                Self {
                    substeps: 1,
                    relax: cap - 1,
                }
            } else {
                Self {
                    substeps: wanted.min(cap / per_substep).max(1),
                    relax,
                }
            }
        };
        if settings.tolerance == 0.0 {
            fit(u32::MAX)
        } else {
            fit(substeps.max(1))
        }
    }

    /// Passes this schedule spends: `substeps × (1 + relax)`.
    pub fn passes(&self) -> u32 {
        self.substeps * (1 + self.relax)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn budget(k: u32) -> SolverSettings {
        SolverSettings {
            tolerance: 0.0,
            max_iterations: k,
            ..SolverSettings::default()
        }
    }

    #[test]
    fn a_fixed_budget_of_k_passes_is_never_exceeded() {
        for relax in 0..4 {
            for k in 1..40 {
                let s = Schedule::new(4, relax, &budget(k));
                assert!(s.passes() <= k, "K = {k}, relax = {relax}: {s:?}");
                assert!(s.substeps >= 1);
                if k > relax {
                    assert_eq!(s.substeps, k / (1 + relax));
                    assert_eq!(s.relax, relax);
                }
            }
        }
        assert_eq!(
            Schedule::new(4, 1, &budget(8)),
            Schedule {
                substeps: 4,
                relax: 1
            }
        );
        assert_eq!(
            Schedule::new(4, 3, &budget(2)),
            Schedule {
                substeps: 1,
                relax: 1
            }
        );
    }

    #[test]
    fn the_tolerance_mode_runs_the_substeps_asked_for_under_the_cap() {
        let s = SolverSettings::default();
        assert_eq!(
            Schedule::new(4, 1, &s),
            Schedule {
                substeps: 4,
                relax: 1
            }
        );
        let capped = SolverSettings {
            max_iterations: 5,
            ..s
        };
        assert_eq!(Schedule::new(4, 1, &capped).substeps, 2);
    }
}
