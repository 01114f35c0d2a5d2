//! Registration of `learned-sor` in a [`Registry`].

use std::path::Path;

use deepcontact_core::registry::{ProviderInfo, Registry, SpecError};
use deepcontact_warmstart::{RelaxedConfig, RelaxedWarmStart};

use crate::{RelaxError, RelaxationPolicy};

/// `sor` with `policy`'s per-point factors, named `name`, under `config` (its `omega` is not
/// used).
pub fn learned_sor(
    name: &str,
    policy: RelaxationPolicy,
    config: RelaxedConfig,
) -> Result<RelaxedWarmStart, SpecError> {
    Ok(RelaxedWarmStart::new(config)?.with_relaxation(name, Box::new(policy)))
}

/// Registers `learned-sor`: the shipped policy, or `path=policy.json`; `name=` renames it,
/// `sweeps=` (300) and `tolerance=` (1e-4) bound its sweeps as `sor`'s.
pub fn register(registry: &mut Registry) {
    registry.register_provider(
        "learned-sor",
        ProviderInfo::new(
            "sor whose per-contact relaxation factor is picked by a learned policy (six features, fitted on seeds 0-99; \
             models/learned-sor.json); path=policy.json, name=learned-sor, sweeps=300, tolerance=1e-4",
        )
        .learned(),
        |p, _| {
            let build = |e: RelaxError| SpecError::Build {
                spec: "learned-sor".into(),
                reason: e.to_string(),
            };
            let policy = match p.string("path") {
                Some(path) => RelaxationPolicy::from_file(Path::new(path)),
                None => RelaxationPolicy::shipped(),
            }
            .map_err(build)?;
            let name = p.string("name").unwrap_or("learned-sor");
            let d = RelaxedConfig::default();
            let sweeps = p.u64("sweeps", u64::from(d.sweeps))?;
            let config = RelaxedConfig {
                sweeps: u32::try_from(sweeps).unwrap_or(u32::MAX),
                tolerance: p.f64("tolerance", d.tolerance)?,
                ..d
            };
            Ok(Box::new(learned_sor(name, policy, config)?))
        },
    );
}
