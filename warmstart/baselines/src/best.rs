//! The `best` provider: several candidate starts, scored by one residual sweep each.

use deepcontact_core::{
    Impulse, Observation, Real, SpecError, Velocity, WarmStart, WarmStartContext, WarmStartError,
};

use crate::rows::{natural_residual_sq, velocities_after};

/// Asks every candidate for a start and keeps the one with the smallest natural-map
/// residual `‖λ − proj(λ − m (Jv(λ) − b))‖₂` (the change one Jacobi sweep would make:
/// one pass over the points per candidate). Every candidate observes every solve, so
/// candidates with memory keep learning whichever start won. A candidate that fails is
/// skipped; if all fail the error of the last one is returned.
///
/// Under a pass budget ([`WarmStartContext::pass_budget`]) the candidates are asked in order
/// while passes are left: each is offered what is left less the pass that scores it, and
/// the candidates after the budget ran out are not asked (they observe the solve with a
/// budget of 0, so one that sweeps after the solve, as `tail` does, runs no sweeps).
///
/// ```
/// use deepcontact_core::{CarriedWarmStart, WarmStart, ZeroWarmStart};
/// use deepcontact_warmstart::BestOfWarmStart;
///
/// let best = BestOfWarmStart::new(vec![Box::new(CarriedWarmStart), Box::new(ZeroWarmStart)]).unwrap();
/// assert_eq!(best.name(), "best");
/// ```
pub struct BestOfWarmStart {
    candidates: Vec<Box<dyn WarmStart>>,
    trial: Vec<Impulse>,
    flat: Vec<Real>,
    velocities: Vec<Velocity>,
    /// Islands each candidate won.
    wins: Vec<u64>,
    /// Per island of the step (`ctx.island`), per candidate: the pass budget it was offered
    /// (`None`: no budget), which its `observe` gets too.
    offered: Vec<Option<u32>>,
    /// Passes of the last island: the candidates' and one per candidate scored.
    last_passes: u32,
}

impl std::fmt::Debug for BestOfWarmStart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = self.candidates.iter().map(|c| c.name()).collect();
        f.debug_struct("BestOfWarmStart")
            .field("candidates", &names)
            .field("wins", &self.wins)
            .finish()
    }
}

impl BestOfWarmStart {
    /// A wrapper over `candidates` (at least one).
    pub fn new(candidates: Vec<Box<dyn WarmStart>>) -> Result<Self, SpecError> {
        if candidates.is_empty() {
            return Err(SpecError::InvalidParameter {
                spec: "best".into(),
                param: "of".into(),
                value: String::new(),
                reason: "needs at least one candidate".into(),
            });
        }
        let wins = vec![0; candidates.len()];
        Ok(Self {
            candidates,
            trial: Vec::new(),
            flat: Vec::new(),
            velocities: Vec::new(),
            wins,
            offered: Vec::new(),
            last_passes: 0,
        })
    }
}

impl WarmStart for BestOfWarmStart {
    fn name(&self) -> &str {
        "best"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let mut best: Option<(Real, usize)> = None;
        let mut last_error = None;
        let n = self.candidates.len();
        let at = ctx.island * n;
        if self.offered.len() < at + n {
            self.offered.resize(at + n, None);
        }
        let mut spent = 0;
        for (c, candidate) in self.candidates.iter_mut().enumerate() {
            let offer = match ctx.pass_budget {
                None => None,
                // One of the passes left scores the candidate.
                Some(b) if b > spent => Some(b - spent - 1),
                Some(_) => {
                    self.offered[at + c] = Some(0);
                    continue;
                }
            };
            self.offered[at + c] = offer;
            let asked = offer.map_or(*ctx, |o| ctx.with_pass_budget(o));
            self.trial.clear();
            self.trial.resize(out.len(), Impulse::ZERO);
            let produced = candidate
                .warm_start(&asked, &mut self.trial)
                .and_then(|_| deepcontact_core::warm_start::check_output(&self.trial, out.len()));
            spent += candidate.passes_spent();
            if let Err(e) = produced {
                last_error = Some(e);
                continue;
            }
            spent += 1;
            velocities_after(
                ctx.problem,
                &self.trial,
                &mut self.flat,
                &mut self.velocities,
            );
            let score = natural_residual_sq(ctx.problem, &self.trial, &self.velocities);
            if best.is_none_or(|(s, _)| score < s) {
                best = Some((score, c));
                out.copy_from_slice(&self.trial);
            }
        }
        self.last_passes = spent;
        match (best, last_error) {
            (Some((_, c)), _) => {
                self.wins[c] += 1;
                Ok(())
            }
            (None, Some(e)) => Err(e),
            (None, None) => Ok(()),
        }
    }

    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        let at = ctx.island * self.candidates.len();
        for (c, candidate) in self.candidates.iter_mut().enumerate() {
            match self.offered.get(at + c).copied().flatten() {
                Some(o) => candidate.observe(&ctx.with_pass_budget(o), seen),
                None => candidate.observe(ctx, seen),
            }
        }
    }

    fn reset(&mut self) {
        for c in &mut self.candidates {
            c.reset();
        }
        self.wins.fill(0);
    }

    fn diagnostics(&self) -> Vec<(String, Real)> {
        let total = self.wins.iter().sum::<u64>().max(1) as Real;
        self.candidates
            .iter()
            .zip(&self.wins)
            .map(|(c, &w)| (format!("share_{}", c.name()), w as Real / total))
            .collect()
    }

    /// On the last island, the passes of every candidate asked, and one per candidate scored
    /// (its velocities and residual are a pass over the rows).
    fn passes_spent(&self) -> u32 {
        self.last_passes
    }
}
