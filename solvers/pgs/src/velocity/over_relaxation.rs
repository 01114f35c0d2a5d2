//! An over-relaxation schedule inside the solve: the first sweeps over-relaxed, the last plain.
//!
//! Scaling a row's effective mass by ω is the over-relaxed Gauss-Seidel update
//! `λ ← proj(λ − ω m (v − b))`, which moves the slow, load-redistributing modes of a pile
//! `O(√μ)` a sweep where Gauss-Seidel moves them `O(μ)` (the `sor` provider's derivation). Under
//! a fixed budget of passes the best use of them is a large factor first and one near 1 last
//! (docs/RESEARCH.md); a provider that sweeps so before the world's solve pays for a second
//! solve of the island (its plan, its set-up, its end), which at 4 to 8 passes costs more than
//! the sweeps. Here the schedule runs inside the world's solve: between shares only the
//! single-point manifolds' effective masses change (rows and batches), the velocities and
//! impulses carry on. Box faces (two-point manifolds) keep theirs: their normals go through the
//! block solver, which the scaling would not reach.

use deepcontact_core::{ContactProblem, SolveReport, SolverSettings};

use super::measures::Verdict;
use super::{Batch, LANES, PgsSolver, Real};
use crate::PgsError;

/// Over-relaxation factors for equal shares of the first `max_iterations − 1` sweeps of a solve
/// (`pgs:sor=1.8/1.7/1.3`): in share `j` the single-point manifolds' effective masses are
/// scaled by factor `j`; the last sweep, and every sweep after a share that met the stop rule,
/// is plain Gauss-Seidel on the island as given. Small islands packed into shared batches
/// ([`VelocitySolver::solve_many`](deepcontact_core::VelocitySolver::solve_many)) are scaled
/// together at the same sweeps, each ending with the bits of its own scheduled solve: on the
/// piles the small islands' residual counts too. Meant for a fixed budget of passes, where
/// `max_iterations` is the budget; with a cap of hundreds the shares are hundreds of sweeps long.
///
/// ```
/// use deepcontact_pgs::OverRelaxation;
///
/// let schedule = OverRelaxation::new(&[1.8, 1.4]).unwrap();
/// // A budget of 8 passes: 7 relaxed sweeps in two shares, then one plain.
/// assert_eq!(schedule.shares(7).collect::<Vec<_>>(), [(1.8, 3), (1.4, 4)]);
/// assert!(OverRelaxation::new(&[2.0]).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverRelaxation {
    factors: [Real; OverRelaxation::MAX],
    len: usize,
}

impl OverRelaxation {
    /// The most factors a schedule holds.
    pub const MAX: usize = 8;

    /// No over-relaxation (the default): every sweep plain.
    pub const NONE: Self = Self {
        factors: [1.0; Self::MAX],
        len: 0,
    };

    /// The schedule of `factors` (at most [`Self::MAX`], each in [1, 2)).
    ///
    /// # Errors
    /// [`PgsError::OverRelaxation`] for more than [`Self::MAX`] factors or one outside [1, 2).
    pub fn new(factors: &[Real]) -> Result<Self, PgsError> {
        if factors.len() > Self::MAX {
            return Err(PgsError::OverRelaxation(format!(
                "{} factors, at most {}",
                factors.len(),
                Self::MAX
            )));
        }
        if let Some(f) = factors.iter().find(|f| !(1.0..2.0).contains(*f)) {
            return Err(PgsError::OverRelaxation(format!(
                "factor {f} is not in [1, 2)"
            )));
        }
        let mut schedule = Self::NONE;
        schedule.factors[..factors.len()].copy_from_slice(factors);
        schedule.len = factors.len();
        Ok(schedule)
    }

