//! The `random` provider: uniformly random impulses from a seeded, portable generator.

use deepcontact_core::rng::PortableRng;
use deepcontact_core::{Impulse, Real, WarmStart, WarmStartContext, WarmStartError};

use deepcontact_core::SpecError;

/// Ranges and seed of [`RandomWarmStart`]. The defaults are the thesis's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomConfig {
    /// Seed of the generator (default 0). The same seed gives the same stream on every platform.
    pub seed: u64,
    /// Lower end of the normal impulse range (default 0 N·s). Must be ≥ 0.
    pub normal_min: Real,
    /// Upper end of the normal impulse range (default 5 N·s). Must be ≥ `normal_min`.
    pub normal_max: Real,
    /// Tangent impulses are drawn from `[-tangent_max, tangent_max)` (default 2 N·s). Must be ≥ 0.
    pub tangent_max: Real,
}

impl Default for RandomConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            normal_min: 0.0,
            normal_max: 5.0,
            tangent_max: 2.0,
        }
    }
}

impl RandomConfig {
    /// Rejects non-finite values, a negative `normal_min` or `tangent_max`, and an empty normal range.
    pub fn validate(&self) -> Result<(), SpecError> {
        let invalid = |param: &str, value: Real, reason: &str| SpecError::InvalidParameter {
            spec: "random".into(),
            param: param.into(),
            value: value.to_string(),
            reason: reason.into(),
        };
        if !(self.normal_min.is_finite() && self.normal_min >= 0.0) {
            return Err(invalid(
                "normal_min",
                self.normal_min,
                "must be finite and >= 0",
            ));
        }
        if !(self.normal_max.is_finite() && self.normal_max >= self.normal_min) {
            return Err(invalid(
                "normal_max",
                self.normal_max,
                "must be finite and >= normal_min",
            ));
        }
        if !(self.tangent_max.is_finite() && self.tangent_max >= 0.0) {
            return Err(invalid(
                "tangent_max",
                self.tangent_max,
                "must be finite and >= 0",
            ));
        }
        Ok(())
    }
}

/// Random warm start ("random" in the thesis): normal impulses uniform in
/// `[normal_min, normal_max)`, tangent impulses uniform in `[-tangent_max, tangent_max)`.
///
/// The generator is seeded at construction and again by `reset` (which a world calls before
/// its first step), and advances with every point, so a world stepped with providers built
/// from the same config, or with one provider used before on another world, sees the same
/// values.
///
/// ```
/// use deepcontact_core::{ContactProblem, Impulse, WarmStart, WarmStartContext};
/// use deepcontact_warmstart::{RandomConfig, RandomWarmStart};
///
/// let mut provider = RandomWarmStart::new(RandomConfig { seed: 3, ..Default::default() }).unwrap();
/// let problem = ContactProblem::new();
/// let ctx = WarmStartContext::new(&problem, &[], 0, 0.01);
/// provider.warm_start(&ctx, &mut []).unwrap();
/// assert_eq!(provider.name(), "random");
/// ```
#[derive(Debug, Clone)]
pub struct RandomWarmStart {
    config: RandomConfig,
    rng: PortableRng,
}

impl RandomWarmStart {
    /// A provider with the given (validated) config.
    pub fn new(config: RandomConfig) -> Result<Self, SpecError> {
        config.validate()?;
        Ok(Self {
            config,
            rng: PortableRng::new(config.seed),
        })
    }

    /// The config.
    pub fn config(&self) -> &RandomConfig {
        &self.config
    }
}

impl WarmStart for RandomWarmStart {
    fn name(&self) -> &str {
        "random"
    }

    fn warm_start(
        &mut self,
        _ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let c = self.config;
        for o in out.iter_mut() {
            let normal = self.rng.uniform_range(c.normal_min, c.normal_max);
            let tangent = self.rng.uniform_range(-c.tangent_max, c.tangent_max);
            *o = Impulse::new(normal, tangent);
        }
        Ok(())
    }

    /// A new world: the generator starts its stream again from the seed.
    fn reset(&mut self) {
        self.rng = PortableRng::new(self.config.seed);
    }
}
