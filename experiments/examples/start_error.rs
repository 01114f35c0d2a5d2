//! Where builtin's start error lives, and what it costs (the diagnosis of docs/RESEARCH.md).
//!
//! Runs piles of `--bodies` circles (default 100) with `builtin`, records the largest island at
//! chosen steps, and for each: solves it from the carried start to 1e-10 (λ*, the answer PGS
//! reaches from there), decomposes the start error `e = λ* − λc` on the eigenvectors of `W_AA`
//! (the Delassus matrix on λ*'s active set: loaded normal rows, friction rows inside the cone),
//! and measures PGS iterations to the world's tolerance (at most `--cap`, default 1 000, the
//! world's own cap) from λc, from 0, and from `λ* + e` with either its slow part (the
//! eigenvectors of the smallest share of eigenvalues, the first of `--slow`, default 0.1) or its
//! fast part removed; with more shares, the iterations with each share's slow part removed (what
//! an exact correction on that many of the slowest modes would leave); and how soft the slow
//! modes are (the eigenvalue at the first share over the median).
//!
//! ```sh
//! cargo run --release -p deepcontact-experiments --example start_error -- 100..104
//! cargo run --release -p deepcontact-experiments --example start_error -- 100..103 \
//!     --bodies 1000 --steps 160,200,240 --slow 0.1,0.3,0.5 --cap 20000
//! ```

use deepcontact_core::{ContactProblem, Impulse, SolverSettings};
use deepcontact_experiments::record::{IslandRecorder, pgs_iterations, solve_from};
use deepcontact_lcp::{AssemblyMode, DEFAULT_DENSE_THRESHOLD, Delassus};
use deepcontact_pgs::PgsSolver;
use faer::{Mat, Side};

const USAGE: &str = "usage: start_error [SEEDS, default 100..104] [--bodies 100] \
[--steps 150,175,200,225,249] [--slow 0.1,...] [--cap 1000]";

/// The command line's settings.
struct Options {
    seeds: Vec<u64>,
    bodies: usize,
    steps: Vec<u64>,
    /// Shares of the active set's eigenvalues counted as "slow", the first for the table's
    /// slow and fast parts.
    slow: Vec<f64>,
    /// PGS iterations at most when counting them to the world's tolerance.
    cap: u32,
}

/// PGS iterations from `start` to `tolerance` (at most `cap`), and the answer.
fn solve(
    problem: &ContactProblem,
    start: &[Impulse],
    tolerance: f64,
    cap: u32,
) -> (u32, Vec<Impulse>) {
    let settings = SolverSettings {
        tolerance,
        max_iterations: cap,
        ..SolverSettings::default()
    };
    solve_from(&mut PgsSolver::new(), problem, start, &settings).expect("a recorded problem solves")
}

/// The impulses as one vector of rows, normal then tangent per point.
fn flat(x: &[Impulse]) -> Vec<f64> {
    x.iter().flat_map(|i| [i.normal, i.tangent]).collect()
}

/// [`flat`] undone, the normals clamped at 0.
fn unflat(x: &[f64]) -> Vec<Impulse> {
    x.chunks(2)
        .map(|c| Impulse::new(c[0].max(0.0), c[1]))
        .collect()
}

/// `a − b`, element by element.
fn minus(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

/// `‖a‖²`.
fn norm_squared(a: &[f64]) -> f64 {
    a.iter().map(|x| x * x).sum()
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
    /// Iterations with the slow part of each share of `--slow` removed.
    without_slow: Vec<u32>,
    /// Eigenvalue at the first slow share over the median eigenvalue of `W_AA`.
    softness: f64,
}

fn analyse(
    o: &Options,
    seed: u64,
    step: u64,
    problem: &ContactProblem,
    carried: &[Impulse],
) -> Row {
    let tolerance = SolverSettings::default().tolerance;
    let (from_carried, _) = solve(problem, carried, tolerance, o.cap);
    let (from_zero, _) = solve(
        problem,
        &vec![Impulse::ZERO; carried.len()],
        tolerance,
        o.cap,
    );
    let (_, exact) = pgs_iterations(problem, carried, 1e-10).expect("a recorded problem solves");
    let (x, c) = (flat(&exact), flat(carried));
    let e = minus(&x, &c);
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
    let n = active.len();
    let waa = Mat::from_fn(n, n, |i, j| w[(active[i], active[j])]);
    let ea: Vec<f64> = active.iter().map(|&k| e[k]).collect();
    let we: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|j| waa[(i, j)] * ea[j]).sum())
        .collect();
    // Eigenvalues in nondecreasing order, eigenvectors the columns of U.
    let eig = waa
        .self_adjoint_eigen(Side::Lower)
        .expect("W_AA is symmetric");
    let (u, s) = (eig.U(), eig.S().column_vector());
    // The part of `e` on the slowest `share` of the modes, on every row.
    let slow_part = |share: f64| {
        let count = ((n as f64) * share).ceil() as usize;
        let mut slow = vec![0.0; rows];
        for m in 0..count.min(n) {
            let coef: f64 = (0..n).map(|i| u[(i, m)] * ea[i]).sum();
            for (i, &k) in active.iter().enumerate() {
                slow[k] += coef * u[(i, m)];
            }
        }
        slow
    };
    let first = o.slow[0];
    let slow = slow_part(first);
    let fast = minus(&e, &slow);
    let eigenvalue = |q: f64| s[((n.max(1) - 1) as f64 * q) as usize];
    let softness = eigenvalue(first) / eigenvalue(0.5);

    let (slow_only, _) = solve(problem, &unflat(&minus(&x, &slow)), tolerance, o.cap);
    let (fast_only, _) = solve(problem, &unflat(&minus(&x, &fast)), tolerance, o.cap);
    let without_slow = o.slow[1..]
        .iter()
        .map(|&share| {
            let rest = minus(&e, &slow_part(share));
            solve(problem, &unflat(&minus(&x, &rest)), tolerance, o.cap).0
        })
        .collect();
    Row {
        seed,
        step,
        points: problem.len(),
        from_carried,
        from_zero,
        error_l2: norm_squared(&e).sqrt(),
        slow_share: norm_squared(&slow) / norm_squared(&e).max(1e-300),
        velocity_error: norm_squared(&we).sqrt(),
        slow_only,
        fast_only,
        without_slow,
        softness,
    }
}

