//! The registry: names → factories of warm-start providers, velocity solvers and scenes, with
//! the metadata callers need (is a provider an oracle, does it need the world, is it learned).
//! Scenes are built for a seed ([`Registry::build_scene`]); [`crate::scene::register`] adds
//! the core's.
//!
//! Each implementation crate registers its own entries with a `register(&mut Registry)`
//! function (`deepcontact_pgs::register`, `deepcontact_lcp::register`,
//! `deepcontact_warmstart::register`, `deepcontact_grid::register`,
//! `deepcontact_onnx::register`); `deepcontact_experiments::full_registry()` calls them all,
//! and a user adds their own providers to it:
//!
//! ```
//! use deepcontact_core::registry::{ProviderInfo, Registry};
//! use deepcontact_core::{ZeroWarmStart, WarmStart};
//!
//! let mut registry = Registry::empty();
//! registry.register_provider(
//!     "cold",
//!     ProviderInfo::new("zeros under another name"),
//!     |_params, _registry| Ok(Box::new(ZeroWarmStart) as Box<dyn WarmStart>),
//! );
//! let provider = registry.build_provider("cold").unwrap();
//! assert_eq!(provider.name(), "none");
//! assert!(!registry.provider_info("cold").unwrap().oracle);
//! assert!(registry.build_provider("cold:x=1").is_err()); // unknown parameter
//! ```

mod error;
mod spec;

use std::collections::BTreeMap;
use std::sync::Arc;

pub use error::SpecError;
pub use spec::{Params, Spec, split_spec_list};

use crate::scene::Scene;
use crate::solver::VelocitySolver;
use crate::warm_start::WarmStart;

