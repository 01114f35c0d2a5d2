//! Momentum on Gauss-Seidel sweeps, measured on recorded islands of a pile: how many sweeps
//! from the carried impulses each variant needs before a sweep changes no impulse by more than
//! the world's tolerance (1e-4 N·s, its stop rule).
//!
//! Variants (one sweep visits every point, friction row then normal row, as the world's PGS):
//! - `gs`: plain projected Gauss-Seidel, forward sweeps.
//! - `nncg`: the nonsmooth nonlinear conjugate gradient of Silcowski et al. (2011) on forward
//!   sweeps: `β = ‖Δ_k‖² / ‖Δ_{k−1}‖²`, restart (no momentum) when `β > 1`, else
//!   `λ += β p`, `p ← β p + Δ_k`.
//! - `hb β`: heavy-ball momentum with a fixed `β`, restarted when `‖Δ‖` grows.
//! - `sym …`: the same on symmetric sweeps (a forward sweep, then a backward one, as one
//!   iteration: Gauss-Seidel symmetrised, the classical partner of conjugate gradients).
//! - `extrapolate m/F`: forward sweeps; every `m` sweeps, if the change shrank by a rate
//!   `ρ < 1` a sweep over those `m` and the last two changes point the same way (cosine above
//!   0.95), the impulses jump by `min(ρ / (1 − ρ), F)` times the last change (the rest of a
//!   geometric series along one slow mode); the jump is undone when the next sweep's change is
//!   larger than the last one before it.
//!
//! Each cell prints `sweeps/restarts` (for `extrapolate`: `sweeps/jumps/undone`); a symmetric
//! iteration counts as two sweeps. The momentum step is not projected (the next sweep
//! projects), as in the paper.
//!
//! ```sh
//! cargo run --release -p deepcontact-experiments --example momentum_sweeps -- \
//!     --bodies 1000 --seed 100 --steps 160,200 --cap 40000
//! ```

use deepcontact_core::math::cross;
use deepcontact_core::{ContactProblem, Impulse, Real, Velocity};
use deepcontact_experiments::record::IslandRecorder;

/// The world's stop rule: the largest impulse change of a sweep (N·s).
const TOLERANCE: Real = 1e-4;

/// How the sweeps are combined.
#[derive(Debug, Clone, Copy)]
enum Method {
    /// Plain sweeps.
    Plain,
    /// Nonsmooth nonlinear conjugate gradient.
    Nncg,
    /// Heavy ball with this momentum.
    HeavyBall(Real),
}

/// An island's impulses (`[tangent, normal]` per point) and the bodies' velocities after them.
struct State<'a> {
    problem: &'a ContactProblem,
    lambda: Vec<Real>,
    velocity: Vec<Velocity>,
}

impl<'a> State<'a> {
    fn new(problem: &'a ContactProblem, start: &[Impulse]) -> Self {
        let velocity = problem
            .bodies
            .iter()
            .map(|b| Velocity::new(b.linear_velocity, b.angular_velocity))
            .collect();
        let mut state = Self {
            problem,
            lambda: vec![0.0; 2 * start.len()],
            velocity,
        };
        for (i, s) in start.iter().enumerate() {
            state.push(2 * i, s.tangent);
            state.push(2 * i + 1, s.normal);
        }
        state
    }

    /// Adds `y` to row `k`'s impulse (even rows friction, odd rows normal) and moves the
    /// bodies by it: B along the row's direction, A against it.
    fn push(&mut self, k: usize, y: Real) {
        let p = &self.problem.points[k / 2];
        let dir = if k % 2 == 0 { p.tangent() } else { p.normal };
        let imp = dir * y;
        let (a, b) = (p.body_a as usize, p.body_b as usize);
        let (ba, bb) = (&self.problem.bodies[a], &self.problem.bodies[b]);
        self.velocity[a].linear -= imp * ba.inv_mass;
        self.velocity[a].angular -= ba.inv_inertia * cross(&p.r_a, &imp);
        self.velocity[b].linear += imp * bb.inv_mass;
        self.velocity[b].angular += bb.inv_inertia * cross(&p.r_b, &imp);
        self.lambda[k] += y;
    }

    /// Gauss-Seidel on row `k`; the change is added to `d[k]`.
    fn relax(&mut self, k: usize, d: &mut [Real]) {
        let p = &self.problem.points[k / 2];
        let v = self
            .problem
            .relative_velocity_with(k / 2, &self.velocity)
            .expect("the problem's own point");
        let old = self.lambda[k];
        let new = if k % 2 == 0 {
            let bound = p.friction * self.lambda[k + 1].max(0.0);
            (old - p.tangent_mass * v.dot(&p.tangent())).clamp(-bound, bound)
        } else {
            (old - p.normal_mass * (v.dot(&p.normal) - p.velocity_bias)).max(0.0)
        };
        d[k] += new - old;
        self.push(k, new - old);
    }

    /// One iteration (a forward sweep, and a backward one if `symmetric`); `d` its changes.
    fn iterate(&mut self, symmetric: bool, d: &mut [Real]) {
        d.fill(0.0);
        for k in 0..self.lambda.len() {
            self.relax(k, d);
        }
        if symmetric {
            for i in (0..self.lambda.len() / 2).rev() {
                self.relax(2 * i + 1, d);
                self.relax(2 * i, d);
            }
        }
    }
}

