//! The phases of one fixed-iteration step, timed one by one on a settled world.

use std::time::Instant;

use deepcontact_benches::{fixed_iterations, fixed_world};
use deepcontact_core::broad_phase::BroadPhase;
use deepcontact_core::island::Islands;
use deepcontact_core::narrow_phase::NarrowPhase;
use deepcontact_core::{
    Impulse, Pose, PositionSolver, SolveReport, Velocity, VelocitySolver, World,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Phases of one step timed one by one on a settled world, through the same public pieces
/// that `World::step` runs (seconds per step, averaged over `reps`).
#[derive(Default, Clone, Copy)]
pub struct Phases {
    /// Broad phase, s.
    pub broad: f64,
    /// Narrow phase, s.
    pub narrow: f64,
    /// Islands, s.
    pub islands: f64,
    /// Velocity solve, s.
    pub velocity: f64,
    /// Position pass, s.
    pub position: f64,
    /// Contact-weighted mean position iterations.
    pub position_iterations: f64,
    /// Broad-phase pairs.
    pub pairs: usize,
}

/// Times the phases of a fixed-`iterations` step on `world`, each the minimum over `reps`.
pub fn phases(world: &World, iterations: u32, reps: u32) -> Result<Phases, String> {
    let bodies = world.bodies();
    let (mut bp, mut np, mut isl) = (BroadPhase::new(), NarrowPhase::new(), Islands::default());
    let dynamic: Vec<bool> = bodies.iter().map(|b| b.is_dynamic()).collect();
    let settings = fixed_world(iterations);
    let (mut vs, mut ps) = (PgsSolver::default(), PgsPositionSolver::default());
    let mut impulses: Vec<Impulse> = Vec::new();
    let mut velocities: Vec<Velocity> = Vec::new();
    let mut poses: Vec<Pose> = Vec::new();
    let mut report = SolveReport::default();
    // Each phase's minimum over the repetitions: robust to other processes on the machine.
    let inf = f64::INFINITY;
    let mut ph = Phases {
        broad: inf,
        narrow: inf,
        islands: inf,
        velocity: inf,
        position: inf,
        ..Phases::default()
    };
    for _ in 0..reps {
        let (mut velocity, mut position, mut position_iterations) = (0.0, 0.0, 0.0);
        let t = Instant::now();
        let pairs = bp.find_pairs(bodies, settings.prediction).to_vec();
        ph.broad = ph.broad.min(t.elapsed().as_secs_f64());
        ph.pairs = pairs.len();
        let t = Instant::now();
        np.collide(bodies, &pairs, settings.prediction);
        ph.narrow = ph.narrow.min(t.elapsed().as_secs_f64());
        let manifold_bodies: Vec<(u32, u32)> = np
            .manifolds_ranges
            .iter()
            .map(|&(s, _)| {
                (
                    np.contacts[s as usize].id.body_a,
                    np.contacts[s as usize].id.body_b,
                )
            })
            .collect();
        let t = Instant::now();
        isl.build(&dynamic, &manifold_bodies);
        ph.islands = ph.islands.min(t.elapsed().as_secs_f64());
        for problem in world.last_problems() {
            // Start from the impulses the world solved for these points (the builtin warm start).
            let solved = world.contacts();
            impulses.clear();
            impulses.extend(problem.points.iter().map(|p| {
                solved
                    .binary_search_by(|(k, _)| k.cmp(&p.id))
                    .map(|i| solved[i].1)
                    .unwrap_or(Impulse::ZERO)
            }));
            velocities.clear();
            velocities.resize(problem.bodies.len(), Velocity::default());
            let t = Instant::now();
            vs.solve(
                problem,
                &fixed_iterations(iterations),
                &mut impulses,
                &mut velocities,
                &mut report,
            )
            .map_err(|e| e.to_string())?;
            velocity += t.elapsed().as_secs_f64();
            poses.clear();
            // The poses the world's position pass starts from: contact-time poses moved by dt × the
            // solved velocities (the world's bodies hold those velocities after the step).
            let dt = world.settings().dt;
            poses.extend(problem.bodies.iter().map(|b| {
                let body = &bodies[b.world_index as usize];
                if body.is_dynamic() {
                    Pose::new(
                        b.position + dt * body.linear_velocity,
                        b.angle + dt * body.angular_velocity,
                    )
                } else {
                    Pose::new(b.position, b.angle)
                }
            }));
            let t = Instant::now();
            let r = ps
                .solve_positions(problem, &settings.position, &mut poses)
                .map_err(|e| e.to_string())?;
            position += t.elapsed().as_secs_f64();
            position_iterations += f64::from(r.iterations) * problem.points.len() as f64;
        }
        ph.velocity = ph.velocity.min(velocity);
        ph.position = ph.position.min(position);
        ph.position_iterations = position_iterations;
    }
    let contacts: usize = world.last_problems().iter().map(|p| p.points.len()).sum();
    // Contact-weighted mean position iterations.
    ph.position_iterations /= contacts.max(1) as f64;
    Ok(ph)
}
