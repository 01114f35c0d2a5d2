//! What a solve of this crate's solvers weighs in PGS passes, for pass budgets
//! ([`deepcontact_core::VelocitySolver::pass_cost`]).
//!
//! A budget counts passes (sweeps of every row of an island with deepcontact-pgs); a Newton
//! iteration or a PSOR sweep on the assembled `W` is other work, and so is the assembly. Each
//! is counted from the island's structure alone (points, entries of `W`, blocks and block
//! updates of the Newton matrix's factors), so that a budget decides the same way on every
//! machine and for every start, with times per unit of structure fitted by least squares on
//! islands of the suite's piles, the 20-row pyramid and the 20-box stack
//! (`cargo run --release -p deepcontact-benches --example pass_weights`, which prints the
//! measured and the counted weights island by island; 2-vCPU AMD EPYC family 25 model 17,
//! 2026-12-07), each time the slope between two iteration counts:
//!
//! | work | ns |
//! |---|---|
//! | a PGS pass | 4.8 a point of a single-point manifold (swept in lanes), 21.5 a point of a two-point one (the block solver) |
//! | a Newton iteration | 0.94 a block update of the factorisation, 11.6 a block of the factors (the triangular solves, the accuracy check), 0.1 an entry of `W`, 30 a point (classification, line search) |
//! | a Newton solve's set-up | 5.0 an entry of `W`, 16.8 a block of the factors, 87 a point (the analysis kept while the contact graph holds) |
//! | a PSOR sweep | 0.87 an entry of `W`, 0.31 a point |
//! | a PSOR solve's set-up | 3.87 an entry of `W`, 126 a point |
//!
//! Counted this way, on 59 islands of 8 to 1 634 points of those scenes, a Newton iteration
//! weighs 6 to 72 passes and its set-up 24 to 228, a PSOR sweep 2 to 34 and its set-up 15 to
//! 175. The count is within a factor of two of the measured ratio on 42 of the 59 Newton
//! iterations and on every PSOR sweep; the others are iterations that factorise again after a
//! failed line search (measured up to 3.6 × the count, on the 20-box stack 19–24 passes
//! against 6 counted) and islands under 15 points (counted up to 3 × the measured). A ratio of
//! times, the weight moves less between machines than the times do.

use deepcontact_core::{ContactProblem, PassCost, Real};

use crate::AssemblyMode;

/// A PGS pass over an island of `points` points, `paired` of them in two-point manifolds, ns.
fn pass_ns(points: usize, paired: usize) -> Real {
    let single = points - paired.min(points);
    4.8 * single as Real + 21.5 * paired as Real
}

/// A set-up of `set_up` ns and iterations of `iteration` ns in passes of `pass` ns, each
/// rounded up (an empty island: nothing to set up, one pass an iteration).
fn weigh(pass: Real, set_up: Real, iteration: Real) -> PassCost {
    if pass <= 0.0 {
        return PassCost::ONE_PER_ITERATION;
    }
    let passes = |ns: Real| (ns / pass).ceil().min(u32::MAX as Real) as u32;
    PassCost {
        set_up: passes(set_up),
        per_iteration: passes(iteration).max(1),
    }
}

/// The size of one Newton iteration on a problem, counted from its structure alone (the same
/// on every machine and for every start; [`crate::NewtonSolver::work`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NewtonWork {
    /// Contact points (2 rows each).
    pub points: usize,
    /// Of those, the points of two-point manifolds (PGS solves their normals as a block).
    pub paired_points: usize,
    /// Stored entries of `W` (rows² when assembled dense): one product `W x` reads each once.
    pub w_entries: usize,
    /// 2 × 2 blocks of the factors' filled pattern: a triangular solve visits each once.
    pub filled_blocks: usize,
    /// 2 × 2 block updates of one factorisation.
    pub updates: usize,
}

impl NewtonWork {
    /// What a Newton solve weighs in PGS passes of the same island (the module's weights).
    pub fn pass_cost(&self) -> PassCost {
        let (w, filled) = (self.w_entries as Real, self.filled_blocks as Real);
        let points = self.points as Real;
        weigh(
            pass_ns(self.points, self.paired_points),
            5.0 * w + 16.8 * filled + 87.0 * points,
            0.94 * self.updates as Real + 11.6 * filled + 0.1 * w + 30.0 * points,
        )
    }
}

/// The size of one PSOR sweep on a problem, counted from its structure alone
/// ([`crate::PsorSolver::work`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PsorWork {
    /// Contact points (2 rows each).
    pub points: usize,
    /// Of those, the points of two-point manifolds.
    pub paired_points: usize,
    /// Stored entries of `W` (rows² when assembled dense): a sweep reads each once.
    pub w_entries: usize,
}

impl PsorWork {
    /// What a PSOR solve weighs in PGS passes of the same island (the module's weights).
    pub fn pass_cost(&self) -> PassCost {
        let (w, points) = (self.w_entries as Real, self.points as Real);
        weigh(
            pass_ns(self.points, self.paired_points),
            3.87 * w + 126.0 * points,
            0.87 * w + 0.31 * points,
        )
    }
}

/// Points of `manifolds` that belong to two-point manifolds.
fn paired_points(manifolds: &[(u32, u32)]) -> usize {
    manifolds.iter().filter(|&&(s, e)| e - s == 2).count() * 2
}

/// The structure every weight starts from: `problem`'s points, its two-point manifolds' points,
/// and the entries of `W` as `mode` would store them (`rows²` dense, 4 a block of the
/// pattern's `blocks` sparse).
pub(crate) fn island_size(
    problem: &ContactProblem,
    mode: AssemblyMode,
    dense_threshold: usize,
    blocks: usize,
) -> (usize, usize, usize) {
    let points = problem.points.len();
    let rows = 2 * points;
    let w_entries = if mode.is_dense_for(rows, dense_threshold) {
        rows * rows
    } else {
        4 * blocks
    };
    (points, paired_points(&problem.manifolds), w_entries)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An island about the size of a 130-point one of the circle pile: an iteration weighs tens
    /// of passes, its set-up more, and box faces, whose PGS pass costs more, weigh less.
    #[test]
    fn a_newton_iteration_weighs_tens_of_passes_and_less_on_box_faces() {
        let circles = NewtonWork {
            points: 130,
            paired_points: 0,
            w_entries: 2544,
            filled_blocks: 900,
            updates: 1500,
        };
        let cost = circles.pass_cost();
        assert!((15..=40).contains(&cost.per_iteration), "{cost:?}");
        assert!(cost.set_up > cost.per_iteration, "{cost:?}");
        let boxes = NewtonWork {
            paired_points: 130,
            ..circles
        };
        assert!(boxes.pass_cost().per_iteration < cost.per_iteration);
    }

    #[test]
    fn an_empty_island_weighs_one_pass_an_iteration() {
        assert_eq!(
            NewtonWork::default().pass_cost(),
            PassCost::ONE_PER_ITERATION
        );
        assert_eq!(PsorWork::default().pass_cost(), PassCost::ONE_PER_ITERATION);
    }

    #[test]
    fn a_psor_sweep_weighs_more_than_a_pass_on_a_dense_island() {
        let cost = PsorWork {
            points: 40,
            paired_points: 40,
            w_entries: 6400,
        }
        .pass_cost();
        assert!(cost.per_iteration >= 5, "{cost:?}");
        assert!(cost.set_up >= 20, "{cost:?}");
    }
}