/// Sweeps from `start` until an iteration changes no impulse by `TOLERANCE` or more (`cap`
/// iterations at most): `(sweeps, restarts)`, or `None` at the cap.
fn sweeps_to_tolerance(
    problem: &ContactProblem,
    start: &[Impulse],
    method: Method,
    symmetric: bool,
    cap: u32,
) -> Option<(u32, u32)> {
    let mut state = State::new(problem, start);
    let n = state.lambda.len();
    let (mut d, mut p) = (vec![0.0; n], vec![0.0; n]);
    let (mut previous, mut restarts) = (Real::INFINITY, 0);
    let per = if symmetric { 2 } else { 1 };
    for it in 1..=cap {
        state.iterate(symmetric, &mut d);
        if d.iter().all(|x| x.abs() < TOLERANCE) {
            return Some((per * it, restarts));
        }
        let norm: Real = d.iter().map(|x| x * x).sum();
        let beta = match method {
            Method::Plain => continue,
            Method::Nncg => norm / previous,
            Method::HeavyBall(b) if norm <= previous => b,
            Method::HeavyBall(_) => Real::INFINITY,
        };
        previous = norm;
        if beta > 1.0 {
            restarts += u32::from(it > 1);
            p.copy_from_slice(&d);
            continue;
        }
        for (k, (pk, dk)) in p.iter_mut().zip(&d).enumerate() {
            let step = beta * *pk;
            state.push(k, step);
            *pk = step + dk;
        }
    }
    None
}

/// Forward sweeps from `start` with a jump along the last change every `every` sweeps (see
/// the module docs; at most `most` times the change) until the stop rule holds: `(sweeps,
/// jumps, jumps undone)`, or `None` at the cap.
fn extrapolated_sweeps(
    problem: &ContactProblem,
    start: &[Impulse],
    every: usize,
    most: Real,
    cap: u32,
) -> Option<(u32, u32, u32)> {
    let mut state = State::new(problem, start);
    let n = state.lambda.len();
    let (mut d, mut last) = (vec![0.0; n], vec![0.0; n]);
    let (mut saved_lambda, mut saved_velocity) = (state.lambda.clone(), state.velocity.clone());
    let (mut jumps, mut undone) = (0, 0);
    let mut norms: Vec<Real> = Vec::with_capacity(every);
    let mut before_jump: Option<Real> = None;
    let norm = |v: &[Real]| v.iter().map(|x| x * x).sum::<Real>().sqrt();
    for it in 1..=cap {
        last.copy_from_slice(&d);
        state.iterate(false, &mut d);
        if d.iter().all(|x| x.abs() < TOLERANCE) {
            return Some((it, jumps, undone));
        }
        let now = norm(&d);
        if let Some(before) = before_jump.take()
            && now > before
        {
            state.lambda.copy_from_slice(&saved_lambda);
            state.velocity.copy_from_slice(&saved_velocity);
            undone += 1;
            norms.clear();
            continue;
        }
        norms.push(now);
        if norms.len() < every {
            continue;
        }
        let rho = (now / norms[0]).powf(1.0 / (every as Real - 1.0));
        let cosine = d.iter().zip(&last).map(|(a, b)| a * b).sum::<Real>() / (now * norm(&last));
        norms.clear();
        if rho < 1.0 && cosine > 0.95 {
            saved_lambda.copy_from_slice(&state.lambda);
            saved_velocity.copy_from_slice(&state.velocity);
            before_jump = Some(now);
            let factor = (rho / (1.0 - rho)).min(most);
            for (k, dk) in d.iter().enumerate() {
                state.push(k, factor * dk);
            }
            jumps += 1;
        }
    }
    None
}

/// The options: `--bodies` (1 000), `--seed` (100), `--steps` (160,200), `--cap` (40 000).
fn parse() -> Result<(usize, u64, Vec<u64>, u32), String> {
    let (mut bodies, mut seed, mut steps, mut cap) = (1000, 100, vec![160, 200], 40_000);
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let value = args.next().ok_or(format!("{flag} needs a value"))?;
        let bad = |what: &str| format!("{flag} {value}: {what}");
        match flag.as_str() {
            "--bodies" => bodies = value.parse().map_err(|_| bad("a count"))?,
            "--seed" => seed = value.parse().map_err(|_| bad("an integer"))?,
            "--steps" => {
                steps = value
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad("step numbers, comma-separated"))?
            }
            "--cap" => cap = value.parse().map_err(|_| bad("a count"))?,
            other => {
                return Err(format!(
                    "unknown flag {other} (--bodies, --seed, --steps, --cap)"
                ));
            }
        }
    }
    Ok((bodies, seed, steps, cap))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (bodies, seed, steps, cap) = parse()?;
    let islands = IslandRecorder::record_pile(seed, bodies, &steps)?;
    let methods = [
        ("gs", Method::Plain),
        ("nncg", Method::Nncg),
        ("hb 0.5", Method::HeavyBall(0.5)),
        ("hb 0.8", Method::HeavyBall(0.8)),
        ("hb 0.9", Method::HeavyBall(0.9)),
    ];
    println!(
        "pile of {bodies}, seed {seed}: sweeps/restarts to max |Δλ| < {TOLERANCE} (cap {cap})"
    );
    for (step, problem, carried) in &islands {
        print!("step {step}, {} points:", problem.len());
        for symmetric in [false, true] {
            for (name, method) in methods {
                let cell = sweeps_to_tolerance(problem, carried, method, symmetric, cap)
                    .map_or("cap".into(), |(s, r)| format!("{s}/{r}"));
                print!(" {}{name} {cell};", if symmetric { "sym " } else { "" });
            }
        }
        for (every, most) in [(10, 10.0), (20, 100.0), (50, 1000.0)] {
            let cell = extrapolated_sweeps(problem, carried, every, most, cap)
                .map_or("cap".into(), |(s, j, u)| format!("{s}/{j}/{u}"));
            print!(" extrapolate {every}/{most} {cell};");
        }
        println!();
    }
    Ok(())
}