    /// Parses `a/b/c` (factors separated by `/`).
    ///
    /// # Errors
    /// [`PgsError::OverRelaxation`] for a factor that is not a number, and as [`Self::new`].
    pub fn parse(text: &str) -> Result<Self, PgsError> {
        let factors = text
            .split('/')
            .map(|f| {
                f.trim().parse::<Real>().map_err(|e| {
                    PgsError::OverRelaxation(format!("factors separated by '/': `{f}`: {e}"))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Self::new(&factors)
    }

    /// The factors, in order.
    pub fn factors(&self) -> &[Real] {
        &self.factors[..self.len]
    }

    /// Whether the schedule is empty ([`Self::NONE`]).
    pub fn is_none(&self) -> bool {
        self.len == 0
    }

    /// Each factor with its share of `sweeps`: factor `j` of `n` runs sweeps
    /// `⌊sweeps·j/n⌋ .. ⌊sweeps·(j+1)/n⌋`; a factor whose share is empty is skipped.
    pub fn shares(&self, sweeps: u32) -> impl Iterator<Item = (Real, u32)> + '_ {
        let n = self.len.max(1) as u64;
        let edge = move |j: u64| (u64::from(sweeps) * j / n) as u32;
        self.factors()
            .iter()
            .enumerate()
            .map(move |(j, &f)| (f, edge(j as u64 + 1) - edge(j as u64)))
            .filter(|&(_, share)| share > 0)
    }
}

impl Default for OverRelaxation {
    fn default() -> Self {
        Self::NONE
    }
}

impl PgsSolver {
    /// Stage 3 under the settings' [`OverRelaxation`]: its shares of `max_iterations − 1`
    /// sweeps over-relaxed, then plain sweeps for the rest, until the stop rule holds; the
    /// plain [`Self::run`] without a schedule or with a cap of one sweep. Returns the
    /// iterations run and the last verdict; the rows' effective masses are the island's again
    /// at the end.
    pub(crate) fn run_scheduled(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> (u32, Verdict) {
        let schedule = self.settings.over_relaxation;
        let points = problem.points.len();
        if schedule.is_none() || settings.max_iterations < 2 {
            return self.run(points, settings, report);
        }
        // One solve: the stop rule's least iterations count from its first sweep, not a share's.
        let stage = |iterations, done: u32| SolverSettings {
            max_iterations: iterations,
            min_iterations: settings.min_iterations.saturating_sub(done).max(1),
            ..*settings
        };
        self.save_batch_masses();
        let (mut it, mut verdict) = (0, Verdict::Continue);
        for (omega, share) in schedule.shares(settings.max_iterations - 1) {
            self.scale_single_points(problem, omega);
            let (i, v) = self.run(points, &stage(share, it), report);
            (it, verdict) = (it + i, v);
            if verdict != Verdict::Continue {
                break;
            }
        }
        self.scale_single_points(problem, 1.0);
        if verdict == Verdict::Continue {
            let (i, v) = self.run(points, &stage(settings.max_iterations - it, it), report);
            (it, verdict) = (it + i, v);
        }
        (it, verdict)
    }

    /// Sets the single-point manifolds' effective masses, where the sweep reads them, to
    /// `problem`'s times `omega` (1: the island's own, bit for bit). The plain and chunked plans
    /// read a batched manifold's from its batch lanes, scaled from the copy
    /// [`Self::save_batch_masses`] took, and the rest from the rows; the domain plan and a
    /// plan without batches read every row.
    fn scale_single_points(&mut self, problem: &ContactProblem, omega: Real) {
        let points = problem.points.len();
        let rows_only = self.segments.is_empty()
            || (self.plans_domains(points) && self.settings.precision == crate::Precision::F64);
        let scale = |rows: &mut [super::Row], m: &super::Manifold| {
            let (r, p) = (
                &mut rows[m.start as usize],
                &problem.points[m.start as usize],
            );
            r.normal_mass = p.normal_mass * omega;
            r.tangent_mass = p.tangent_mass * omega;
        };
        if rows_only {
            for m in self.manifolds.iter().filter(|m| m.count == 1) {
                scale(&mut self.rows, m);
            }
            return;
        }
        // The serial remainder's single-point manifolds (the overflow colour's).
        for m in self.scratch.iter().filter(|m| m.count == 1) {
            scale(&mut self.rows, m);
        }
        scale_lanes(&mut self.batches, &self.batch_masses, omega);
    }

    /// Keeps the batches' lanes' effective masses (the island's own, or a pack's) for
    /// [`Self::scale_single_points`] and [`scale_lanes`].
    pub(crate) fn save_batch_masses(&mut self) {
        self.batch_masses.clear();
        self.batch_masses.extend(self.batches.iter().map(|b| {
            let mut base = [0.0; 2 * LANES];
            base[..LANES].copy_from_slice(&b.normal_mass);
            base[LANES..].copy_from_slice(&b.tangent_mass);
            base
        }));
    }
}

/// Sets every lane's effective masses of `batches` to `masses` (per batch, its lanes' normal
/// masses then their tangent masses, as [`PgsSolver::save_batch_masses`] keeps them) times
/// `omega`. A batch holds single-point manifolds only; padding lanes' masses are zero and stay
/// zero; `omega` = 1 gives the saved masses bit for bit.
pub(crate) fn scale_lanes(batches: &mut [Batch], masses: &[[Real; 2 * LANES]], omega: Real) {
    for (batch, base) in batches.iter_mut().zip(masses) {
        for lane in 0..LANES {
            batch.normal_mass[lane] = base[lane] * omega;
            batch.tangent_mass[lane] = base[LANES + lane] * omega;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PgsSettings, Precision};
    use deepcontact_core::{Impulse, Velocity, VelocitySolver, scene};

    use super::super::test_support::{islands, solution_bits};

    /// The bits of a solve of `problem` from zero impulses at `cap` sweeps, `tolerance` and
    /// `least` iterations at least:
    /// impulses, velocities, iterations, natural residual.
    fn solved(
        settings: PgsSettings,
        problem: &ContactProblem,
        cap: u32,
        tolerance: Real,
        least: u32,
    ) -> (Vec<u64>, SolveReport) {
        let stop = SolverSettings {
            max_iterations: cap,
            min_iterations: least,
            tolerance,
            ..SolverSettings::default()
        };
        let mut impulses = vec![Impulse::ZERO; problem.len()];
        let mut velocities = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        let mut solver = PgsSolver::with_settings(settings);
        solver
            .solve(problem, &stop, &mut impulses, &mut velocities, &mut report)
            .unwrap();
        // The rows hold the island's own effective masses again.
        for (r, p) in solver.rows.iter().zip(&problem.points) {
            assert_eq!(r.normal_mass.to_bits(), p.normal_mass.to_bits());
            assert_eq!(r.tangent_mass.to_bits(), p.tangent_mass.to_bits());
        }
        let mut bits = solution_bits(&impulses, &velocities);
        bits.extend([
            u64::from(report.iterations),
            report.natural_residual.to_bits(),
        ]);
        (bits, report)
    }

    fn with(settings: PgsSettings, factors: &[Real]) -> PgsSettings {
        PgsSettings {
            over_relaxation: OverRelaxation::new(factors).unwrap(),
            ..settings
        }
    }

    #[test]
    fn a_schedule_of_ones_gives_the_bits_of_plain_sweeps() {
        let circles = islands(scene::pile(12345, 100).unwrap(), 130).remove(0);
        let boxes = islands(
            scene::box_pile(12345, &scene::ShapePileParams::default()).unwrap(),
            150,
        )
        .remove(0);
        let chunked = PgsSettings {
            parallel_min_points: 1,
            ..PgsSettings::default()
        };
        let f32 = PgsSettings {
            precision: Precision::F32,
            ..PgsSettings::default()
        };
        for settings in [PgsSettings::default(), f32, chunked] {
            for problem in [&circles, &boxes] {
                // Eight sweeps in three shares and a plain one; a stop inside a share; a stop
                // whose least iterations (20) span shares of 13.
                for (cap, tolerance, least) in [(8, 0.0, 1), (200, 1e-2, 1), (40, 1e3, 20)] {
                    let (plain, report) = solved(settings, problem, cap, tolerance, least);
                    let (ones, _) = solved(
                        with(settings, &[1.0, 1.0, 1.0]),
                        problem,
                        cap,
                        tolerance,
                        least,
                    );
                    assert_eq!(ones, plain, "cap {cap}");
                    let it = report.iterations;
                    if cap == 200 {
                        // 199 sweeps in shares of 66, 66 and 67, then the plain one.
                        assert!(report.converged && it < 199, "stopped in a share: {it}");
                    }
                    if least > 1 {
                        assert!(report.converged && it == least, "{it} iterations");
                    }
                }
            }
        }
    }

    #[test]
    fn an_over_relaxed_schedule_ends_a_pile_nearer_a_solution_in_eight_passes() {
        let problem = islands(scene::pile(12345, 100).unwrap(), 200).remove(0);
        assert!(problem.len() > 100, "the settled pile's island");
        let (_, plain) = solved(PgsSettings::default(), &problem, 8, 0.0, 1);
        let (_, relaxed) = solved(
            with(PgsSettings::default(), &[1.8, 1.4]),
            &problem,
            8,
            0.0,
            1,
        );
        assert_eq!(relaxed.iterations, 8, "the budget, no more");
        assert!(
            relaxed.natural_residual < 0.8 * plain.natural_residual,
            "{} against {}",
            relaxed.natural_residual,
            plain.natural_residual
        );
    }

    #[test]
    fn factors_outside_one_to_two_are_a_typed_error() {
        for factors in [&[2.0][..], &[0.9], &[1.5, f64::NAN], &[1.1; 9]] {
            assert!(
                matches!(
                    OverRelaxation::new(factors),
                    Err(PgsError::OverRelaxation(_))
                ),
                "{factors:?}"
            );
        }
        let schedule = OverRelaxation::new(&[1.8, 1.6, 1.2]).unwrap();
        assert_eq!(schedule.factors(), [1.8, 1.6, 1.2]);
        // Fewer sweeps than factors: the empty shares are skipped.
        assert_eq!(schedule.shares(2).collect::<Vec<_>>(), [(1.6, 1), (1.2, 1)]);
        assert!(OverRelaxation::default().is_none());
    }
}