fn main() {
    match parse() {
        Ok(None) => println!("{USAGE}"),
        Ok(Some(o)) => {
            if let Err(e) = run(&o) {
                eprintln!("start_error: {e}");
                std::process::exit(1);
            }
        }
        Err(e) => {
            eprintln!("start_error: {e}\n{USAGE}");
            std::process::exit(2);
        }
    }
}

/// The options from the command line (`None`: help was asked for).
fn parse() -> Result<Option<Options>, Box<dyn std::error::Error>> {
    let mut o = Options {
        seeds: deepcontact_experiments::seeds::parse_seeds("100..104")?,
        bodies: 100,
        steps: vec![150, 175, 200, 225, 249],
        slow: vec![0.1],
        cap: 1000,
    };
    /// A comma-separated list of numbers.
    fn list<T: std::str::FromStr>(text: &str) -> Result<Vec<T>, String>
    where
        T::Err: std::fmt::Display,
    {
        text.split(',')
            .map(|s| s.trim().parse().map_err(|e| format!("`{s}`: {e}")))
            .collect()
    }
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--bodies" => o.bodies = value()?.parse()?,
            "--steps" => o.steps = list(&value()?)?,
            "--slow" => o.slow = list(&value()?)?,
            "--cap" => o.cap = value()?.parse()?,
            "-h" | "--help" => return Ok(None),
            seeds if !seeds.starts_with('-') => {
                o.seeds = deepcontact_experiments::seeds::parse_seeds(seeds)?;
            }
            other => return Err(format!("unknown argument `{other}`").into()),
        }
    }
    if o.slow.is_empty() || o.slow.iter().any(|s| !(0.0..=1.0).contains(s)) {
        return Err("--slow takes shares between 0 and 1".into());
    }
    Ok(Some(o))
}

fn run(o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let more: String = o.slow[1..]
        .iter()
        .map(|s| format!(" it, slowest {:.0} % removed |", s * 100.0))
        .collect();
    println!(
        "| seed | step | points | it from carried | it from 0 | ‖e‖₂ | slow share of ‖e‖² | ‖W_AA e_A‖₂ | it, slow part only | it, fast part only |{more} μ_slow / μ₅₀ % |"
    );
    println!(
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|{}---:|",
        "---:|".repeat(o.slow.len() - 1)
    );
    let mut totals = [0.0; 5];
    let mut without = vec![0.0; o.slow.len() - 1];
    let mut count = 0.0;
    for &seed in &o.seeds {
        for (step, problem, carried) in &IslandRecorder::record_pile(seed, o.bodies, &o.steps)? {
            let r = analyse(o, seed, *step, problem, carried);
            let more: String = r.without_slow.iter().map(|it| format!(" {it} |")).collect();
            println!(
                "| {} | {} | {} | {} | {} | {:.3e} | {:.3} | {:.3e} | {} | {} |{more} {:.2e} |",
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
            for (t, it) in without.iter_mut().zip(&r.without_slow) {
                *t += f64::from(*it);
            }
            count += 1.0;
        }
    }
    let more: String = o.slow[1..]
        .iter()
        .zip(&without)
        .map(|(s, t)| {
            format!(
                ", with the slowest {:.0} % removed {:.1}",
                s * 100.0,
                t / count
            )
        })
        .collect();
    println!(
        "\nmean over {count} islands: iterations from carried {:.1}, slow share {:.3}, iterations with the slow part only {:.1}, with the fast part only {:.1}{more}, μ_slow / μ₅₀ % {:.2e}",
        totals[0] / count,
        totals[1] / count,
        totals[2] / count,
        totals[3] / count,
        totals[4] / count
    );
    Ok(())
}
