//! The `extrapolate` provider: carried impulses continued linearly in time.

use std::collections::HashMap;

use deepcontact_core::{
    ContactId, Impulse, Observation, Real, SpecError, WarmStart, WarmStartContext, WarmStartError,
};

/// `λ_t + α (λ_t − λ_{t−1})` by contact id: if a point's impulse grew last step it is
/// expected to grow again (a load arriving from above, a body sliding to rest). Points seen
/// for one step only get their carried impulse; the result is projected onto the friction
/// cone. Maps are kept between steps (no allocation once grown).
///
/// ```
/// use deepcontact_core::WarmStart;
/// use deepcontact_warmstart::ExtrapolatedWarmStart;
///
/// let provider = ExtrapolatedWarmStart::new(0.5).unwrap();
/// assert_eq!(provider.name(), "extrapolate");
/// ```
#[derive(Debug, Clone)]
pub struct ExtrapolatedWarmStart {
    alpha: Real,
    /// Starts for the step being solved, by contact id.
    current: HashMap<ContactId, Impulse>,
    /// Starts for the next step, written by `observe`.
    next: HashMap<ContactId, Impulse>,
    step: Option<u64>,
}

impl ExtrapolatedWarmStart {
    /// A provider with weight `alpha` (finite; 0 is `builtin`; the registry's default 0.25 was the best of 0.15, 0.25, 0.35, 0.5 and 1 on the tuning seeds).
    pub fn new(alpha: Real) -> Result<Self, SpecError> {
        if !alpha.is_finite() {
            return Err(SpecError::InvalidParameter {
                spec: "extrapolate".into(),
                param: "alpha".into(),
                value: alpha.to_string(),
                reason: "must be finite".into(),
            });
        }
        Ok(Self {
            alpha,
            current: HashMap::new(),
            next: HashMap::new(),
            step: None,
        })
    }

    /// The weight α.
    pub fn alpha(&self) -> Real {
        self.alpha
    }
}

impl WarmStart for ExtrapolatedWarmStart {
    fn name(&self) -> &str {
        "extrapolate"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        if self.step != Some(ctx.step) {
            std::mem::swap(&mut self.current, &mut self.next);
            self.next.clear();
            self.step = Some(ctx.step);
        }
        for (i, (o, p)) in out.iter_mut().zip(&ctx.problem.points).enumerate() {
            *o = match self.current.get(&p.id) {
                Some(&start) if ctx.carried.get(i).is_some_and(Option::is_some) => start,
                _ => ctx.carried_or_zero(i),
            };
        }
        Ok(())
    }

    /// Where a point had a carried impulse λ_{t−1} and solved to λ_t, its next start is
    /// `λ_t + α (λ_t − λ_{t−1})`; a new point's is λ_t.
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        let points = ctx.problem.points.iter().zip(seen.solved).zip(ctx.carried);
        for ((p, now), carried) in points {
            let start = match carried {
                Some(old) => {
                    let normal = (now.normal + self.alpha * (now.normal - old.normal)).max(0.0);
                    let bound = p.friction * normal;
                    let tangent = (now.tangent + self.alpha * (now.tangent - old.tangent))
                        .clamp(-bound, bound);
                    Impulse::new(normal, tangent)
                }
                None => *now,
            };
            self.next.insert(p.id, start);
        }
    }

    fn reset(&mut self) {
        self.current.clear();
        self.next.clear();
        self.step = None;
    }
}
