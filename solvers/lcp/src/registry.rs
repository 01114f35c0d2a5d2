//! Registration of `psor` and `newton`.

use deepcontact_core::VelocitySolver;
use deepcontact_core::registry::{Params, Registry, SpecError};

use crate::{
    AssemblyMode, DEFAULT_DENSE_THRESHOLD, NewtonSettings, NewtonSolver, PsorSettings, PsorSolver,
};

/// The shared `assembly=auto|dense|sparse` and `dense_threshold=` parameters.
fn assembly(p: &mut Params<'_>) -> Result<(AssemblyMode, usize), SpecError> {
    let mode = match p.choice("assembly", &["auto", "dense", "sparse"])? {
        None | Some("auto") => AssemblyMode::Auto,
        Some("dense") => AssemblyMode::Dense,
        Some(_) => AssemblyMode::Sparse,
    };
    let threshold = p.u64("dense_threshold", DEFAULT_DENSE_THRESHOLD as u64)?;
    Ok((mode, usize::try_from(threshold).unwrap_or(usize::MAX)))
}

/// Registers `psor` (`omega=1`, `assembly=auto|dense|sparse`, `dense_threshold=128`) and
/// `newton` (`reg=1e-10`, `assembly`, `dense_threshold`); defaults are
/// [`PsorSettings::default`] and [`NewtonSettings::default`].
pub fn register(registry: &mut Registry) {
    registry.register_solver(
        "psor",
        "projected SOR on the assembled Delassus matrix; omega=1 (in (0,2); 1 = PGS without \
         block solver), assembly=auto|dense|sparse, dense_threshold=128 (rows)",
        |p| {
            let omega = p.f64("omega", 1.0)?;
            let (assembly, dense_threshold) = assembly(p)?;
            let settings = PsorSettings {
                omega,
                assembly,
                dense_threshold,
                ..PsorSettings::default()
            };
            settings
                .validate()
                .map_err(|e| p.invalid("omega", &omega.to_string(), e.to_string()))?;
            Ok(Box::new(PsorSolver::with_settings(settings)) as Box<dyn VelocitySolver>)
        },
    );
    registry.register_solver(
        "newton",
        "semismooth Newton on the natural map (faer LU, Armijo line search); reg=1e-10 \
         (relative regularisation), assembly=auto|dense|sparse, dense_threshold=128 (rows), \
         stop_on_failed_step=false (stop at the first failed line search instead of retrying), \
         max_backtracks=8",
        |p| {
            let regularization = p.f64("reg", NewtonSettings::default().regularization)?;
            let (assembly, dense_threshold) = assembly(p)?;
            let stop_on_failed_step =
                p.choice("stop_on_failed_step", &["true", "false"])? == Some("true");
            let max_backtracks = p.u64(
                "max_backtracks",
                u64::from(NewtonSettings::default().max_backtracks),
            )?;
            let max_backtracks = u32::try_from(max_backtracks).map_err(|_| {
                p.invalid("max_backtracks", &max_backtracks.to_string(), "too large")
            })?;
            let settings = NewtonSettings {
                regularization,
                stop_on_failed_step,
                max_backtracks,
                assembly,
                dense_threshold,
                ..NewtonSettings::default()
            };
            settings
                .validate()
                .map_err(|e| p.invalid("reg", &regularization.to_string(), e.to_string()))?;
            Ok(Box::new(NewtonSolver::with_settings(settings)) as Box<dyn VelocitySolver>)
        },
    );
}
