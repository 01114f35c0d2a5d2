//! The transfers and the `grid` provider on real piles.

use std::sync::OnceLock;

use deepcontact_core::Velocity;

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, SolveReport, SolverSettings, Vector, VelocitySolver,
    WarmStart, WarmStartContext, WarmStartError, World, WorldSettings, ZeroWarmStart, scene,
};
use deepcontact_grid::{
    CH_MASS, GridEncoder, GridFilterConfig, GridFiltered, GridLayout, GridSpec, Kernel, RoundTrip,
    register,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Steps to settle, as in the thesis's Table 1 (a pile by then).
const STEPS: usize = 200;

/// A pile of 100 circles after `STEPS` steps with the builtin warm start (built once).
fn pile() -> &'static World {
    static PILE: OnceLock<World> = OnceLock::new();
    PILE.get_or_init(|| {
        let mut world = scene::pile(3, 100)
            .unwrap()
            .build(WorldSettings::default())
            .unwrap();
        let (mut v, mut p) = (PgsSolver::new(), PgsPositionSolver::new());
        for _ in 0..STEPS {
            world.step(&mut CarriedWarmStart, &mut v, &mut p).unwrap();
        }
        world
    })
}

fn round_trip(res: f64, h: f64) -> deepcontact_grid::RoundTripSums {
    let mut rt = RoundTrip::new(
        Vector::zeros(),
        Vector::new(15.0, 15.0),
        res,
        h,
        Kernel::Poly6,
    )
    .unwrap();
    rt.world(pile()).unwrap()
}

#[test]
fn support_below_spacing_loses_body_mass() {
    let s = round_trip(0.25, 0.125);
    assert_eq!(s.bodies, 100);
    assert!(s.lost_bodies > 0);
    // A body mass is π/4 ≈ 0.785; losing some bodies gives a clearly visible mean.
    assert!(s.body_mean() > 0.02, "{}", s.body_mean());
}

#[test]
fn spacing_equal_to_support_keeps_body_mass() {
    for (res, h) in [(0.25, 0.25), (0.125, 0.25), (0.25, 0.5), (0.125, 0.5)] {
        let s = round_trip(res, h);
        assert_eq!(s.lost_bodies, 0);
        assert!(s.body_mean() < 1e-4, "res={res} h={h}: {}", s.body_mean());
    }
    let s = round_trip(0.25, 0.25);
    assert!(s.contacts > 100, "{} contacts", s.contacts);
    // Contacts are closer than h to each other, so their impulses mix a little, but
    // nothing is lost in total.
    assert_eq!(s.lost_contacts, 0);
}

#[test]
fn encoder_marks_walls_and_conserves_mass() {
    let world = pile();
    let layout = GridLayout::thesis();
    let mut enc = GridEncoder::new(layout.clone()).unwrap();
    let mut input = vec![0.0; layout.input_len()];
    let stats = enc.encode_world(world, &mut input).unwrap();
    assert_eq!(
        (stats.bodies, stats.lost_bodies, stats.wall_nodes),
        (100, 0, 240)
    );
    assert_eq!(stats.contacts, world.raw_contacts().len());
    let n = layout.nodes();
    let spec = GridSpec::thesis();
    let interior: f64 = (0..n)
        .filter(|&i| {
            let (ix, iy) = spec.coords(i);
            ix > 0 && iy > 0 && ix < 60 && iy < 60
        })
        .map(|i| input[CH_MASS * n + i])
        .sum();
    let border = input[CH_MASS * n..(CH_MASS + 1) * n].iter().sum::<f64>() - interior;
    assert!((border - 240.0 * 100.0).abs() < 1e-9, "{border}");
    // Bodies on the floor have their centres at y ≈ 0.5 = h: the border nodes get at most
    // a vanishing weight (then overwritten by the wall mass), so the body mass is inside.
    let mass: f64 = world.bodies().iter().map(|b| b.mass).sum();
    assert!(
        (interior - mass).abs() < 1e-6 * mass,
        "{interior} vs {mass}"
    );
    assert!(input.iter().all(|v| v.is_finite()));
    // Labels: normal impulses are non-negative and their total is conserved.
    let mut labels = vec![0.0; layout.output_len()];
    enc.encode_world_labels(world, &mut labels).unwrap();
    let total: f64 = world.contacts().iter().map(|(_, i)| i.normal).sum();
    assert!((labels[..n].iter().sum::<f64>() - total).abs() < 1e-9 * total.max(1.0));
    assert!(labels[..n].iter().all(|&v| v >= 0.0));
}

/// The test's own oracle (so the test does not depend on the baselines' `copy`):
/// solve the problem from zeros to 1e-9.
struct Oracle(PgsSolver);

impl WarmStart for Oracle {
    fn name(&self) -> &str {
        "oracle"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let settings = SolverSettings {
            max_iterations: 20_000,
            tolerance: 1e-9,
            ..SolverSettings::default()
        };
        let mut v = vec![Velocity::default(); ctx.problem.bodies.len()];
        out.fill(Impulse::ZERO);
        self.0
            .solve(
                ctx.problem,
                &settings,
                out,
                &mut v,
                &mut SolveReport::default(),
            )
            .map_err(|e| WarmStartError::Provider(e.to_string()))
    }
}

