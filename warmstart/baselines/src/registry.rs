//! The registry: names → provider and solver factories.

use std::collections::BTreeMap;
use std::sync::Arc;

use deepcontact_core::{Impulse, VelocitySolver, WarmStart};

use crate::error::WarmstartError;
use crate::spec::{Params, Spec};
use crate::{
    ConstantWarmStart, OracleConfig, OracleWarmStart, RandomConfig, RandomWarmStart, Rounded,
};

/// Builds a provider from its parameters; may use the registry to build solvers.
pub type ProviderFactory = Arc<
    dyn Fn(&mut Params<'_>, &Registry) -> Result<Box<dyn WarmStart>, WarmstartError> + Send + Sync,
>;
/// Builds a velocity solver from its parameters.
pub type SolverFactory =
    Arc<dyn Fn(&mut Params<'_>) -> Result<Box<dyn VelocitySolver>, WarmstartError> + Send + Sync>;

#[derive(Clone)]
struct Entry<F> {
    help: String,
    factory: F,
}

/// Named factories of warm-start providers and velocity solvers.
///
/// ```
/// use deepcontact_warmstart::Registry;
/// let registry = Registry::with_defaults();
/// let provider = registry.build_provider("builtin").unwrap();
/// assert_eq!(provider.name(), "builtin");
/// assert!(registry.build_provider("nope").is_err());
/// ```
#[derive(Clone, Default)]
pub struct Registry {
    providers: BTreeMap<String, Entry<ProviderFactory>>,
    solvers: BTreeMap<String, Entry<SolverFactory>>,
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("providers", &self.providers.keys().collect::<Vec<_>>())
            .field("solvers", &self.solvers.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl Registry {
    /// An empty registry.
    pub fn empty() -> Self {
        Self::default()
    }

    /// The baseline providers and the PGS solver.
    pub fn with_defaults() -> Self {
        let mut r = Self::empty();
        r.register_solver(
            "pgs",
            "sequential-impulse projected Gauss-Seidel (Box2D v2.4); block=true|false, order=coloured|sequential, lanes=true|false",
            |p| {
                let block = p.bool("block", true)?;
                let lanes = p.bool("lanes", true)?;
                let ordering = match p.string("order") {
                    None | Some("coloured") | Some("colored") => deepcontact_pgs::Ordering::Coloured,
                    Some("sequential") => deepcontact_pgs::Ordering::Sequential,
                    Some(v) => {
                        return Err(WarmstartError::InvalidParameter {
                            spec: "pgs".into(),
                            param: "order".into(),
                            value: v.into(),
                            reason: "must be coloured or sequential".into(),
                        });
                    }
                };
                Ok(Box::new(deepcontact_pgs::PgsSolver::with_settings(
                    deepcontact_pgs::PgsSettings {
                        block_solver: block,
                        ordering,
                        lanes,
                        ..Default::default()
                    },
                )))
            },
        );
        r.register_provider("none", "zeros (cold start)", |_, _| {
            Ok(Box::new(crate::Zeros))
        });
        r.register_provider(
            "builtin",
            "last step's impulses matched by contact id",
            |_, _| Ok(Box::new(crate::Builtin)),
        );
        r.register_provider(
            "random",
            "normal U(normal_min, normal_max), tangent U(-tangent_max, tangent_max), seeded; \
             seed=0, normal_min=0, normal_max=5, tangent_max=2",
            |p, _| {
                let d = RandomConfig::default();
                let config = RandomConfig {
                    seed: p.u64("seed", d.seed)?,
                    normal_min: p.f64("normal_min", d.normal_min)?,
                    normal_max: p.f64("normal_max", d.normal_max)?,
                    tangent_max: p.f64("tangent_max", d.tangent_max)?,
                };
                Ok(Box::new(RandomWarmStart::new(config)?))
            },
        );
        r.register_provider(
            "bad",
            "the same impulse everywhere; value=50 sets both, normal= and tangent= override one",
            |p, _| {
                let value = p.f64("value", ConstantWarmStart::BAD.normal)?;
                let normal = p.f64("normal", value)?;
                let tangent = p.f64("tangent", value)?;
                Ok(Box::new(ConstantWarmStart::new(
                    "bad",
                    Impulse::new(normal, tangent),
                )?))
            },
        );
        r.register_provider(
            "copy",
            "oracle: solve this step's problem first and start from that; \
             solver=pgs, tolerance=1e-6, max_iterations=10000, decimals= (round, as copy2/copy0)",
            |p, r| {
                let oracle = build_oracle(p, r)?;
                if p.string("decimals").is_none() {
                    return Ok(Box::new(oracle));
                }
                let decimals = p.u64("decimals", 0)?;
                let decimals = decimals_u32(p.name(), decimals)?;
                Ok(Box::new(Rounded::new(oracle, decimals)?))
            },
        );
        r.register_provider(
            "copy2",
            "copy rounded to 2 decimals; solver=pgs, tolerance=1e-6, max_iterations=10000",
            |p, r| Ok(Box::new(Rounded::new(build_oracle(p, r)?, 2)?)),
        );
        r.register_provider(
            "copy0",
            "copy rounded to 0 decimals (normals clamped to >= 0); solver=pgs, tolerance=1e-6, max_iterations=10000",
            |p, r| Ok(Box::new(Rounded::new(build_oracle(p, r)?, 0)?)),
        );
        r
    }

    /// Adds (or replaces) a provider factory under `name`.
    pub fn register_provider<F>(&mut self, name: &str, help: &str, factory: F)
    where
        F: Fn(&mut Params<'_>, &Registry) -> Result<Box<dyn WarmStart>, WarmstartError>
            + Send
            + Sync
            + 'static,
    {
        self.providers.insert(
            name.to_string(),
            Entry {
                help: help.to_string(),
                factory: Arc::new(factory),
            },
        );
    }

    /// Adds (or replaces) a solver factory under `name`.
    pub fn register_solver<F>(&mut self, name: &str, help: &str, factory: F)
    where
        F: Fn(&mut Params<'_>) -> Result<Box<dyn VelocitySolver>, WarmstartError>
            + Send
            + Sync
            + 'static,
    {
        self.solvers.insert(
            name.to_string(),
            Entry {
                help: help.to_string(),
                factory: Arc::new(factory),
            },
        );
    }

    /// Registered provider names with their help lines.
    pub fn providers(&self) -> impl Iterator<Item = (&str, &str)> {
        self.providers
            .iter()
            .map(|(k, e)| (k.as_str(), e.help.as_str()))
    }

    /// Registered solver names with their help lines.
    pub fn solvers(&self) -> impl Iterator<Item = (&str, &str)> {
        self.solvers
            .iter()
            .map(|(k, e)| (k.as_str(), e.help.as_str()))
    }

    /// Builds a provider from a parsed spec; unknown names and parameters are errors.
    pub fn provider_from_spec(&self, spec: &Spec) -> Result<Box<dyn WarmStart>, WarmstartError> {
        let entry =
            self.providers
                .get(&spec.name)
                .ok_or_else(|| WarmstartError::UnknownProvider {
                    name: spec.name.clone(),
                    known: self
                        .providers
                        .keys()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(", "),
                })?;
        let mut params = Params::new(spec);
        let provider = (entry.factory)(&mut params, self)?;
        params.finish()?;
        Ok(provider)
    }

    /// Builds a provider from text such as `random:seed=3`.
    pub fn build_provider(&self, spec: &str) -> Result<Box<dyn WarmStart>, WarmstartError> {
        self.provider_from_spec(&spec.parse()?)
    }

    /// Builds a solver from a parsed spec.
    pub fn solver_from_spec(&self, spec: &Spec) -> Result<Box<dyn VelocitySolver>, WarmstartError> {
        let entry = self
            .solvers
            .get(&spec.name)
            .ok_or_else(|| WarmstartError::UnknownSolver {
                name: spec.name.clone(),
                known: self.solvers.keys().cloned().collect::<Vec<_>>().join(", "),
            })?;
        let mut params = Params::new(spec);
        let solver = (entry.factory)(&mut params)?;
        params.finish()?;
        Ok(solver)
    }

    /// Builds a solver from text such as `pgs` or `pgs:block=false`.
    pub fn build_solver(&self, spec: &str) -> Result<Box<dyn VelocitySolver>, WarmstartError> {
        self.solver_from_spec(&spec.parse()?)
    }
}

fn decimals_u32(spec: &str, d: u64) -> Result<u32, WarmstartError> {
    u32::try_from(d).map_err(|_| WarmstartError::InvalidParameter {
        spec: spec.into(),
        param: "decimals".into(),
        value: d.to_string(),
        reason: "too large".into(),
    })
}

/// The oracle's parameters: `solver` (a registry solver spec, default `pgs`), `tolerance`
/// (default 1e-6, ≥ 0) and `max_iterations` (default 10 000, 1 ..= u32::MAX).
fn build_oracle(
    p: &mut Params<'_>,
    registry: &Registry,
) -> Result<OracleWarmStart, WarmstartError> {
    let d = OracleConfig::default();
    let spec = p.name().to_string();
    let invalid = |param: &str, value: String, reason: &str| WarmstartError::InvalidParameter {
        spec: spec.clone(),
        param: param.into(),
        value,
        reason: reason.into(),
    };
    let tolerance = p.f64("tolerance", d.tolerance)?;
    if tolerance < 0.0 {
        return Err(invalid("tolerance", tolerance.to_string(), "must be >= 0"));
    }
    let max_iterations = p.u64("max_iterations", u64::from(d.max_iterations))?;
    let max_iterations = match u32::try_from(max_iterations) {
        Ok(m) if m >= 1 => m,
        _ => {
            return Err(invalid(
                "max_iterations",
                max_iterations.to_string(),
                "must be in 1..=4294967295",
            ));
        }
    };
    let solver = registry.build_solver(p.string("solver").unwrap_or("pgs"))?;
    OracleWarmStart::new(
        solver,
        OracleConfig {
            tolerance,
            max_iterations,
        },
    )
}
