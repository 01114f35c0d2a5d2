//! The `bad` provider: the same (large) impulse at every point.

use deepcontact_core::{Impulse, Real, WarmStart, WarmStartContext, WarmStartError};

use deepcontact_core::SpecError;

/// A constant warm start ("bad" in the thesis, which used (50, 50) N·s: far larger than
/// any impulse of the pile, so the solver has to undo it).
///
/// ```
/// use deepcontact_core::{ContactProblem, Impulse, WarmStart, WarmStartContext};
/// use deepcontact_warmstart::ConstantWarmStart;
///
/// let mut provider = ConstantWarmStart::bad();
/// let problem = ContactProblem::new();
/// let ctx = WarmStartContext::new(&problem, &[], 0, 0.01);
/// provider.warm_start(&ctx, &mut []).unwrap();
/// assert_eq!(provider.impulse(), Impulse::new(50.0, 50.0));
/// ```
#[derive(Debug, Clone)]
pub struct ConstantWarmStart {
    impulse: Impulse,
    name: String,
}

impl ConstantWarmStart {
    /// The thesis's default impulse, (50, 50) N·s.
    pub const BAD: Impulse = Impulse::new(50.0, 50.0);

    /// A provider writing `impulse` everywhere, named `name`. The normal must be finite
    /// and ≥ 0 and the tangent finite.
    pub fn new(name: &str, impulse: Impulse) -> Result<Self, SpecError> {
        let invalid = |param: &str, value: Real, reason: &str| SpecError::InvalidParameter {
            spec: name.into(),
            param: param.into(),
            value: value.to_string(),
            reason: reason.into(),
        };
        if !(impulse.normal.is_finite() && impulse.normal >= 0.0) {
            return Err(invalid("normal", impulse.normal, "must be finite and >= 0"));
        }
        if !impulse.tangent.is_finite() {
            return Err(invalid("tangent", impulse.tangent, "must be finite"));
        }
        Ok(Self {
            impulse,
            name: name.to_string(),
        })
    }

    /// The thesis's "bad" provider: (50, 50) everywhere.
    pub fn bad() -> Self {
        Self {
            impulse: Self::BAD,
            name: "bad".into(),
        }
    }

    /// The impulse written at every point.
    pub fn impulse(&self) -> Impulse {
        self.impulse
    }
}

impl WarmStart for ConstantWarmStart {
    fn name(&self) -> &str {
        &self.name
    }

    fn warm_start(
        &mut self,
        _ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        out.fill(self.impulse);
        Ok(())
    }
}