/// Warm start every island of the pile's last step with `provider`, check the output,
/// and return the world solver's total iterations from there.
fn iterations(provider: &mut dyn WarmStart) -> u64 {
    let world = pile();
    let problems: &[ContactProblem] = world.last_problems();
    assert!(!problems.is_empty());
    let mut solver = PgsSolver::new();
    let mut total = 0;
    for (k, problem) in problems.iter().enumerate() {
        let n = problem.points.len();
        let carried = vec![None; n];
        let ctx = WarmStartContext::new(problem, &carried, STEPS as u64, 0.01).with_world(
            world,
            k,
            problems.len(),
        );
        let mut out = vec![Impulse::ZERO; n];
        provider.warm_start(&ctx, &mut out).unwrap();
        deepcontact_core::warm_start::check_output(&out, n).unwrap();
        let mut v = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        solver
            .solve(
                problem,
                &SolverSettings::default(),
                &mut out,
                &mut v,
                &mut report,
            )
            .unwrap();
        total += report.iterations as u64;
    }
    total
}

#[test]
fn grid_oracle_lands_between_copy_and_zero() {
    let copy = iterations(&mut Oracle(PgsSolver::new()));
    let config = GridFilterConfig::default();
    let grid =
        iterations(&mut GridFiltered::new(Box::new(Oracle(PgsSolver::new())), config).unwrap());
    let none = iterations(&mut ZeroWarmStart);
    assert!(
        copy <= grid && grid < none,
        "copy {copy}, grid {grid}, none {none}"
    );
    // A coarser grid loses more.
    let coarse = GridFilterConfig {
        spacing: 0.5,
        h: 1.0,
        ..config
    };
    let coarse =
        iterations(&mut GridFiltered::new(Box::new(Oracle(PgsSolver::new())), coarse).unwrap());
    assert!(coarse < none, "coarse {coarse}, none {none}");
}

#[test]
fn grid_provider_output_is_admissible_and_uses_the_box_grid() {
    let world = pile();
    let mut p = GridFiltered::new(
        Box::new(Oracle(PgsSolver::new())),
        GridFilterConfig::default(),
    )
    .unwrap();
    for (k, problem) in world.last_problems().iter().enumerate() {
        let n = problem.points.len();
        let carried = vec![None; n];
        let ctx = WarmStartContext::new(problem, &carried, 0, 0.01).with_world(world, k, 1);
        let mut out = vec![Impulse::ZERO; n];
        p.warm_start(&ctx, &mut out).unwrap();
        assert!(out.iter().all(|i| i.is_finite() && i.normal >= 0.0));
        assert_eq!(p.last_grid(), &GridSpec::thesis());
        // Without the world: a grid around the problem's own bodies and points.
        let ctx = WarmStartContext::new(problem, &carried, 0, 0.01);
        p.warm_start(&ctx, &mut out).unwrap();
        assert!(out.iter().all(|i| i.is_finite() && i.normal >= 0.0));
        assert!(p.last_grid().len() <= GridSpec::thesis().len());
    }
}

#[test]
fn registry_grid_runs_a_world() {
    let mut registry = deepcontact_core::Registry::empty();
    deepcontact_pgs::register(&mut registry);
    deepcontact_warmstart::register(&mut registry);
    register(&mut registry);
    // `inner=builtin` keeps this independent of the oracle; the default inner is `copy`.
    let mut provider = Watched {
        inner: registry
            .build_provider("grid:inner=builtin,transfer=bilinear")
            .unwrap(),
        calls: 0,
        points: 0,
        loaded: 0,
    };
    let mut world = scene::pile(1, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let (mut v, mut pos) = (PgsSolver::new(), PgsPositionSolver::new());
    // The first contact comes at step 32; 45 steps give the provider 13 steps of a pile.
    for _ in 0..45 {
        let report = world.step(&mut provider, &mut v, &mut pos).unwrap();
        assert_eq!(report.fallbacks, 0);
    }
    let Watched {
        calls,
        points,
        loaded,
        ..
    } = provider;
    assert!(calls >= 13, "the provider started {calls} islands");
    // After the first contact step the carried impulses, through the grid, load most points.
    assert!(
        loaded * 2 > points,
        "{loaded} of {points} points started with a normal impulse > 0"
    );
    assert!(
        registry
            .build_provider("grid:inner=builtin,kernel=gaussian,sigma=0.2")
            .is_ok()
    );
    assert!(
        registry
            .build_provider("grid:inner=builtin,sigma=0.2")
            .is_err()
    );
    assert!(
        registry
            .build_provider("grid:inner=builtin,transfer=nearest")
            .is_err()
    );
    assert!(registry.build_provider("grid:inner=builtin,res=0").is_err());
}

/// A provider watched from outside: the islands it started, their points, and the points it
/// started with a positive normal impulse.
struct Watched {
    inner: Box<dyn WarmStart>,
    calls: usize,
    points: usize,
    loaded: usize,
}

impl WarmStart for Watched {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.inner.warm_start(ctx, out)?;
        self.calls += 1;
        self.points += out.len();
        self.loaded += out.iter().filter(|i| i.normal > 0.0).count();
        Ok(())
    }

    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &deepcontact_core::Observation<'_>) {
        self.inner.observe(ctx, seen);
    }

    fn reset(&mut self) {
        self.inner.reset();
    }
}
