//! Scaling study: piles of 100, 1 000 and 10 000 circles (box scaled to keep the density),
//! deepcontact beside rapier2d, printed as a markdown table.
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example scaling
//! cargo run --release -p deepcontact-benches --example scaling -- --sizes 100,1000 --iterations 10
//! ```
//!
//! Per size: the pile is settled (builtin warm start, PGS, thesis stop rule with the velocity
//! cap lowered to `--settle-cap`, position cap 20) for `--settle` steps (default: 250 × (N /
//! 100)^¼, the thesis's 250 steps stretched by the longer fall of a taller pile), then
//! measured for a number of steps under three settings, continuing from the settled state:
//!
//! * `fixed`: `--iterations` velocity iterations always (tolerance 0), position cap the same;
//!   time per step, its split, and ns per contact point per iteration of the velocity solve;
//! * `thesis`: the thesis stop rule (∞-norm < 1e-4, cap 1000; position cap 250);
//! * `rapier2d`: the same scene in rapier2d with `num_solver_iterations = --iterations`,
//!   settled for the same number of steps in rapier itself.
//!
//! Timings are wall-clock on whatever machine runs it; compare rows of one run only.

use std::time::Instant;

use deepcontact_benches::{SEED, fixed_iterations, fixed_world, settle_world};
use deepcontact_core::Pose;
use deepcontact_core::Velocity;
use deepcontact_core::broad_phase::BroadPhase;
use deepcontact_core::island::Islands;
use deepcontact_core::narrow_phase::NarrowPhase;
use deepcontact_core::{
    CarriedWarmStart, Impulse, PositionSolver, SolveReport, StepReport, VelocitySolver, World,
    WorldSettings, scene,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

#[path = "../benches/groups/rapier_pile.rs"]
mod rapier_pile;

struct Options {
    sizes: Vec<usize>,
    iterations: u32,
    settle: Option<u64>,
    settle_cap: u32,
    measure: Option<u64>,
    rapier: bool,
    thesis: bool,
    trace: bool,
}

fn parse() -> Result<Options, String> {
    let mut o = Options {
        sizes: deepcontact_benches::SIZES.to_vec(),
        iterations: 10,
        settle: None,
        settle_cap: 50,
        measure: None,
        rapier: true,
        thesis: true,
        trace: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--sizes" => {
                o.sizes = value("--sizes")?
                    .split(',')
                    .map(|s| {
                        s.trim()
                            .parse::<usize>()
                            .map_err(|e| format!("--sizes: {e}"))
                    })
                    .collect::<Result<_, _>>()?
            }
            "--iterations" => {
                o.iterations = value("--iterations")?
                    .parse()
                    .map_err(|e| format!("--iterations: {e}"))?
            }
            "--settle" => {
                o.settle = Some(
                    value("--settle")?
                        .parse()
                        .map_err(|e| format!("--settle: {e}"))?,
                )
            }
            "--settle-cap" => {
                o.settle_cap = value("--settle-cap")?
                    .parse()
                    .map_err(|e| format!("--settle-cap: {e}"))?
            }
            "--measure" => {
                o.measure = Some(
                    value("--measure")?
                        .parse()
                        .map_err(|e| format!("--measure: {e}"))?,
                )
            }
            "--no-rapier" => o.rapier = false,
            "--no-thesis" => o.thesis = false,
            "--trace" => o.trace = true,
            "-h" | "--help" => {
                println!(
                    "scaling [--sizes 100,1000,10000] [--iterations 10] [--settle STEPS] [--settle-cap 50] \
                     [--measure STEPS] [--no-rapier] [--no-thesis] [--trace]"
                );
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(o)
}

/// Steps to settle a pile of `n` bodies: 250 × (n / 100)^¼.
fn settle_steps(n: usize) -> u64 {
    (250.0 * (n as f64 / 100.0).powf(0.25)).round() as u64
}

/// Steps measured per setting: about 50 000 body-steps, 5 to 500.
fn measure_steps(n: usize) -> u64 {
    (50_000 / n as u64).clamp(5, 500)
}

#[derive(Default)]
struct Totals {
    steps: u64,
    contacts: u64,
    point_iterations: u64,
    iterations_max: u64,
    step: f64,
    warm: f64,
    solve: f64,
    wall: f64,
    wall_min: f64,
}

impl Totals {
    fn add(&mut self, r: &StepReport, fixed: Option<u32>, wall: f64) {
        self.steps += 1;
        self.contacts += r.contacts as u64;
        if let Some(n) = fixed {
            self.point_iterations += u64::from(n) * r.contacts as u64;
        }
        self.iterations_max += u64::from(r.velocity_iterations);
        self.step += r.step_seconds;
        self.warm += r.warm_start_seconds;
        self.solve += r.solve_seconds;
        self.wall += wall;
        self.wall_min = if self.steps == 1 {
            wall
        } else {
            self.wall_min.min(wall)
        };
    }
    fn ms(&self, s: f64) -> f64 {
        s / self.steps as f64 * 1e3
    }
}

fn run(
    world: &mut World,
    settings: WorldSettings,
    steps: u64,
    fixed: Option<u32>,
) -> Result<Totals, String> {
    world.set_settings(settings).map_err(|e| e.to_string())?;
    let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
    let mut t = Totals::default();
    for _ in 0..steps {
        let t0 = Instant::now();
        let r = world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .map_err(|e| e.to_string())?;
        t.add(&r, fixed, t0.elapsed().as_secs_f64());
    }
    Ok(t)
}

/// rapier2d's figures for one pile.
struct Peer {
    /// Mean ms per step.
    ms: f64,
    /// Fastest step, ms.
    min_ms: f64,
    /// Mean contact points handed to the solver.
    contacts: f64,
    /// Velocity resolution (all substeps) in ns per contact point per solver iteration.
    solver_ns: f64,
    /// Collision detection, ms per step.
    collision_ms: f64,
}

/// Phases of one step timed one by one on a settled world, through the same public pieces
/// that `World::step` runs (seconds per step, averaged over `reps`).
#[derive(Default, Clone, Copy)]
struct Phases {
    broad: f64,
    narrow: f64,
    islands: f64,
    velocity: f64,
    position: f64,
    position_iterations: f64,
    pairs: usize,
}

fn phases(world: &World, iterations: u32, reps: u32) -> Result<Phases, String> {
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

fn main() -> Result<(), String> {
    let o = parse()?;
    let mut rows = Vec::new();
    for &n in &o.sizes {
        let scene = scene::pile(SEED, n).map_err(|e| e.to_string())?;
        let settle = o.settle.unwrap_or_else(|| settle_steps(n));
        let mut world = scene
            .build(settle_world(o.settle_cap))
            .map_err(|e| e.to_string())?;
        let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
        let t0 = Instant::now();
        for s in 0..settle {
            let r = world
                .step(&mut CarriedWarmStart, &mut solver, &mut position)
                .map_err(|e| e.to_string())?;
            if o.trace && (s % 50 == 0 || s + 1 == settle) {
                eprintln!(
                    "  n={n} step {s}: {} contacts, KE {:.3} J, {} islands, {} it, {} pos it, {:.2} ms (solve {:.2})",
                    r.contacts,
                    world.kinetic_energy(),
                    r.islands,
                    r.velocity_iterations,
                    r.position_iterations,
                    r.step_seconds * 1e3,
                    r.solve_seconds * 1e3
                );
            }
        }
        let settle_s = t0.elapsed().as_secs_f64();
        let m = o.measure.unwrap_or_else(|| measure_steps(n));
        let fixed = run(&mut world, fixed_world(o.iterations), m, Some(o.iterations))?;
        let ph = phases(&world, o.iterations, m.min(20) as u32)?;
        let thesis = if o.thesis {
            Some(run(&mut world, WorldSettings::default(), m.min(20), None)?)
        } else {
            None
        };
        let rapier = if o.rapier {
            let mut peer = rapier_pile::RapierPile::new(&scene, o.iterations as usize);
            for s in 0..settle {
                peer.step();
                if o.trace && (s % 50 == 0 || s + 1 == settle) {
                    eprintln!(
                        "  n={n} rapier step {s}: {} contacts, KE {:.3} J",
                        peer.contacts(),
                        peer.kinetic_energy()
                    );
                }
            }
            let (mut wall, mut wall_min, mut contacts) = (0.0, f64::INFINITY, 0u64);
            let (mut solver, mut collision) = (0.0, 0.0);
            for _ in 0..m {
                let t0 = Instant::now();
                peer.step();
                let dt = t0.elapsed().as_secs_f64();
                wall += dt;
                wall_min = wall_min.min(dt);
                contacts += peer.contacts() as u64;
                solver += peer.solver_seconds();
                collision += peer.collision_seconds();
            }
            eprintln!(
                "n={n}: kinetic energy after the measured steps: deepcontact {:.3} J, rapier2d {:.3} J",
                world.kinetic_energy(),
                peer.kinetic_energy()
            );
            Some(Peer {
                ms: wall / m as f64 * 1e3,
                min_ms: wall_min * 1e3,
                contacts: contacts as f64 / m as f64,
                solver_ns: solver / (contacts.max(1) as f64 * f64::from(o.iterations)) * 1e9,
                collision_ms: collision / m as f64 * 1e3,
            })
        } else {
            None
        };
        eprintln!(
            "n={n}: settled {settle} steps in {settle_s:.1} s, measured {m} steps per setting"
        );
        rows.push((n, settle, fixed, thesis, rapier, ph));
    }

    println!(
        "| bodies | contacts | fixed {it}: ms/step (min) | solve ms | rest ms | ns/contact/iter | \
         µs/contact/step | thesis: ms/step | iterations (max) | rapier2d {it}: ms/step (min) | \
         rapier contacts | ours/rapier (min) |",
        it = o.iterations
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (n, _, f, t, r, _) in &rows {
        let contacts = f.contacts as f64 / f.steps as f64;
        let ns = f.solve / f.point_iterations.max(1) as f64 * 1e9;
        let us_per_contact = f.ms(f.wall) * 1e3 / contacts.max(1.0);
        let (t_ms, t_it) = t
            .as_ref()
            .map(|t| {
                (
                    format!("{:.2}", t.ms(t.wall)),
                    format!("{:.0}", t.iterations_max as f64 / t.steps as f64),
                )
            })
            .unwrap_or(("–".into(), "–".into()));
        let (r_ms, r_c, ratio) = r
            .as_ref()
            .map(|p| {
                (
                    format!("{:.2} ({:.2})", p.ms, p.min_ms),
                    format!("{:.0}", p.contacts),
                    format!(
                        "{:.2} ({:.2})",
                        f.ms(f.wall) / p.ms,
                        f.wall_min * 1e3 / p.min_ms
                    ),
                )
            })
            .unwrap_or(("–".into(), "–".into(), "–".into()));
        println!(
            "| {n} | {contacts:.0} | {:.2} ({:.2}) | {:.2} | {:.2} | {ns:.1} | {us_per_contact:.2} | {t_ms} | {t_it} \
             | {r_ms} | {r_c} | {ratio} |",
            f.ms(f.wall),
            f.wall_min * 1e3,
            f.ms(f.solve),
            f.ms(f.wall - f.solve - f.warm),
        );
    }

    println!();
    println!(
        "Phases of a fixed-{it} step, timed one by one on the settled world (minimum over repetitions; \
         ns per contact point; velocity and position per point-iteration):",
        it = o.iterations
    );
    println!();
    println!(
        "| bodies | contacts | pairs | broad | narrow | islands | velocity /it | position /it | position its | \
         min step ms |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (n, _, f, _, _, ph) in &rows {
        let contacts = f.contacts as f64 / f.steps as f64;
        let per = |s: f64| s / contacts.max(1.0) * 1e9;

        println!(
            "| {n} | {contacts:.0} | {} | {:.0} | {:.0} | {:.0} | {:.1} | {:.1} | {:.1} | {:.2} |",
            ph.pairs,
            per(ph.broad),
            per(ph.narrow),
            per(ph.islands),
            per(ph.velocity) / f64::from(o.iterations),
            per(ph.position) / ph.position_iterations.max(1.0),
            ph.position_iterations,
            f.wall_min * 1e3,
        );
    }

    if o.rapier {
        println!();
        println!(
            "Solver only, ns per contact point per iteration at {it} iterations (ours: PGS velocity solve; \
             rapier2d: its whole velocity resolution, each iteration = one substep with one PGS and one \
             stabilisation pass plus integration); collision detection in ms per step:",
            it = o.iterations
        );
        println!();
        println!(
            "| bodies | ours ns/contact/iter | rapier2d ns/contact/iter | ratio | ours broad+narrow ms | rapier2d collision ms |"
        );
        println!("|---:|---:|---:|---:|---:|---:|");
        for (n, _, f, _, r, ph) in &rows {
            if let Some(p) = r {
                let ns = f.solve / f.point_iterations.max(1) as f64 * 1e9;
                println!(
                    "| {n} | {ns:.1} | {:.1} | {:.2} | {:.2} | {:.2} |",
                    p.solver_ns,
                    ns / p.solver_ns,
                    (ph.broad + ph.narrow) * 1e3,
                    p.collision_ms
                );
            }
        }
    }
    Ok(())
}
