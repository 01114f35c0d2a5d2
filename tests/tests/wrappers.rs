//! Providers that wrap another (`sor:start=NAME`, `grid:inner=NAME`, the rounding wrapper)
//! hand it everything the world tells a provider (each solve, a new world) and report what it
//! did (its passes, its diagnostics).

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use deepcontact_core::math::Real;
use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, Observation, PointDesc, ProblemBody, SolveReport,
    StepReport, Vector, WarmStart, WarmStartContext, WarmStartError, WorldSettings, scene,
};
use deepcontact_experiments::full_registry;
use deepcontact_grid::{GridFilterConfig, GridFiltered};
use deepcontact_pgs::PgsPositionSolver;
use deepcontact_warmstart::{RelaxedConfig, RelaxedWarmStart, Rounded};

/// Passes the probe says it spent on each call.
const PROBE_PASSES: u32 = 3;

/// The carried impulses, counting the solves it is shown and the resets, with one diagnostic.
#[derive(Debug, Clone, Default)]
struct Probe {
    observed: Arc<AtomicUsize>,
    resets: Arc<AtomicUsize>,
}

impl WarmStart for Probe {
    fn name(&self) -> &str {
        "probe"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        CarriedWarmStart.warm_start(ctx, out)
    }
    fn observe(&mut self, _ctx: &WarmStartContext<'_>, _seen: &Observation<'_>) {
        self.observed.fetch_add(1, Ordering::Relaxed);
    }
    fn reset(&mut self) {
        self.resets.fetch_add(1, Ordering::Relaxed);
    }
    fn diagnostics(&self) -> Vec<(String, Real)> {
        vec![(
            "probe_observed".into(),
            self.observed.load(Ordering::Relaxed) as Real,
        )]
    }
    fn passes_spent(&self) -> u32 {
        PROBE_PASSES
    }
}

/// A box resting on the ground, falling at one step of gravity: one two-point manifold.
fn resting_box() -> ContactProblem {
    let mut p = ContactProblem::new();
    let ground = p.add_body(ProblemBody::fixed(Vector::zeros()));
    let b = p.add_body(ProblemBody::dynamic(
        Vector::new(0.0, 0.5),
        0.0,
        Vector::new(0.0, -0.0981),
        0.0,
        1.0,
        1.0 / 6.0,
    ));
    p.begin_manifold();
    for x in [-0.5, 0.5] {
        p.add_point(&PointDesc::new(ground, b, Vector::new(x, 0.0), Vector::y()))
            .unwrap();
    }
    p
}

/// Runs `wrapper` (holding a clone of `probe`) through one call of each method and checks that
/// the probe saw the solve and the reset, and that the wrapper reports the probe's passes (at
/// least: a wrapper that sweeps adds its own) and its diagnostic.
fn forwards_to_the_probe(wrapper: &mut dyn WarmStart, probe: &Probe) {
    let problem = resting_box();
    let carried = vec![Some(Impulse::new(2.0, 0.0)); problem.len()];
    let ctx = WarmStartContext::new(&problem, &carried, 1, 0.01);
    let mut out = vec![Impulse::ZERO; problem.len()];
    wrapper.warm_start(&ctx, &mut out).unwrap();
    let name = wrapper.name().to_owned();
    assert!(
        wrapper.passes_spent() >= PROBE_PASSES,
        "{name}: {} passes",
        wrapper.passes_spent()
    );
    let report = SolveReport::default();
    wrapper.observe(&ctx, &Observation::new(&out, &out, false, &report));
    assert_eq!(probe.observed.load(Ordering::Relaxed), 1, "{name}: observe");
    assert!(
        wrapper
            .diagnostics()
            .iter()
            .any(|(k, v)| k.ends_with("probe_observed") && *v == 1.0),
        "{name}: {:?}",
        wrapper.diagnostics()
    );
    wrapper.reset();
    assert_eq!(probe.resets.load(Ordering::Relaxed), 1, "{name}: reset");
}

/// The step reports of the 100-circle pile (seed 7) stepped 80 times with `provider`.
fn pile_reports(provider: &mut dyn WarmStart) -> Vec<StepReport> {
    let mut world = scene::pile(7, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let mut solver = full_registry().build_solver("pgs").unwrap();
    let mut position = PgsPositionSolver::new();
    (0..80)
        .map(|_| {
            world
                .step(provider, solver.as_mut(), &mut position)
                .unwrap()
        })
        .collect()
}

/// A start inside `sor`, and the probe that counts what it is told.
fn sor_over_a_probe() -> (RelaxedWarmStart, Probe) {
    let probe = Probe::default();
    let sor = RelaxedWarmStart::new(RelaxedConfig::default())
        .unwrap()
        .with_start(Box::new(probe.clone()));
    (sor, probe)
}

/// `sor:start=NAME` never passed the solves on to its start, so a start that keeps history
/// (`extrapolate`) had none and `sor:start=extrapolate` stepped with the bits of `sor`.
#[test]
fn regression_sor_start_never_saw_the_solves() {
    let (mut sor, probe) = sor_over_a_probe();
    forwards_to_the_probe(&mut sor, &probe);

    // In a world: the extrapolated start now moves the trajectory away from plain `sor`'s.
    let run = |spec: &str| {
        let mut provider = full_registry().build_provider(spec).unwrap();
        pile_reports(&mut provider)
            .iter()
            .map(|r| (r.contacts, r.velocity_iterations))
            .collect::<Vec<_>>()
    };
    let (plain, extrapolated) = (run("sor"), run("sor:start=extrapolate"));
    assert!(
        plain.iter().filter(|(contacts, _)| *contacts > 0).count() > 20,
        "the pile lands"
    );
    assert_ne!(plain, extrapolated);
}

#[test]
fn the_grid_filter_forwards_to_its_inner_provider() {
    let probe = Probe::default();
    let mut grid = GridFiltered::new(Box::new(probe.clone()), GridFilterConfig::default()).unwrap();
    forwards_to_the_probe(&mut grid, &probe);
    assert_eq!(grid.passes_spent(), PROBE_PASSES);
}

#[test]
fn the_rounding_wrapper_forwards_to_its_inner_provider() {
    let probe = Probe::default();
    let mut rounded = Rounded::new(probe.clone(), 2).unwrap();
    forwards_to_the_probe(&mut rounded, &probe);
    assert_eq!(rounded.passes_spent(), PROBE_PASSES);
}

/// The world itself tells a wrapped start about every island it solves.
#[test]
fn a_world_shows_every_solve_to_the_start_inside_sor() {
    let (mut sor, probe) = sor_over_a_probe();
    let islands: usize = pile_reports(&mut sor).iter().map(|r| r.islands).sum();
    assert!(islands > 20, "{islands} islands solved");
    assert_eq!(probe.observed.load(Ordering::Relaxed), islands);
    // The world resets its provider before the first step.
    assert_eq!(probe.resets.load(Ordering::Relaxed), 1);
}