/// Builds a provider from its parameters; may use the registry to build solvers.
pub type ProviderFactory =
    Arc<dyn Fn(&mut Params<'_>, &Registry) -> Result<Box<dyn WarmStart>, SpecError> + Send + Sync>;
/// Builds a velocity solver from its parameters.
pub type SolverFactory =
    Arc<dyn Fn(&mut Params<'_>) -> Result<Box<dyn VelocitySolver>, SpecError> + Send + Sync>;
/// Builds a scene from its parameters and a seed (which places its bodies).
pub type SceneFactory = Arc<dyn Fn(&mut Params<'_>, u64) -> Result<Scene, SpecError> + Send + Sync>;

/// What the registry knows about a provider besides how to build it.
///
/// Built with [`ProviderInfo::new`] and the flag setters; a plain `&str` converts into an
/// entry with that help line and every flag off.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ProviderInfo {
    /// One line on what it writes and which parameters it takes.
    pub help: String,
    /// Solves the step's problem itself (an oracle: `copy`, `grid`); not a fair contender,
    /// and it costs about one extra solve per step (default false).
    pub oracle: bool,
    /// Reads the world through [`crate::WarmStartContext::world`], so hand-built problems
    /// without a world get a provider error (default false).
    pub needs_world: bool,
    /// Its output comes from a trained model (default false).
    pub learned: bool,
}

impl ProviderInfo {
    /// An entry with `help` and every flag off.
    pub fn new(help: impl Into<String>) -> Self {
        Self {
            help: help.into(),
            ..Self::default()
        }
    }
    /// Marks the provider as an oracle.
    pub fn oracle(mut self) -> Self {
        self.oracle = true;
        self
    }
    /// Marks the provider as needing the world.
    pub fn needs_world(mut self) -> Self {
        self.needs_world = true;
        self
    }
    /// Marks the provider as learned.
    pub fn learned(mut self) -> Self {
        self.learned = true;
        self
    }
}

impl From<&str> for ProviderInfo {
    fn from(help: &str) -> Self {
        Self::new(help)
    }
}

#[derive(Clone)]
struct ProviderEntry {
    info: ProviderInfo,
    factory: ProviderFactory,
}

#[derive(Clone)]
struct SolverEntry {
    help: String,
    factory: SolverFactory,
}

#[derive(Clone)]
struct SceneEntry {
    help: String,
    factory: SceneFactory,
}

/// Named factories of warm-start providers and velocity solvers. See the [module](self) docs.
#[derive(Clone, Default)]
pub struct Registry {
    providers: BTreeMap<String, ProviderEntry>,
    solvers: BTreeMap<String, SolverEntry>,
    scenes: BTreeMap<String, SceneEntry>,
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("providers", &self.providers.keys().collect::<Vec<_>>())
            .field("solvers", &self.solvers.keys().collect::<Vec<_>>())
            .field("scenes", &self.scenes.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl Registry {
    /// An empty registry.
    pub fn empty() -> Self {
        Self::default()
    }

    /// Adds (or replaces) a provider factory under `name`.
    pub fn register_provider<F>(&mut self, name: &str, info: impl Into<ProviderInfo>, factory: F)
    where
        F: Fn(&mut Params<'_>, &Registry) -> Result<Box<dyn WarmStart>, SpecError>
            + Send
            + Sync
            + 'static,
    {
        self.providers.insert(
            name.to_string(),
            ProviderEntry {
                info: info.into(),
                factory: Arc::new(factory),
            },
        );
    }

    /// Adds (or replaces) a solver factory under `name`.
    pub fn register_solver<F>(&mut self, name: &str, help: &str, factory: F)
    where
        F: Fn(&mut Params<'_>) -> Result<Box<dyn VelocitySolver>, SpecError>
            + Send
            + Sync
            + 'static,
    {
        self.solvers.insert(
            name.to_string(),
            SolverEntry {
                help: help.to_string(),
                factory: Arc::new(factory),
            },
        );
    }

    /// Adds (or replaces) a scene factory under `name` (see [`crate::scene::register`]).
    pub fn register_scene<F>(&mut self, name: &str, help: &str, factory: F)
    where
        F: Fn(&mut Params<'_>, u64) -> Result<Scene, SpecError> + Send + Sync + 'static,
    {
        self.scenes.insert(
            name.to_string(),
            SceneEntry {
                help: help.to_string(),
                factory: Arc::new(factory),
            },
        );
    }

    /// Registered scene names with their help lines.
    pub fn scenes(&self) -> impl Iterator<Item = (&str, &str)> {
        self.scenes
            .iter()
            .map(|(k, e)| (k.as_str(), e.help.as_str()))
    }

    /// Builds the scene of a parsed spec for `seed`; unknown names and parameters are errors.
    pub fn scene_from_spec(&self, spec: &Spec, seed: u64) -> Result<Scene, SpecError> {
        let entry = self
            .scenes
            .get(&spec.name)
            .ok_or_else(|| SpecError::UnknownScene {
                name: spec.name.clone(),
                known: Self::known(&self.scenes),
            })?;
        let mut params = Params::new(spec);
        let scene = (entry.factory)(&mut params, seed)?;
        params.finish()?;
        Ok(scene)
    }

    /// Builds a scene from text such as `box-pile:bodies=1000,friction=0.3`.
    pub fn build_scene(&self, spec: &str, seed: u64) -> Result<Scene, SpecError> {
        self.scene_from_spec(&spec.parse()?, seed)
    }

    /// Registered provider names with their help lines.
    pub fn providers(&self) -> impl Iterator<Item = (&str, &str)> {
        self.providers
            .iter()
            .map(|(k, e)| (k.as_str(), e.info.help.as_str()))
    }

    /// Registered solver names with their help lines.
    pub fn solvers(&self) -> impl Iterator<Item = (&str, &str)> {
        self.solvers
            .iter()
            .map(|(k, e)| (k.as_str(), e.help.as_str()))
    }

    /// What is known about the provider registered as `name`.
    pub fn provider_info(&self, name: &str) -> Option<&ProviderInfo> {
        self.providers.get(name).map(|e| &e.info)
    }

    /// Whether the provider of `spec` is registered as an oracle (false when unknown).
    pub fn is_oracle(&self, spec: &Spec) -> bool {
        self.provider_info(&spec.name).is_some_and(|i| i.oracle)
    }

    fn known<V>(map: &BTreeMap<String, V>) -> String {
        map.keys().cloned().collect::<Vec<_>>().join(", ")
    }

    /// Builds a provider from a parsed spec; unknown names and parameters are errors.
    pub fn provider_from_spec(&self, spec: &Spec) -> Result<Box<dyn WarmStart>, SpecError> {
        let entry = self
            .providers
            .get(&spec.name)
            .ok_or_else(|| SpecError::UnknownProvider {
                name: spec.name.clone(),
                known: Self::known(&self.providers),
            })?;
        let mut params = Params::new(spec);
        let provider = (entry.factory)(&mut params, self)?;
        params.finish()?;
        Ok(provider)
    }

    /// Builds a provider from text such as `random:seed=3`.
    pub fn build_provider(&self, spec: &str) -> Result<Box<dyn WarmStart>, SpecError> {
        self.provider_from_spec(&spec.parse()?)
    }

    /// Builds a solver from a parsed spec.
    pub fn solver_from_spec(&self, spec: &Spec) -> Result<Box<dyn VelocitySolver>, SpecError> {
        let entry = self
            .solvers
            .get(&spec.name)
            .ok_or_else(|| SpecError::UnknownSolver {
                name: spec.name.clone(),
                known: Self::known(&self.solvers),
            })?;
        let mut params = Params::new(spec);
        let solver = (entry.factory)(&mut params)?;
        params.finish()?;
        Ok(solver)
    }

    /// Builds a solver from text such as `pgs` or `pgs:block=false`.
    pub fn build_solver(&self, spec: &str) -> Result<Box<dyn VelocitySolver>, SpecError> {
        self.solver_from_spec(&spec.parse()?)
    }
}
