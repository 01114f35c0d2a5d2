//! The sequential-impulse velocity solver.

use std::time::Instant;

use deepcontact_core::math::{Real, Vector, cross};
use deepcontact_core::{ContactProblem, CoreError, Impulse, SolveReport, SolverSettings, VelocitySolver};

use crate::PgsError;

/// Options of the PGS solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PgsSettings {
    /// Solve the two normal rows of a 2-point manifold together, as Box2D's block solver
    /// (default true; only polygon manifolds have two points).
    pub block_solver: bool,
    /// Validate the problem before solving (default true; costs one pass over the data).
    pub validate: bool,
}

impl Default for PgsSettings {
    fn default() -> Self {
        Self { block_solver: true, validate: true }
    }
}

/// One contact point laid out for the solver loop: everything the two rows need, with
/// the cross products precomputed (`rn = r × n`, `rt = r × t`).
#[derive(Debug, Clone, Copy, Default)]
struct Row {
    a: u32,
    b: u32,
    nx: Real,
    ny: Real,
    rna: Real,
    rnb: Real,
    rta: Real,
    rtb: Real,
    normal_mass: Real,
    tangent_mass: Real,
    friction: Real,
    bias: Real,
    ln: Real,
    lt: Real,
}

/// Block-solver data of a 2-point manifold: `K` and its inverse.
#[derive(Debug, Clone, Copy, Default)]
struct Block {
    k11: Real,
    k12: Real,
    k22: Real,
    i11: Real,
    i12: Real,
    i22: Real,
    /// Whether K is well conditioned enough for the block solver.
    usable: bool,
}

/// Body velocity and inverse mass, packed for the loop.
#[derive(Debug, Clone, Copy, Default)]
struct Vel {
    vx: Real,
    vy: Real,
    w: Real,
    im: Real,
    ii: Real,
}

/// Projected Gauss-Seidel on sequential impulses (Box2D v2.4's `b2ContactSolver`).
#[derive(Debug, Clone, Default)]
pub struct PgsSolver {
    /// Options.
    pub settings: PgsSettings,
    rows: Vec<Row>,
    manifolds: Vec<(u32, u32)>,
    blocks: Vec<Block>,
    vel: Vec<Vel>,
}

impl PgsSolver {
    /// A solver with default options.
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options.
    pub fn with_settings(settings: PgsSettings) -> Self {
        Self { settings, ..Self::default() }
    }

    /// Stage 1, prepare: copy the problem into rows and packed velocities.
    fn prepare(&mut self, problem: &ContactProblem, start: &[Impulse]) {
        self.vel.clear();
        self.vel.extend(problem.bodies.iter().map(|b| Vel {
            vx: b.linear_velocity.x,
            vy: b.linear_velocity.y,
            w: b.angular_velocity,
            im: b.inv_mass,
            ii: b.inv_inertia,
        }));
        self.rows.clear();
        self.rows.extend(problem.points.iter().zip(start).map(|(p, s)| {
            let t = p.tangent();
            Row {
                a: p.body_a,
                b: p.body_b,
                nx: p.normal.x,
                ny: p.normal.y,
                rna: cross(&p.r_a, &p.normal),
                rnb: cross(&p.r_b, &p.normal),
                rta: cross(&p.r_a, &t),
                rtb: cross(&p.r_b, &t),
                normal_mass: p.normal_mass,
                tangent_mass: p.tangent_mass,
                friction: p.friction,
                bias: p.velocity_bias,
                ln: s.normal,
                lt: s.tangent,
            }
        }));
        self.manifolds.clear();
        self.manifolds.extend_from_slice(&problem.manifolds);
        self.blocks.clear();
        for &(s, e) in &problem.manifolds {
            let mut block = Block::default();
            if self.settings.block_solver && e - s == 2 {
                let (r1, r2) = (&self.rows[s as usize], &self.rows[s as usize + 1]);
                let (va, vb) = (&self.vel[r1.a as usize], &self.vel[r1.b as usize]);
                let (ma, mb, ia, ib) = (va.im, vb.im, va.ii, vb.ii);
                block.k11 = ma + mb + ia * r1.rna * r1.rna + ib * r1.rnb * r1.rnb;
                block.k22 = ma + mb + ia * r2.rna * r2.rna + ib * r2.rnb * r2.rnb;
                block.k12 = ma + mb + ia * r1.rna * r2.rna + ib * r1.rnb * r2.rnb;
                let det = block.k11 * block.k22 - block.k12 * block.k12;
                // Box2D's condition-number guard: k11² < 1000 det.
                if block.k11 * block.k11 < 1000.0 * det && det > 0.0 {
                    let inv = 1.0 / det;
                    block.i11 = block.k22 * inv;
                    block.i22 = block.k11 * inv;
                    block.i12 = -block.k12 * inv;
                    block.usable = true;
                }
            }
            self.blocks.push(block);
        }
    }

