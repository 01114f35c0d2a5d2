//! Measures the PGS loop in ns per contact point per iteration on a settled pile (in order,
//! coloured, coloured in batches, the same with islands of 512 points or more in the domain
//! plan on one thread (`pgs:parallel_from=512`: four domains or more), and coloured in batches
//! in `f32`, `pgs:precision=f32`):
//! `cargo run --release -p deepcontact-pgs --example pgs_speed [bodies] [iterations]`.

use std::time::Instant;

use deepcontact_core::Velocity;

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, SolveReport, SolverSettings, VelocitySolver,
    WarmStart, WarmStartContext, WarmStartError, WorldSettings, scene,
};
use deepcontact_pgs::{Ordering, PgsPositionSolver, PgsSettings, PgsSolver, Precision};

struct Record(Vec<(ContactProblem, Vec<Impulse>)>, u64);
impl WarmStart for Record {
    fn name(&self) -> &str {
        "record"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        if ctx.step == self.1 {
            self.0.push((
                ctx.problem.clone(),
                ctx.carried_impulses().collect::<Vec<_>>(),
            ));
        }
        CarriedWarmStart.warm_start(ctx, out)
    }
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let bodies = args.first().copied().unwrap_or(100);
    let iterations = args.get(1).copied().unwrap_or(1000) as u32;
    let steps = 240;
    let mut world = scene::pile(12345, bodies)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let mut rec = Record(Vec::new(), steps - 1);
    let (mut s, mut p) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..steps {
        world.step(&mut rec, &mut s, &mut p).unwrap();
    }
    let settings = SolverSettings {
        tolerance: 0.0,
        max_iterations: iterations,
        ..SolverSettings::default()
    };
    let points: usize = rec.0.iter().map(|(p, _)| p.len()).sum();
    let variants = [
        (
            "sequential",
            Ordering::Sequential,
            false,
            Precision::F64,
            usize::MAX,
        ),
        (
            "coloured",
            Ordering::Coloured,
            false,
            Precision::F64,
            usize::MAX,
        ),
        (
            "coloured+lanes",
            Ordering::Coloured,
            true,
            Precision::F64,
            usize::MAX,
        ),
        ("domains", Ordering::Coloured, true, Precision::F64, 512),
        ("f32", Ordering::Coloured, true, Precision::F32, usize::MAX),
    ];
    println!(
        "{bodies} bodies, {points} points in {} islands, {iterations} iterations (best of 5, side by side):",
        rec.0.len()
    );
    let mut results: Vec<Vec<Impulse>> = Vec::new();
    let mut times = Vec::new();
    for (name, ordering, lanes, precision, parallel_min_points) in variants {
        let mut solver = PgsSolver::with_settings(PgsSettings {
            ordering,
            lanes,
            precision,
            parallel_min_points,
            ..PgsSettings::default()
        });
        let mut report = SolveReport::default();
        let mut best = f64::INFINITY;
        let mut out = Vec::new();
        for _ in 0..5 {
            out.clear();
            let t = Instant::now();
            for (problem, carried) in &rec.0 {
                let mut imp = carried.clone();
                let mut vel = vec![Velocity::default(); problem.bodies.len()];
                solver
                    .solve(problem, &settings, &mut imp, &mut vel, &mut report)
                    .unwrap();
                out.extend_from_slice(&imp);
            }
            best = best.min(t.elapsed().as_secs_f64());
        }
        let ns = best * 1e9 / (points as f64 * iterations as f64);
        times.push(ns);
        println!(
            "  {name:<15} {:>9.3} ms per solve  {ns:>6.2} ns per point per iteration  ({:.2}x sequential)",
            best * 1e3,
            times[0] / ns
        );
        results.push(out);
    }
    let same = |x: &[Impulse], y: &[Impulse]| {
        x.iter().zip(y).all(|(a, b)| {
            a.normal.to_bits() == b.normal.to_bits() && a.tangent.to_bits() == b.tangent.to_bits()
        })
    };
    println!(
        "  coloured+lanes bit-identical to coloured: {}",
        same(&results[1], &results[2])
    );
}
