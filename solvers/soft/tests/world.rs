//! The soft step in a world: the solver owns its islands' positions.

use deepcontact_core::{
    BodyKind, CarriedWarmStart, SolverSettings, StepReport, World, WorldSettings, scene,
};
use deepcontact_pgs::PgsPositionSolver;
use deepcontact_soft::{SoftSettings, SoftSolver};

/// Steps `world` `steps` times with the soft solver (`substeps`, `relax`) and the builtin
/// warm start; returns every step's report.
fn run(world: &mut World, solver: &mut SoftSolver, steps: usize) -> Vec<StepReport> {
    let mut position = PgsPositionSolver::new();
    (0..steps)
        .map(|_| {
            world
                .step(&mut CarriedWarmStart, solver, &mut position)
                .unwrap()
        })
        .collect()
}

/// The deepest overlap the narrow phase reports for the world as it is now (m, ≥ 0).
fn penetration(world: &World) -> f64 {
    world
        .raw_contacts()
        .iter()
        .map(|c| (-c.separation).max(0.0))
        .fold(0.0, f64::max)
}

fn soft(substeps: u32, relax: u32) -> SoftSolver {
    SoftSolver::with_settings(SoftSettings {
        substeps,
        relax,
        ..SoftSettings::default()
    })
}

/// A 20-row pyramid of unit boxes (210 boxes) stands for 1 000 steps of 0.01 s with
/// `soft:substeps=4,relax=1`: the top box stays near its start and no contact overlaps by
/// 2 cm. Prints the deepest penetration over the steps and the final kinetic energy
/// (`cargo test --release -p deepcontact-soft --test world -- --nocapture pyramid`).
#[test]
fn a_20_row_pyramid_stands_for_1000_steps() {
    let scene = scene::pyramid(20);
    let mut world = scene.build(WorldSettings::default()).unwrap();
    let top = world.bodies().len() - 1;
    let start = world.bodies()[top].position;
    let mut solver = soft(4, 1);
    let mut position = PgsPositionSolver::new();
    let mut deepest: f64 = 0.0;
    let mut worst_drift: f64 = 0.0;
    for _ in 0..1000 {
        let report = world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .unwrap();
        assert_eq!(
            report.position_iterations, 0,
            "no position pass on soft islands"
        );
        deepest = deepest.max(penetration(&world));
        worst_drift = worst_drift.max((world.bodies()[top].position - start).norm());
    }
    let drift = (world.bodies()[top].position - start).norm();
    let energy = world.kinetic_energy();
    println!(
        "pyramid 20, soft:substeps=4,relax=1, 1000 steps: max penetration {deepest:.6} m, \
         final kinetic energy {energy:.3e} J, top box drift {drift:.6} m (worst {worst_drift:.6} m)"
    );
    assert!(deepest < 0.02, "max penetration {deepest} m");
    assert!(worst_drift < 0.05, "top box moved {worst_drift} m");
    assert!(energy < 1e-3, "kinetic energy {energy} J");
}

/// One box resting on the ground: the normal impulses of a step sum to `m g dt` (N·s per
/// step, the world's units, whatever the substep count).
#[test]
fn a_resting_box_carries_m_g_dt_per_step_in_the_world() {
    for substeps in [1, 4, 8] {
        let mut world = scene::stack(1).build(WorldSettings::default()).unwrap();
        let mut solver = soft(substeps, 1);
        run(&mut world, &mut solver, 300);
        let body = world
            .bodies()
            .iter()
            .find(|b| b.kind == BodyKind::Dynamic)
            .unwrap();
        let m_g_dt = body.mass * 9.81 * 0.01;
        let total: f64 = world.contacts().iter().map(|(_, i)| i.normal).sum();
        assert!(
            (total - m_g_dt).abs() < 1e-3 * m_g_dt,
            "{substeps} substeps: {total} N·s, m g dt = {m_g_dt}"
        );
        assert!(
            body.linear_velocity.norm() < 1e-3,
            "{:?}",
            body.linear_velocity
        );
    }
}

/// Positions bit-identical with islands solved on one or two threads (the pile starts as
/// many islands, so two threads do solve side by side, on forks).
#[test]
fn one_and_two_island_threads_give_the_same_bits() {
    let bits = |threads: usize| -> Vec<u64> {
        // Not the defaults, so that a fork that lost the step's dt or gravity shows.
        let settings = WorldSettings {
            island_threads: threads,
            dt: 1.0 / 60.0,
            gravity: deepcontact_core::Vector::new(0.0, -10.0),
            ..WorldSettings::default()
        };
        let mut world = scene::pile(12345, 100).unwrap().build(settings).unwrap();
        run(&mut world, &mut soft(4, 1), 120);
        world
            .bodies()
            .iter()
            .flat_map(|b| b.state())
            .map(f64::to_bits)
            .collect()
    };
    assert_eq!(bits(1), bits(2));
}

/// Under the world's pass budget (`WorldSettings::budget = Some(K)`, the builtin provider
/// spending none) every island's solve spends at most K passes.
#[test]
fn the_world_pass_budget_holds() {
    for k in [2, 3, 4, 8, 9] {
        let settings = WorldSettings {
            budget: Some(k),
            ..WorldSettings::default()
        };
        let mut world = scene::pyramid(5).build(settings).unwrap();
        for r in run(&mut world, &mut soft(4, 1), 50) {
            assert!(
                r.velocity_iterations <= k,
                "K = {k}: {}",
                r.velocity_iterations
            );
        }
    }
}

/// The hard-contact solvers keep the trait's defaults: they do not own positions, and asking
/// one to integrate them is an error, not a silent `dt × v`.
#[test]
fn hard_solvers_do_not_own_positions() {
    use deepcontact_core::{Impulse, Pose, SolveReport, Velocity, VelocitySolver};
    let mut pgs = deepcontact_pgs::PgsSolver::new();
    assert!(!pgs.owns_positions());
    assert!(soft(4, 1).owns_positions());
    let problem = deepcontact_core::ContactProblem::new();
    let result = pgs.solve_with_positions(
        &problem,
        &SolverSettings::default(),
        &mut [] as &mut [Impulse],
        &mut [] as &mut [Velocity],
        &mut [] as &mut [Pose],
        &mut SolveReport::default(),
    );
    assert!(result.is_err());
}

/// Under a fixed budget of K passes (tolerance 0, cap K) no island spends more than K.
#[test]
fn a_fixed_budget_of_k_passes_holds_in_the_world() {
    for k in [1, 2, 3, 5, 8] {
        let settings = WorldSettings {
            solver: SolverSettings {
                tolerance: 0.0,
                max_iterations: k,
                ..SolverSettings::default()
            },
            ..WorldSettings::default()
        };
        let mut world = scene::pyramid(5).build(settings).unwrap();
        for r in run(&mut world, &mut soft(4, 1), 50) {
            assert!(
                r.velocity_iterations <= k,
                "K = {k}: {}",
                r.velocity_iterations
            );
            assert!(r.velocity_iterations >= 1.min(k) || r.contacts == 0);
        }
    }
}