    /// Stage 2, warm start: apply the start impulses to the velocities.
    fn warm_start(&mut self) {
        for r in &self.rows {
            let (px, py) = (r.ln * r.nx - r.lt * r.ny, r.ln * r.ny + r.lt * r.nx);
            let va = &mut self.vel[r.a as usize];
            va.vx -= va.im * px;
            va.vy -= va.im * py;
            va.w -= va.ii * (r.ln * r.rna + r.lt * r.rta);
            let vb = &mut self.vel[r.b as usize];
            vb.vx += vb.im * px;
            vb.vy += vb.im * py;
            vb.w += vb.ii * (r.ln * r.rnb + r.lt * r.rtb);
        }
    }

    /// Stage 3, one Gauss-Seidel sweep. Returns `(max |Δλ|, Σ Δλ²)`.
    fn iterate(&mut self) -> (Real, Real) {
        let mut max_d: Real = 0.0;
        let mut sum_sq: Real = 0.0;
        let vel = &mut self.vel;
        let rows = &mut self.rows;
        for (m, &(s, e)) in self.manifolds.iter().enumerate() {
            let (s, e) = (s as usize, e as usize);
            // Friction rows first (their bound uses the current normal impulse).
            for r in &mut rows[s..e] {
                let (va, vb) = (vel[r.a as usize], vel[r.b as usize]);
                // t = (-ny, nx)
                let vt = (vb.vx - va.vx) * -r.ny + (vb.vy - va.vy) * r.nx + vb.w * r.rtb - va.w * r.rta;
                let bound = r.friction * r.ln;
                let new = (r.lt - r.tangent_mass * vt).clamp(-bound, bound);
                let d = new - r.lt;
                r.lt = new;
                apply(vel, r, 0.0, d);
                max_d = max_d.max(d.abs());
                sum_sq += d * d;
            }
            let block = &self.blocks[m];
            if block.usable {
                let (d1, d2) = solve_block(vel, &mut rows[s..e], block);
                max_d = max_d.max(d1.abs()).max(d2.abs());
                sum_sq += d1 * d1 + d2 * d2;
            } else {
                for r in &mut rows[s..e] {
                    let (va, vb) = (vel[r.a as usize], vel[r.b as usize]);
                    let vn = (vb.vx - va.vx) * r.nx + (vb.vy - va.vy) * r.ny + vb.w * r.rnb - va.w * r.rna;
                    let new = (r.ln - r.normal_mass * (vn - r.bias)).max(0.0);
                    let d = new - r.ln;
                    r.ln = new;
                    apply(vel, r, d, 0.0);
                    max_d = max_d.max(d.abs());
                    sum_sq += d * d;
                }
            }
        }
        (max_d, sum_sq)
    }

    /// Friction rows were clamped against the normal impulse of the previous sweep; a
    /// last projection onto the final cone `|λt| ≤ μ λn` (its change applied to the
    /// velocities, so both stay consistent) makes the returned impulses admissible even
    /// when the cap was hit. The change is at most μ × the last normal change.
    fn project_friction(&mut self) {
        for r in &mut self.rows {
            let bound = r.friction * r.ln;
            let new = r.lt.clamp(-bound, bound);
            if new != r.lt {
                let d = new - r.lt;
                r.lt = new;
                apply(&mut self.vel, r, 0.0, d);
            }
        }
    }

    /// Natural-map residual of the current impulses and velocities, in impulse units.
    fn natural_residual(&self) -> Real {
        let mut res: Real = 0.0;
        for r in &self.rows {
            let (va, vb) = (&self.vel[r.a as usize], &self.vel[r.b as usize]);
            let vn = (vb.vx - va.vx) * r.nx + (vb.vy - va.vy) * r.ny + vb.w * r.rnb - va.w * r.rna;
            let vt = (vb.vx - va.vx) * -r.ny + (vb.vy - va.vy) * r.nx + vb.w * r.rtb - va.w * r.rta;
            let rn = r.ln - (r.ln - r.normal_mass * (vn - r.bias)).max(0.0);
            let bound = r.friction * r.ln;
            let rt = r.lt - (r.lt - r.tangent_mass * vt).clamp(-bound, bound);
            res = res.max(rn.abs()).max(rt.abs());
        }
        res
    }
}

