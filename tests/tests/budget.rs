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
    ledger_of(
        full_registry().build_provider(provider).unwrap(),
        budget,
        steps,
    )
}

/// [`ledger`] for a built provider.
fn ledger_of(provider: Box<dyn WarmStart>, budget: Option<u32>, steps: usize) -> Ledger {
    let settings = WorldSettings {
        budget,
        ..WorldSettings::default()
    };
    let mut world = scene::pile(7, 100).unwrap().build(settings).unwrap();
    let mut ledger = Ledger {
        inner: provider,
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

/// Every island of `l` spent at most the `budget − 1` passes offered, and the solver ran the
/// rest.
fn assert_within(l: &Ledger, name: &str, budget: u32) {
    for (i, (&spent, &solved)) in l.spent.iter().zip(&l.solved).enumerate() {
        assert!(spent < budget, "island {i}: {name} spent {spent}");
        assert_eq!(spent + solved, budget, "island {i}: {spent} + {solved}");
    }
}

#[test]
fn under_a_budget_of_8_sor_leaves_the_solver_8_minus_its_sweeps() {
    let l = ledger("sor", Some(8), 90);
    assert!(l.spent.len() > 100, "{} islands solved", l.spent.len());
    assert!(
        l.offered.iter().all(|&o| o == Some(7)),
        "the provider is offered K - 1"
    );
    assert!(l.spent.iter().all(|&s| s >= 1), "sor swept every island");
    assert_within(&l, "sor", 8);
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
    assert_within(&l, "grid:inner=sor", 8);
}

/// `krylov` ran its ten conjugate-gradient steps (21 passes) whatever the budget, so under a
/// budget of 8 it spent about three times the passes it was offered.
#[test]
fn regression_krylov_spent_more_passes_than_it_was_offered() {
    let l = ledger("krylov", Some(8), 90);
    assert!(l.spent.len() > 100, "{} islands solved", l.spent.len());
    // Seven passes fit a round of three steps: its residual and 2 × 3 applications of W.
    assert!(l.spent.contains(&7), "a correction ran");
    assert_within(&l, "krylov", 8);
}

/// `presolve` counted each Newton iteration as one pass, though an iteration (a
/// factorisation of the island's Newton matrix) and the solve's set-up weigh tens of passes,
/// so under a budget of 8 it ran up to seven Newton iterations (1 to 3 an island on this pile)
/// and reported each as a pass.
#[test]
fn regression_presolve_counted_a_newton_iteration_as_one_pass() {
    let l = ledger("presolve", Some(8), 90);
    assert!(l.spent.len() > 100, "{} islands solved", l.spent.len());
    // Not even one iteration fits in 7 passes: the solver gets the whole budget.
    assert!(l.spent.iter().all(|&s| s == 0), "{:?}", &l.spent[..8]);
    assert_within(&l, "presolve", 8);
    // With room for a few iterations it runs them, each weighing more than a pass.
    let l = ledger("presolve", Some(1000), 90);
    let ran: Vec<u32> = l.spent.iter().copied().filter(|&s| s > 0).collect();
    assert!(ran.len() > 50, "{} islands with a Newton solve", ran.len());
    assert!(ran.iter().all(|&s| s > 8), "{:?}", &ran[..8]);
    assert_within(&l, "presolve", 1000);
    // A PSOR sweep on the assembled `W`, and its assembly, weigh more than a pass too.
    let l = ledger("presolve:solver=psor", Some(8), 90);
    assert!(l.spent.iter().all(|&s| s == 0), "{:?}", &l.spent[..8]);
    let l = ledger("presolve:solver=psor", Some(200), 90);
    assert!(l.spent.iter().any(|&s| s > 0), "no PSOR solve ran");
    assert_within(&l, "presolve:solver=psor", 200);
}

/// Oracles (which solve the island to build their start) are left out: they are references,
/// not providers a budget judges. So are the providers that read a model file named on the
/// command line (`onnx`, `graph-file`): no such file is in the repository.
#[test]
fn every_provider_spends_at_most_the_passes_it_is_offered() {
    let registry = full_registry();
    let names: Vec<String> = registry
        .providers()
        .map(|(n, _)| n.to_string())
        .filter(|n| !registry.provider_info(n).is_some_and(|i| i.oracle))
        .collect();
    assert!(names.len() >= 15, "{} providers", names.len());
    let (mut over, mut ran) = (Vec::new(), 0);
    for name in &names {
        // The smallest budget (one pass for the provider), a small one and the suite's.
        for budget in [2, 4, 8] {
            let provider = match registry.build_provider(name) {
                Ok(provider) => provider,
                Err(e) if e.to_string().contains("path=") => continue,
                Err(e) => panic!("{name}: {e}"),
            };
            ran += 1;
            let l = ledger_of(provider, Some(budget), 60);
            assert!(!l.spent.is_empty(), "{name}: no island solved");
            assert!(l.offered.iter().all(|&o| o == Some(budget - 1)), "{name}");
            if let Some(&most) = l.spent.iter().max().filter(|&&m| m > budget - 1) {
                over.push(format!("{name} spent {most} of {}", budget - 1));
            }
        }
    }
    assert!(
        ran + 6 >= 3 * names.len(),
        "{ran} of {} runs",
        3 * names.len()
    );
    assert!(over.is_empty(), "over the budget offered: {over:?}");
}

/// `best` asked and scored all four of its candidates whatever the budget (`tail`'s two sweeps
/// and four scoring passes: 6), so under the suite's smallest budget, 4, it spent twice the 3
/// passes it was offered.
#[test]
fn regression_best_spent_six_passes_under_a_budget_of_four() {
    let l = ledger("best", Some(4), 90);
    assert!(l.spent.len() > 100, "{} islands solved", l.spent.len());
    // builtin and extrapolate scored (a pass each), tail offered the last pass: none left
    // for its sweeps, one to score it.
    assert!(l.spent.contains(&3), "three candidates scored");
    assert_within(&l, "best", 4);
}

/// `tail` ran its two sweeps after every solve whatever the budget, so under a budget of 2
/// (one pass for the provider) it spent two.
#[test]
fn regression_tail_swept_twice_with_one_pass_offered() {
    let l = ledger("tail", Some(2), 90);
    assert!(l.spent.len() > 100, "{} islands solved", l.spent.len());
    assert!(l.spent.iter().all(|&s| s == 1), "{:?}", &l.spent[..8]);
    assert!(l.solved.iter().all(|&s| s == 1));
    // With room for both sweeps it runs both.
    let l = ledger("tail", Some(8), 90);
    assert!(!l.spent.is_empty() && l.spent.iter().all(|&s| s == 2));
}

/// A provider offered no passes (as `best` offers the candidates after its budget ran out)
/// spends none.
#[test]
fn every_provider_offered_no_passes_spends_none() {
    let registry = full_registry();
    let mut world = scene::pile(7, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let mut solver = registry.build_solver("pgs").unwrap();
    let mut position = PgsPositionSolver::new();
    for _ in 0..80 {
        world
            .step(
                &mut deepcontact_core::CarriedWarmStart,
                solver.as_mut(),
                &mut position,
            )
            .unwrap();
    }
    let problems = world.last_problems().to_vec();
    let k = (0..problems.len())
        .max_by_key(|&k| problems[k].len())
        .unwrap();
    let island = &problems[k];
    assert!(island.len() > 20, "{} points", island.len());
    let carried: Vec<Option<Impulse>> = vec![Some(Impulse::new(0.1, 0.0)); island.len()];
    let mut over = Vec::new();
    for (name, _) in registry.providers() {
        if registry.provider_info(name).is_some_and(|i| i.oracle) {
            continue;
        }
        let Ok(mut provider) = registry.build_provider(name) else {
            continue;
        };
        let ctx = WarmStartContext::new(island, &carried, 80, world.settings().dt)
            .with_world(&world, k, problems.len())
            .with_pass_budget(0);
        let mut out = vec![Impulse::ZERO; island.len()];
        provider.warm_start(&ctx, &mut out).unwrap();
        if provider.passes_spent() > 0 {
            over.push(format!("{name} spent {}", provider.passes_spent()));
        }
    }
    assert!(over.is_empty(), "offered none: {over:?}");
}
