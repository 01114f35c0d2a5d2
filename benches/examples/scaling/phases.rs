//! The phases of one fixed-iteration step, timed one by one on a settled world.

use std::time::Instant;

use deepcontact_benches::{fixed_iterations, fixed_world};
use deepcontact_core::broad_phase::BroadPhase;
use deepcontact_core::island::Islands;
use deepcontact_core::narrow_phase::NarrowPhase;
use deepcontact_core::{
    ContactProblem, Impulse, Pose, PositionSolver, SolveReport, Velocity, VelocitySolver, World,
    WorldSettings,
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

/// Times the phases of a fixed-`iterations` step on `world`, each the minimum over `reps`
/// (robust to other processes on the machine).
pub fn phases(world: &World, iterations: u32, reps: u32) -> Result<Phases, String> {
    let mut timer = PhaseTimer::new(world, iterations);
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
        timer.collision(&mut ph);
        let (mut velocity, mut position, mut position_iterations) = (0.0, 0.0, 0.0);
        for problem in world.last_problems() {
            velocity += timer.velocity(problem)?;
            let (seconds, iterations) = timer.position(problem)?;
            position += seconds;
            position_iterations += f64::from(iterations) * problem.points.len() as f64;
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

/// The pieces of `World::step`, run one by one on a settled world's state.
struct PhaseTimer<'w> {
    world: &'w World,
    iterations: u32,
    settings: WorldSettings,
    dynamic: Vec<bool>,
    broad: BroadPhase,
    narrow: NarrowPhase,
    islands: Islands,
    velocity_solver: PgsSolver,
    position_solver: PgsPositionSolver,
    impulses: Vec<Impulse>,
    velocities: Vec<Velocity>,
    poses: Vec<Pose>,
    report: SolveReport,
}

impl<'w> PhaseTimer<'w> {
    fn new(world: &'w World, iterations: u32) -> Self {
        Self {
            world,
            iterations,
            settings: fixed_world(iterations),
            dynamic: world.bodies().iter().map(|b| b.is_dynamic()).collect(),
            broad: BroadPhase::new(),
            narrow: NarrowPhase::new(),
            islands: Islands::default(),
            velocity_solver: PgsSolver::default(),
            position_solver: PgsPositionSolver::default(),
            impulses: Vec::new(),
            velocities: Vec::new(),
            poses: Vec::new(),
            report: SolveReport::default(),
        }
    }

    /// Broad phase, narrow phase and islands, each timed into `ph` (minimum so far).
    fn collision(&mut self, ph: &mut Phases) {
        let bodies = self.world.bodies();
        let prediction = self.settings.prediction;
        let t = Instant::now();
        let pairs = self.broad.find_pairs(bodies, prediction).to_vec();
        ph.broad = ph.broad.min(t.elapsed().as_secs_f64());
        ph.pairs = pairs.len();
        let t = Instant::now();
        self.narrow.collide(bodies, &pairs, prediction);
        ph.narrow = ph.narrow.min(t.elapsed().as_secs_f64());
        let contacts = &self.narrow.contacts;
        let manifold_bodies: Vec<(u32, u32)> = self
            .narrow
            .manifolds_ranges
            .iter()
            .map(|&(s, _)| {
                (
                    contacts[s as usize].id.body_a,
                    contacts[s as usize].id.body_b,
                )
            })
            .collect();
        let t = Instant::now();
        self.islands.build(&self.dynamic, &manifold_bodies);
        ph.islands = ph.islands.min(t.elapsed().as_secs_f64());
    }

    /// Seconds of the fixed-count velocity solve of `problem`, started from the impulses the
    /// world solved for its points (the builtin warm start).
    fn velocity(&mut self, problem: &ContactProblem) -> Result<f64, String> {
        let solved = self.world.contacts();
        self.impulses.clear();
        self.impulses.extend(problem.points.iter().map(|p| {
            solved
                .binary_search_by(|(k, _)| k.cmp(&p.id))
                .map(|i| solved[i].1)
                .unwrap_or(Impulse::ZERO)
        }));
        self.velocities.clear();
        self.velocities
            .resize(problem.bodies.len(), Velocity::default());
        let t = Instant::now();
        self.velocity_solver
            .solve(
                problem,
                &fixed_iterations(self.iterations),
                &mut self.impulses,
                &mut self.velocities,
                &mut self.report,
            )
            .map_err(|e| e.to_string())?;
        Ok(t.elapsed().as_secs_f64())
    }

    /// Seconds and iterations of the position pass of `problem`, from the poses the world's
    /// pass starts from: contact-time poses moved by dt × the solved velocities (the world's
    /// bodies hold those velocities after the step).
    fn position(&mut self, problem: &ContactProblem) -> Result<(f64, u32), String> {
        let bodies = self.world.bodies();
        let dt = self.world.settings().dt;
        self.poses.clear();
        self.poses.extend(problem.bodies.iter().map(|b| {
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
        let r = self
            .position_solver
            .solve_positions(problem, &self.settings.position, &mut self.poses)
            .map_err(|e| e.to_string())?;
        Ok((t.elapsed().as_secs_f64(), r.iterations))
    }
}
