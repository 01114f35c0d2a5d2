//! Where builtin's start error lives, and what it costs (the diagnosis of docs/RESEARCH.md).
//!
//! Runs piles with `builtin`, records the largest island at chosen steps, and for each:
//! solves it from the carried start to 1e-10 (λ*, the answer PGS reaches from there),
//! decomposes the start error `e = λ* − λc` on the eigenvectors of `W_AA` (the Delassus
//! matrix on λ*'s active set: loaded normal rows, friction rows inside the cone), and
//! measures PGS iterations to the world's tolerance from λc, from 0, and from `λ* + e`
//! with either its slow part (the eigenvectors of the smallest 10 % of eigenvalues) or its
//! fast part removed, and how soft the slow modes are (the eigenvalue at 10 % over the median).
//!
//! ```sh
//! cargo run --release -p deepcontact-experiments --example start_error -- 100..104
//! ```

use deepcontact_core::{ContactProblem, Impulse, SolverSettings};
use deepcontact_experiments::record::{IslandRecorder, pgs_iterations};
use deepcontact_lcp::{AssemblyMode, DEFAULT_DENSE_THRESHOLD, Delassus};
use nalgebra::{DMatrix, DVector};

/// Steps recorded in each pile.
const STEPS: [u64; 5] = [150, 175, 200, 225, 249];
/// Share of the active set's eigenvalues counted as "slow".
const SLOW_SHARE: f64 = 0.10;

/// PGS iterations from `start` to `tolerance`, and the answer.
fn solve(problem: &ContactProblem, start: &[Impulse], tolerance: f64) -> (u32, Vec<Impulse>) {
    pgs_iterations(problem, start, tolerance).expect("a recorded problem solves")
}

fn flat(x: &[Impulse]) -> DVector<f64> {
    DVector::from_iterator(2 * x.len(), x.iter().flat_map(|i| [i.normal, i.tangent]))
}

fn unflat(x: &DVector<f64>) -> Vec<Impulse> {
    x.as_slice()
        .chunks(2)
        .map(|c| Impulse::new(c[0].max(0.0), c[1]))
        .collect()
}

/// One recorded island: the figures of the table.
struct Row {
    seed: u64,
    step: u64,
    points: usize,
    from_carried: u32,
    from_zero: u32,
    error_l2: f64,
    slow_share: f64,
    velocity_error: f64,
    slow_only: u32,
    fast_only: u32,
    /// Eigenvalue at the slow/fast border over the median eigenvalue of `W_AA`.
    softness: f64,
}

fn analyse(seed: u64, step: u64, problem: &ContactProblem, carried: &[Impulse]) -> Row {
    let tolerance = SolverSettings::default().tolerance;
    let (from_carried, _) = solve(problem, carried, tolerance);
    let (from_zero, _) = solve(problem, &vec![Impulse::ZERO; carried.len()], tolerance);
    let (_, exact) = solve(problem, carried, 1e-10);
    let (x, c) = (flat(&exact), flat(carried));
    let e = &x - &c;
    let mut delassus = Delassus::new();
    delassus
        .assemble(problem, AssemblyMode::Auto, DEFAULT_DENSE_THRESHOLD)
        .expect("a recorded problem assembles");
    let w = delassus.to_dense();
    let rows = e.len();
    let active: Vec<usize> = (0..rows)
        .filter(|&k| {
            let p = exact[k / 2];
            if k % 2 == 0 {
                p.normal > 0.0
            } else {
                p.tangent.abs() < problem.points[k / 2].friction * p.normal
            }
        })
        .collect();
    let waa = DMatrix::from_fn(active.len(), active.len(), |i, j| w[(active[i], active[j])]);
    let ea = DVector::from_iterator(active.len(), active.iter().map(|&k| e[k]));
    let we = &waa * &ea;
    let eig = waa.symmetric_eigen();
    let mut order: Vec<usize> = (0..active.len()).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let slow_count = ((active.len() as f64) * SLOW_SHARE).ceil() as usize;
    let mut slow = DVector::zeros(rows);
    for &m in order.iter().take(slow_count) {
        let v = eig.eigenvectors.column(m);
        let coef = v.dot(&ea);
        for (i, &k) in active.iter().enumerate() {
            slow[k] += coef * v[i];
        }
    }
    let fast = &e - &slow;
    let eigenvalue = |q: f64| eig.eigenvalues[order[((order.len() - 1) as f64 * q) as usize]];
    let softness = eigenvalue(SLOW_SHARE) / eigenvalue(0.5);

    let (slow_only, _) = solve(problem, &unflat(&(&x - &slow)), tolerance);
    let (fast_only, _) = solve(problem, &unflat(&(&x - &fast)), tolerance);
    Row {
        seed,
        step,
        points: problem.len(),
        from_carried,
        from_zero,
        error_l2: e.norm(),
        slow_share: slow.norm_squared() / e.norm_squared().max(1e-300),
        velocity_error: we.norm(),
        slow_only,
        fast_only,
        softness,
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let arg = std::env::args().nth(1).unwrap_or_else(|| "100..104".into());
    let seeds = deepcontact_experiments::seeds::parse_seeds(&arg)?;
    println!(
        "| seed | step | points | it from carried | it from 0 | ‖e‖₂ | slow share of ‖e‖² | ‖W_AA e_A‖₂ | it, slow part only | it, fast part only | μ₁₀ % / μ₅₀ % |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut totals = [0.0; 5];
    let mut count = 0.0;
    for seed in seeds {
        for (step, problem, carried) in &IslandRecorder::record_pile(seed, 100, &STEPS)? {
            let r = analyse(seed, *step, problem, carried);
            println!(
                "| {} | {} | {} | {} | {} | {:.3e} | {:.3} | {:.3e} | {} | {} | {:.2e} |",
                r.seed,
                r.step,
                r.points,
                r.from_carried,
                r.from_zero,
                r.error_l2,
                r.slow_share,
                r.velocity_error,
                r.slow_only,
                r.fast_only,
                r.softness
            );
            totals[0] += f64::from(r.from_carried);
            totals[1] += r.slow_share;
            totals[2] += f64::from(r.slow_only);
            totals[3] += f64::from(r.fast_only);
            totals[4] += r.softness;
            count += 1.0;
        }
    }
    println!(
        "\nmean over {count} islands: iterations from carried {:.1}, slow share {:.3}, iterations with the slow part only {:.1}, with the fast part only {:.1}, μ₁₀ % / μ₅₀ % {:.2e}",
        totals[0] / count,
        totals[1] / count,
        totals[2] / count,
        totals[3] / count,
        totals[4] / count
    );
    Ok(())
}
