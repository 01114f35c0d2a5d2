//! The registry: names → provider and solver factories.

use std::collections::BTreeMap;
use std::sync::Arc;

use deepcontact_core::{VelocitySolver, WarmStart};

use crate::error::WarmstartError;
use crate::spec::{Params, Spec};

/// Builds a provider from its parameters; may use the registry to build solvers.
pub type ProviderFactory =
    Arc<dyn Fn(&mut Params<'_>, &Registry) -> Result<Box<dyn WarmStart>, WarmstartError> + Send + Sync>;
/// Builds a velocity solver from its parameters.
pub type SolverFactory = Arc<dyn Fn(&mut Params<'_>) -> Result<Box<dyn VelocitySolver>, WarmstartError> + Send + Sync>;

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
        r.register_solver("pgs", "sequential-impulse projected Gauss-Seidel (Box2D v2.4); block=true|false", |p| {
            let block = match p.string("block") {
                None | Some("true") => true,
                Some("false") => false,
                Some(v) => {
                    return Err(WarmstartError::InvalidParameter {
                        spec: "pgs".into(),
                        param: "block".into(),
                        value: v.into(),
                        reason: "must be true or false".into(),
                    });
                }
            };
            Ok(Box::new(deepcontact_pgs::PgsSolver::with_settings(deepcontact_pgs::PgsSettings {
                block_solver: block,
                ..Default::default()
            })))
        });
        r.register_provider("none", "zeros (cold start)", |_, _| Ok(Box::new(crate::Zeros)));
        r.register_provider("builtin", "last step's impulses matched by contact id", |_, _| Ok(Box::new(crate::Builtin)));
        r
    }

    /// Adds (or replaces) a provider factory under `name`.
    pub fn register_provider<F>(&mut self, name: &str, help: &str, factory: F)
    where
        F: Fn(&mut Params<'_>, &Registry) -> Result<Box<dyn WarmStart>, WarmstartError> + Send + Sync + 'static,
    {
        self.providers.insert(name.to_string(), Entry { help: help.to_string(), factory: Arc::new(factory) });
    }

    /// Adds (or replaces) a solver factory under `name`.
    pub fn register_solver<F>(&mut self, name: &str, help: &str, factory: F)
    where
        F: Fn(&mut Params<'_>) -> Result<Box<dyn VelocitySolver>, WarmstartError> + Send + Sync + 'static,
    {
        self.solvers.insert(name.to_string(), Entry { help: help.to_string(), factory: Arc::new(factory) });
    }

    /// Registered provider names with their help lines.
    pub fn providers(&self) -> impl Iterator<Item = (&str, &str)> {
        self.providers.iter().map(|(k, e)| (k.as_str(), e.help.as_str()))
    }

    /// Registered solver names with their help lines.
    pub fn solvers(&self) -> impl Iterator<Item = (&str, &str)> {
        self.solvers.iter().map(|(k, e)| (k.as_str(), e.help.as_str()))
    }

    /// Builds a provider from a parsed spec; unknown names and parameters are errors.
    pub fn provider_from_spec(&self, spec: &Spec) -> Result<Box<dyn WarmStart>, WarmstartError> {
        let entry = self.providers.get(&spec.name).ok_or_else(|| WarmstartError::UnknownProvider {
            name: spec.name.clone(),
            known: self.providers.keys().cloned().collect::<Vec<_>>().join(", "),
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
        let entry = self.solvers.get(&spec.name).ok_or_else(|| WarmstartError::UnknownSolver {
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
