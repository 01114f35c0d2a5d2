//! What a sweep measures of its impulse changes, and the stop rule's verdict on it.

use deepcontact_core::math::Real;
use deepcontact_core::{SolveReport, SolverSettings};

use super::LANES;

/// The measures of one sweep's impulse changes.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Sweep {
    /// `max |Δλ|` over the rows.
    pub(crate) max: Real,
    /// `Σ Δλ²` over the rows.
    pub(crate) sum_sq: Real,
    /// The largest per-manifold `Δλn² + max(0, Δλt)²` (`Δλn` of one-point manifolds only),
    /// the square of [`ResidualNorm::Contact`](deepcontact_core::ResidualNorm::Contact).
    pub(crate) contact_sq: Real,
}

impl Sweep {
    /// Folds the lanes' measures in, lane by lane.
    #[inline]
    pub(crate) fn add_lanes(&mut self, lanes: &LaneSweep) {
        for lane in 0..LANES {
            self.max = self.max.max(lanes.max[lane]);
            self.sum_sq += lanes.sum_sq[lane];
            self.contact_sq = self.contact_sq.max(lanes.contact_sq[lane]);
        }
    }

    /// [`Self::add_lanes`] for an island that owns lanes `first..first + width` of `lanes`
    /// (the others being padding of its own batches, or other islands'). The same bits: a
    /// padding lane measures exactly +0, and folding a +0 into a sum of squares or a
    /// maximum of magnitudes (never NaN: `max` skips it) changes nothing.
    #[inline]
    pub(crate) fn add_span(&mut self, lanes: &LaneSweep, first: usize, width: usize) {
        for lane in first..first + width {
            self.max = self.max.max(lanes.max[lane]);
            self.sum_sq += lanes.sum_sq[lane];
            self.contact_sq = self.contact_sq.max(lanes.contact_sq[lane]);
        }
    }

    /// Folds in the measures of rows swept after this sweep's.
    #[inline]
    pub(crate) fn add(&mut self, other: &Sweep) {
        self.max = self.max.max(other.max);
        self.sum_sq += other.sum_sq;
        self.contact_sq = self.contact_sq.max(other.contact_sq);
    }
}

/// What the stop rule makes of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// Iterate again (if the cap allows).
    Continue,
    /// The stop rule holds.
    Converged,
    /// An impulse change is not finite.
    Diverged,
}

/// Judges iteration `it` (1-based) from its sweep's measures, recording its residuals in
/// `report` when one is given (threads that share a sweep all judge; one records).
#[inline]
pub(crate) fn judge(
    settings: &SolverSettings,
    it: u32,
    sweep: &Sweep,
    report: Option<&mut SolveReport>,
) -> Verdict {
    let (max_d, l2) = (sweep.max, sweep.sum_sq.sqrt());
    if let Some(report) = report {
        report.residual_inf.push(max_d);
        report.residual_l2.push(l2);
    }
    // `max` skips NaN, so a NaN change shows only in the sum of squares.
    if !(max_d.is_finite() && l2.is_finite()) {
        Verdict::Diverged
    } else if settings.converged(it, max_d, l2, sweep.contact_sq.sqrt()) {
        Verdict::Converged
    } else {
        Verdict::Continue
    }
}

/// [`Sweep`] per lane of [`sweep_batch`](super::sweep_batch), as structure of arrays (one register per measure).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LaneSweep {
    pub(super) max: [Real; LANES],
    pub(super) sum_sq: [Real; LANES],
    pub(super) contact_sq: [Real; LANES],
}
