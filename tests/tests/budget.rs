//! Fixed pass budgets (`WorldSettings::budget`): the provider's own passes come out of the
//! solver's, island by island.

use deepcontact_core::{
    Impulse, Observation, WarmStart, WarmStartContext, WarmStartError, World, WorldSettings, scene,
};
use deepcontact_experiments::full_registry;
use deepcontact_pgs::PgsPositionSolver;

/// Wraps a provider and records, per island, the budget it was offered, the passes it
/// spent and the solver iterations that followed.
struct Ledger {
    inner: Box<dyn WarmStart>,
    offered: Vec<Option<u32>>,
    spent: Vec<u32>,
    solved: Vec<u32>,
}

impl WarmStart for Ledger {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let r = self.inner.warm_start(ctx, out);
        self.offered.push(ctx.pass_budget);
        self.spent.push(self.inner.passes_spent());
        r
    }
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.solved.push(seen.report.iterations);
        self.inner.observe(ctx, seen);
    }
    fn passes_spent(&self) -> u32 {
        self.inner.passes_spent()
    }
}

/// Steps a 100-circle pile `steps` times under `budget` passes with `provider`.
fn ledger(provider: &str, budget: Option<u32>, steps: usize) -> Ledger {
    let settings = WorldSettings {
        budget,
        ..WorldSettings::default()
    };
    let mut world = scene::pile(7, 100).unwrap().build(settings).unwrap();
    let mut ledger = Ledger {
        inner: full_registry().build_provider(provider).unwrap(),
        offered: Vec::new(),
        spent: Vec::new(),
        solved: Vec::new(),
    };
    let mut solver = full_registry().build_solver("pgs").unwrap();
    let mut position = PgsPositionSolver::new();
    for _ in 0..steps {
        world
            .step(&mut ledger, solver.as_mut(), &mut position)
            .unwrap();
    }
    ledger
}

#[test]
fn under_a_budget_of_8_sor_leaves_the_solver_8_minus_its_sweeps() {
    let l = ledger("sor", Some(8), 90);
    assert!(l.spent.len() > 100, "{} islands solved", l.spent.len());
    assert!(
        l.offered.iter().all(|&o| o == Some(7)),
        "the provider is offered K - 1"
    );
    for (i, (&spent, &solved)) in l.spent.iter().zip(&l.solved).enumerate() {
        assert!((1..=7).contains(&spent), "island {i}: sor spent {spent}");
        assert_eq!(spent + solved, 8, "island {i}: {spent} + {solved}");
    }
    // The sweeps were cut by the budget (sor's own cap is 300 with a tolerance).
    assert!(l.spent.iter().filter(|&&s| s == 7).count() > l.spent.len() / 2);
}

#[test]
fn providers_that_do_not_sweep_leave_the_solver_the_whole_budget() {
    for provider in ["none", "builtin"] {
        let l = ledger(provider, Some(8), 60);
        assert!(!l.solved.is_empty(), "{provider}: no island solved");
        assert!(l.spent.iter().all(|&s| s == 0), "{provider}");
        assert!(
            l.solved.iter().all(|&s| s == 8),
            "{provider}: {:?}",
            l.solved
        );
    }
}

#[test]
fn without_a_budget_sor_sweeps_by_its_own_rule_and_the_solver_by_the_tolerance() {
    let l = ledger("sor", None, 60);
    assert!(l.offered.iter().all(Option::is_none));
    assert!(l.spent.iter().any(|&s| s > 8), "sor's sweeps were capped");
    assert!(l.solved.iter().any(|&s| s != 8));
}

#[test]
fn a_budget_below_two_passes_is_refused() {
    for budget in [0, 1, 200_000] {
        let settings = WorldSettings {
            budget: Some(budget),
            ..WorldSettings::default()
        };
        let err = World::new(settings).unwrap_err();
        assert!(err.to_string().contains("budget"), "{err}");
    }
}

/// `grid:inner=sor` reported no passes (the grid filter did not forward `passes_spent`), so
/// under a budget the solver ran all K passes after the inner provider's sweeps.
#[test]
fn regression_grid_hid_its_inner_providers_passes() {
    let l = ledger("grid:inner=sor", Some(8), 90);
    assert!(l.spent.len() > 100, "{} islands solved", l.spent.len());
    assert!(
        l.spent.iter().any(|&s| s > 0),
        "the inner sweeps were counted"
    );
    for (i, (&spent, &solved)) in l.spent.iter().zip(&l.solved).enumerate() {
        assert_eq!(spent + solved, 8, "island {i}: {spent} + {solved}");
    }
}
