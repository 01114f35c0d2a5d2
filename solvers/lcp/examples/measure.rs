//! Iterations and solve time per step of PGS, PSOR and Newton on the thesis pile, for the
//! none / builtin / copy warm starts. Run in release:
//!
//! ```text
//! cargo run --release -p deepcontact-lcp --example measure -- [steps] [seed...]
//! ```
//!
//! Each (solver, start) pair simulates its own world (so the trajectories differ slightly);
//! "copy" starts every island from its solution converged to 1e-10 by Newton (the provider's
//! time is not counted in the solve time).

use deepcontact_core::{
    CarriedWarmStart, Impulse, SolveReport, SolverSettings, VelocitySolver, WarmStart,
    WarmStartContext, WarmStartError, WorldSettings, ZeroWarmStart, scene,
};
use deepcontact_lcp::{NewtonSolver, PsorSolver};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Starts from this step's solution (Newton to 1e-10 from the carried impulses).
struct CopyWarmStart {
    solver: NewtonSolver,
    report: SolveReport,
    velocities: Vec<deepcontact_core::Velocity>,
}

impl WarmStart for CopyWarmStart {
    fn name(&self) -> &str {
        "copy"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        for (o, c) in out.iter_mut().zip(ctx.carried_impulses()) {
            *o = c;
        }
        self.velocities
            .resize(ctx.problem.bodies.len(), Default::default());
        let tight = SolverSettings {
            tolerance: 1e-10,
            ..SolverSettings::default()
        };
        self.solver
            .solve(
                ctx.problem,
                &tight,
                out,
                &mut self.velocities,
                &mut self.report,
            )
            .map_err(|e| WarmStartError::Provider(format!("copy: {e}")))
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let steps: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(250);
    let seeds: Vec<u64> = if args.len() > 1 {
        args[1..].iter().filter_map(|s| s.parse().ok()).collect()
    } else {
        vec![12345]
    };
    println!("pile, 100 bodies, {steps} steps, seeds {seeds:?}, tolerance 1e-4 (inf), cap 1000");
    println!(
        "{:<8} {:<8} {:>10} {:>10} {:>10} {:>10} {:>8} {:>12}",
        "solver", "start", "its/step", "its(sum)", "ms/step", "us/it", "capped", "max nat.res"
    );
    for solver_name in ["pgs", "psor", "newton"] {
        for start in ["none", "builtin", "copy"] {
            let (mut its, mut its_sum, mut secs, mut capped, mut res, mut n) =
                (0u64, 0u64, 0.0, 0usize, 0.0f64, 0u64);
            for &seed in &seeds {
                let mut world = scene::pile(seed, 100)
                    .unwrap()
                    .build(WorldSettings::default())
                    .unwrap();
                let mut solver: Box<dyn VelocitySolver> = match solver_name {
                    "pgs" => Box::new(PgsSolver::new()),
                    "psor" => Box::new(PsorSolver::new()),
                    _ => Box::new(NewtonSolver::new()),
                };
                let mut warm: Box<dyn WarmStart> = match start {
                    "none" => Box::new(ZeroWarmStart),
                    "builtin" => Box::new(CarriedWarmStart),
                    _ => Box::new(CopyWarmStart {
                        solver: NewtonSolver::new(),
                        report: SolveReport::default(),
                        velocities: Vec::new(),
                    }),
                };
                let mut position = PgsPositionSolver::new();
                for _ in 0..steps {
                    let r = world
                        .step(warm.as_mut(), solver.as_mut(), &mut position)
                        .unwrap();
                    its += r.velocity_iterations as u64;
                    its_sum += r.velocity_iterations_sum;
                    secs += r.solve_seconds;
                    capped += r.capped_islands;
                    res = res.max(r.natural_residual);
                    n += 1;
                }
            }
            println!(
                "{:<8} {:<8} {:>10.1} {:>10.1} {:>10.3} {:>10.2} {:>8} {:>12.2e}",
                solver_name,
                start,
                its as f64 / n as f64,
                its_sum as f64 / n as f64,
                1e3 * secs / n as f64,
                1e6 * secs / its_sum.max(1) as f64,
                capped,
                res
            );
        }
    }
}
