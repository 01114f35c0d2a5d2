//! A relaxation schedule of the `sor` provider: one factor ω for each equal share of its sweeps.
//!
//! A constant ω trades two errors: the slow, load-redistributing modes shrink faster the larger
//! ω is, while the fast ones that over-relaxation overshoots are left for the sweeps after. Under
//! a small pass budget the order matters: a large ω first moves the slow modes, a factor near 1
//! last settles what it overshot before the world's own pass. A schedule states that order as data
//! (`sor:schedule=1.8/1.5/1.1`); `models/train/schedule.py` fits one per budget.

use deepcontact_core::{Real, SpecError};
use deepcontact_pgs::OverRelaxation;

/// Factors for equal shares of the over-relaxed sweeps, in sweep order (empty: the provider's
/// constant ω or its policy's factors).
///
/// ```
/// use deepcontact_warmstart::Schedule;
///
/// let s = Schedule::parse("sor", "1.8/1.2").unwrap();
/// assert_eq!(s.factors(), &[1.8, 1.2]);
/// // Seven sweeps in two shares: three at 1.8, then four at 1.2.
/// assert_eq!(s.shares(7).collect::<Vec<_>>(), vec![(1.8, 3), (1.2, 4)]);
/// assert!(Schedule::parse("sor", "1.8/2.5").is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Schedule {
    /// The factors, as the solver's own schedule holds them (the same shares).
    factors: OverRelaxation,
}

impl Schedule {
    /// Most factors of a schedule.
    pub const MAX: usize = OverRelaxation::MAX;

    /// No schedule.
    pub const NONE: Self = Self {
        factors: OverRelaxation::NONE,
    };

    /// The schedule of `factors` (at most [`Self::MAX`], each in [1, 2); `spec` names the
    /// provider in the error).
    pub fn new(spec: &str, factors: &[Real]) -> Result<Self, SpecError> {
        let invalid = |reason: String| SpecError::InvalidParameter {
            spec: spec.into(),
            param: "schedule".into(),
            value: factors
                .iter()
                .map(|f| f.to_string())
                .collect::<Vec<_>>()
                .join("/"),
            reason,
        };
        if factors.is_empty() {
            return Err(invalid(format!("must hold 1 to {} factors", Self::MAX)));
        }
        OverRelaxation::new(factors)
            .map(|factors| Self { factors })
            .map_err(|e| invalid(e.to_string()))
    }

    /// Parses `a/b/c` (factors separated by `/`; `spec` names the provider in the error).
    pub fn parse(spec: &str, text: &str) -> Result<Self, SpecError> {
        OverRelaxation::parse(text)
            .map(|factors| Self { factors })
            .map_err(|e| SpecError::InvalidParameter {
                spec: spec.into(),
                param: "schedule".into(),
                value: text.into(),
                reason: e.to_string(),
            })
    }

    /// The factors, in sweep order (empty for [`Self::NONE`]).
    pub fn factors(&self) -> &[Real] {
        self.factors.factors()
    }

    /// Whether this is [`Self::NONE`].
    pub fn is_empty(&self) -> bool {
        self.factors.is_none()
    }

    /// The same factors as the PGS solver's own schedule ([`OverRelaxation`]: over-relaxed
    /// shares inside its solve).
    pub fn over_relaxation(&self) -> OverRelaxation {
        self.factors
    }

    /// Each factor with its share of `sweeps`: factor `j` of `n` runs sweeps
    /// `⌊sweeps·j/n⌋ .. ⌊sweeps·(j+1)/n⌋`, so the shares differ by at most one sweep, the later
    /// ones the longer; a factor whose share is empty (fewer sweeps than factors) is skipped.
    pub fn shares(&self, sweeps: u32) -> impl Iterator<Item = (Real, u32)> + '_ {
        self.factors.shares(sweeps)
    }
}

/// Schedules for pass budgets: under a budget of `K` passes (the world's, the provider's
/// share being `K − 1`) the schedule of the nearest budget in the table, by ratio (a tie
/// goes to the smaller budget).
///
/// ```
/// use deepcontact_warmstart::{BudgetSchedules, Schedule};
///
/// let s = |f: &[f64]| Schedule::new("sor", f).unwrap();
/// let table = BudgetSchedules::new(vec![(8, s(&[1.7, 1.2])), (16, s(&[1.8, 1.4, 1.1]))]);
/// // A budget of 8 passes offers the provider 7; one of 11 is nearer 8 than 16 by ratio.
/// assert_eq!(table.for_pass_budget(7).unwrap().factors(), &[1.7, 1.2]);
/// assert_eq!(table.for_pass_budget(10).unwrap().factors(), &[1.7, 1.2]);
/// assert_eq!(table.for_pass_budget(31).unwrap().factors(), &[1.8, 1.4, 1.1]);
/// assert!(BudgetSchedules::new(vec![]).for_pass_budget(7).is_none());
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BudgetSchedules {
    /// `(K, schedule)`, sorted by `K`.
    table: Vec<(u32, Schedule)>,
}

impl BudgetSchedules {
    /// The table of `(K, schedule)` pairs (any order; a budget given twice keeps its first).
    pub fn new(mut table: Vec<(u32, Schedule)>) -> Self {
        table.sort_by_key(|&(k, _)| k);
        table.dedup_by_key(|&mut (k, _)| k);
        Self { table }
    }

    /// The `(K, schedule)` pairs, by budget.
    pub fn entries(&self) -> &[(u32, Schedule)] {
        &self.table
    }

    /// The schedule for a provider offered `passes` passes (a world budget of `passes + 1`);
    /// `None` for an empty table.
    pub fn for_pass_budget(&self, passes: u32) -> Option<Schedule> {
        let k = f64::from(passes) + 1.0;
        let distance = |budget: u32| (f64::from(budget.max(1)) / k).ln().abs();
        self.table
            .iter()
            .min_by(|a, b| distance(a.0).total_cmp(&distance(b.0)))
            .map(|&(_, s)| s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_cover_every_sweep_once_in_order() {
        let s = Schedule::new("sor", &[1.9, 1.5, 1.1]).unwrap();
        for sweeps in 0..40 {
            let shares: Vec<_> = s.shares(sweeps).collect();
            assert_eq!(shares.iter().map(|&(_, n)| n).sum::<u32>(), sweeps);
            let max = shares.iter().map(|&(_, n)| n).max().unwrap_or(0);
            let min = shares.iter().map(|&(_, n)| n).min().unwrap_or(0);
            assert!(sweeps < 3 || max - min <= 1, "{sweeps}: {shares:?}");
        }
        // Fewer sweeps than factors: the later factors run.
        assert_eq!(s.shares(2).collect::<Vec<_>>(), vec![(1.5, 1), (1.1, 1)]);
    }

    #[test]
    fn bad_schedules_are_typed_errors() {
        for text in [
            "",
            "1.5/",
            "1.5/x",
            "0.9",
            "2",
            "1.1/1.1/1.1/1.1/1.1/1.1/1.1/1.1/1.1",
        ] {
            match Schedule::parse("sor", text) {
                Err(SpecError::InvalidParameter { param, .. }) => assert_eq!(param, "schedule"),
                other => panic!("{text:?}: {other:?}"),
            }
        }
        assert_eq!(
            Schedule::parse("sor", " 1.7 / 1.2 ").unwrap().factors(),
            &[1.7, 1.2]
        );
    }
}