/// Applies the impulse change `(dn, dt)` of row `r` to its two bodies.
#[inline(always)]
fn apply(vel: &mut [Vel], r: &Row, dn: Real, dt: Real) {
    let (px, py) = (dn * r.nx - dt * r.ny, dn * r.ny + dt * r.nx);
    let va = &mut vel[r.a as usize];
    va.vx -= va.im * px;
    va.vy -= va.im * py;
    va.w -= va.ii * (dn * r.rna + dt * r.rta);
    let vb = &mut vel[r.b as usize];
    vb.vx += vb.im * px;
    vb.vy += vb.im * py;
    vb.w += vb.ii * (dn * r.rnb + dt * r.rtb);
}

/// Box2D v2.4's 2-point block solver for the normal rows: solve the mixed LCP
/// `vn = A x + b, x ≥ 0, vn ≥ 0, x·vn = 0` on the incremental impulses by enumerating
/// the four cases (both active, only 1, only 2, none). Returns the two Δλn.
fn solve_block(vel: &mut [Vel], rows: &mut [Row], k: &Block) -> (Real, Real) {
    let (r1, r2) = (rows[0], rows[1]);
    let vn_of = |vel: &[Vel], r: &Row| {
        let (va, vb) = (&vel[r.a as usize], &vel[r.b as usize]);
        (vb.vx - va.vx) * r.nx + (vb.vy - va.vy) * r.ny + vb.w * r.rnb - va.w * r.rna
    };
    let (a1, a2) = (r1.ln, r2.ln);
    // b = vn - bias - K a
    let b1 = vn_of(vel, &r1) - r1.bias - (k.k11 * a1 + k.k12 * a2);
    let b2 = vn_of(vel, &r2) - r2.bias - (k.k12 * a1 + k.k22 * a2);
    let candidates = [
        // Case 1: both points active, x = -K⁻¹ b.
        (-(k.i11 * b1 + k.i12 * b2), -(k.i12 * b1 + k.i22 * b2)),
        // Case 2: only the first.
        (-r1.normal_mass * b1, 0.0),
        // Case 3: only the second.
        (0.0, -r2.normal_mass * b2),
        // Case 4: none.
        (0.0, 0.0),
    ];
    let mut x = (a1.max(0.0), a2.max(0.0));
    for (case, &(x1, x2)) in candidates.iter().enumerate() {
        let vn1 = k.k11 * x1 + k.k12 * x2 + b1;
        let vn2 = k.k12 * x1 + k.k22 * x2 + b2;
        let ok = match case {
            0 => x1 >= 0.0 && x2 >= 0.0,
            1 => x1 >= 0.0 && vn2 >= 0.0,
            2 => x2 >= 0.0 && vn1 >= 0.0,
            _ => b1 >= 0.0 && b2 >= 0.0,
        };
        if ok {
            x = (x1, x2);
            break;
        }
    }
    let (d1, d2) = (x.0 - a1, x.1 - a2);
    rows[0].ln = x.0;
    rows[1].ln = x.1;
    apply(vel, &r1, d1, 0.0);
    apply(vel, &r2, d2, 0.0);
    (d1, d2)
}

impl VelocitySolver for PgsSolver {
    fn name(&self) -> &str {
        "pgs"
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [(Vector, Real)],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let t0 = Instant::now();
        report.clear();
        settings.validate()?;
        if self.settings.validate {
            problem.validate()?;
        }
        if impulses.len() != problem.points.len() {
            return Err(CoreError::LengthMismatch { what: "impulses", expected: problem.points.len(), got: impulses.len() });
        }
        if velocities.len() != problem.bodies.len() {
            return Err(CoreError::LengthMismatch {
                what: "velocities",
                expected: problem.bodies.len(),
                got: velocities.len(),
            });
        }
        self.prepare(problem, impulses);
        self.warm_start();
        let mut it = 0;
        while it < settings.max_iterations {
            let (max_d, sum_sq) = self.iterate();
            it += 1;
            let l2 = sum_sq.sqrt();
            report.residual_inf.push(max_d);
            report.residual_l2.push(l2);
            if !max_d.is_finite() {
                let point = self.rows.iter().position(|r| !(r.ln.is_finite() && r.lt.is_finite())).unwrap_or(0);
                return Err(PgsError::Diverged { point, iteration: it }.into());
            }
            if settings.converged(it, max_d, l2) {
                report.converged = true;
                break;
            }
        }
        report.iterations = it;
        self.project_friction();
        // Stage 4, store impulses and velocities.
        for (imp, r) in impulses.iter_mut().zip(&self.rows) {
            *imp = Impulse::new(r.ln, r.lt);
        }
        for (out, v) in velocities.iter_mut().zip(&self.vel) {
            *out = (Vector::new(v.vx, v.vy), v.w);
        }
        report.natural_residual = self.natural_residual();
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }
}
