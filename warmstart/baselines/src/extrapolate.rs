//! The `extrapolate` provider: carried impulses continued linearly in time.

use deepcontact_core::{
    Impulse, Observation, Real, SpecError, WarmStart, WarmStartContext, WarmStartError,
};

use crate::by_contact::StartsByContact;
use crate::rows::in_cone;

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
    starts: StartsByContact,
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
            starts: StartsByContact::default(),
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
        self.starts.fill(ctx, out);
        Ok(())
    }

    /// Where a point had a carried impulse λ_{t−1} and solved to λ_t, its next start is
    /// `λ_t + α (λ_t − λ_{t−1})`; a new point's is λ_t.
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        let points = ctx.problem.points.iter().zip(seen.solved).zip(ctx.carried);
        for ((p, now), carried) in points {
            let start = match carried {
                Some(old) => in_cone(
                    now.normal + self.alpha * (now.normal - old.normal),
                    now.tangent + self.alpha * (now.tangent - old.tangent),
                    p.friction,
                ),
                None => *now,
            };
            self.starts.insert(p.id, start);
        }
    }

    fn reset(&mut self) {
        self.starts.clear();
    }
}
