//! [`Rounded`]: a wrapper that rounds any provider's output to a number of decimals.

use deepcontact_core::{Impulse, Observation, Real, WarmStart, WarmStartContext, WarmStartError};

use deepcontact_core::SpecError;

/// Rounds the impulses of the wrapped provider to `decimals` decimal places (half away
/// from zero). `Rounded<OracleWarmStart>` with 2 and 0 decimals are the thesis's `copy2`
/// and `copy0`: how precise must a prediction be to help?
///
/// Normal impulses are clamped to ≥ 0 after rounding (a tiny negative value, or −0,
/// must not fail the world's output check), and −0 tangents become +0.
///
/// ```
/// use deepcontact_core::{ContactProblem, Impulse, WarmStart, WarmStartContext};
/// use deepcontact_warmstart::{ConstantWarmStart, Rounded};
///
/// let inner = ConstantWarmStart::new("c", Impulse::new(1.23456, -0.987)).unwrap();
/// let mut rounded = Rounded::new(inner, 2).unwrap();
/// assert_eq!(rounded.name(), "c2");
/// let problem = ContactProblem::new();
/// let ctx = WarmStartContext::new(&problem, &[], 0, 0.01);
/// let mut out = [Impulse::ZERO; 1];
/// rounded.warm_start(&ctx, &mut out).unwrap();
/// assert_eq!(out[0], Impulse::new(1.23, -0.99));
/// ```
#[derive(Debug, Clone)]
pub struct Rounded<W> {
    inner: W,
    decimals: u32,
    scale: Real,
    name: String,
}

impl<W: WarmStart> Rounded<W> {
    /// The largest number of decimals accepted (beyond it `f64` has no digits left to round).
    pub const MAX_DECIMALS: u32 = 15;

    /// Wraps `inner`; the name is the inner name followed by the number of decimals
    /// (`copy` → `copy2`). Errors if `decimals` exceeds [`Self::MAX_DECIMALS`].
    pub fn new(inner: W, decimals: u32) -> Result<Self, SpecError> {
        let name = format!("{}{decimals}", inner.name());
        Self::with_name(inner, decimals, &name)
    }

    /// Wraps `inner` under an explicit name.
    pub fn with_name(inner: W, decimals: u32, name: &str) -> Result<Self, SpecError> {
        if decimals > Self::MAX_DECIMALS {
            return Err(SpecError::InvalidParameter {
                spec: inner.name().to_string(),
                param: "decimals".into(),
                value: decimals.to_string(),
                reason: format!("must be at most {}", Self::MAX_DECIMALS),
            });
        }
        Ok(Self {
            scale: (10.0 as Real).powi(decimals as i32),
            inner,
            decimals,
            name: name.to_string(),
        })
    }

    /// The number of decimals kept.
    pub fn decimals(&self) -> u32 {
        self.decimals
    }

    /// The wrapped provider.
    pub fn inner(&self) -> &W {
        &self.inner
    }

    /// The wrapped provider, mutably.
    pub fn inner_mut(&mut self) -> &mut W {
        &mut self.inner
    }

    /// Unwraps the provider.
    pub fn into_inner(self) -> W {
        self.inner
    }

    /// Rounds one value to the configured decimals (−0 becomes +0).
    #[inline]
    pub fn round(&self, x: Real) -> Real {
        (x * self.scale).round() / self.scale + 0.0
    }
}

impl<W: WarmStart> WarmStart for Rounded<W> {
    fn name(&self) -> &str {
        &self.name
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.inner.warm_start(ctx, out)?;
        for o in out.iter_mut() {
            let normal = self.round(o.normal);
            // A NaN passes through unchanged, so the world's output check still reports it.
            let normal = if normal < 0.0 { 0.0 } else { normal };
            *o = Impulse::new(normal, self.round(o.tangent));
        }
        Ok(())
    }

    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.inner.observe(ctx, seen);
    }
    fn reset(&mut self) {
        self.inner.reset();
    }
    fn diagnostics(&self) -> Vec<(String, Real)> {
        self.inner.diagnostics()
    }
    fn passes_spent(&self) -> u32 {
        self.inner.passes_spent()
    }
}
