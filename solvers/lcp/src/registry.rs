//! Registration of `psor`, `newton` and `pgs-rescue`.

use deepcontact_core::VelocitySolver;
use deepcontact_core::registry::{Params, Registry, SpecError};

use crate::{
    AssemblyMode, DEFAULT_DENSE_THRESHOLD, LcpError, NewtonSettings, NewtonSolver, PgsRescueSolver,
    PsorSettings, PsorSolver, RescueSettings, RescueStart, RescueTrigger,
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

/// A whole-number parameter that must fit a `u32` (a larger one: "too large").
fn u32_param(p: &mut Params<'_>, key: &'static str, default: u32) -> Result<u32, SpecError> {
    let value = p.u64(key, u64::from(default))?;
    u32::try_from(value).map_err(|_| p.invalid(key, &value.to_string(), "too large"))
}

/// Registers `psor` (`omega=1`, `assembly=auto|dense|sparse`, `dense_threshold=128`),
/// `newton` (`reg=1e-10`, `assembly`, `dense_threshold`) and `pgs-rescue`
/// (`trigger=capped|stalled`, `window=100`, `factor=2`, `start=best|iterate|zeros`,
/// `above=10`, `newton_iterations=20`, `newton_chunk=300`, `newton_progress=0.5`,
/// `newton_tolerance=1e-6`, `escalate=300`, `escalate_above=10`, `finish=5000`, `finish_chunk=500`,
/// `sweeps_first=true`); defaults are
/// [`PsorSettings::default`], [`NewtonSettings::default`] and [`RescueSettings::default`].
pub fn register(registry: &mut Registry) {
    register_psor(registry);
    register_newton(registry);
    register_pgs_rescue(registry);
}

/// `psor`: projected SOR on the assembled Delassus matrix.
fn register_psor(registry: &mut Registry) {
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
}

/// `newton`: semismooth Newton on the natural map.
fn register_newton(registry: &mut Registry) {
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
            let max_backtracks = u32_param(
                p,
                "max_backtracks",
                NewtonSettings::default().max_backtracks,
            )?;
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

/// `pgs-rescue`: PGS, then Newton on the islands PGS leaves at its cap.
fn register_pgs_rescue(registry: &mut Registry) {
    registry.register_solver(
        "pgs-rescue",
        "PGS (default settings), then semismooth Newton on the islands PGS leaves at its cap, \
         kept when its natural residual is lower; trigger=capped|stalled (every capped island, \
         or those whose impulse change did not fall by factor over the last window; default \
         capped), window=100 (iterations; a cap below two windows is a budget, never rescued), factor=2 (> 1), above=10 (only islands whose natural \
         residual at the cap is above this multiple of the stop tolerance), start=best|iterate|zeros (Newton \
         from PGS's impulses, from zeros, or from zeros too when the first does not converge; \
         default best), newton_iterations=20 (per start), newton_chunk=300 and newton_progress=0.5 \
         (Newton goes on after a chunk only if the natural residual fell below progress × \
         its value after the chunk before, after the first × PGS's; at least newton_iterations: \
         one solve per start), newton_tolerance=1e-6 (N·s), finish=5000 (PGS iterations from \
         the best result when no start converged and it is still above escalate_above=10 × \
         the stop tolerance; 0: none), finish_chunk=500 (the finishing iterations in rounds of \
         this many, a Newton solve from the end of each but the last until one converges; at \
         least finish: one round, no Newton), sweeps_first=true (the rounds before the Newton \
         starts, which then run only if the rounds leave the island above the gate), \
         escalate=300 (when that leaves it above too, the starts again with this cap; 0: none)",
        |p| {
            let d = RescueSettings::default();
            let trigger = match p.choice("trigger", &["capped", "stalled"])? {
                None => d.trigger,
                Some("stalled") => RescueTrigger::Stalled,
                Some(_) => RescueTrigger::Capped,
            };
            let start = match p.choice("start", &["best", "iterate", "zeros"])? {
                None => d.start,
                Some("iterate") => RescueStart::Iterate,
                Some("zeros") => RescueStart::Zeros,
                Some(_) => RescueStart::Best,
            };
            let window = u32_param(p, "window", d.window)?;
            let newton_iterations = u32_param(p, "newton_iterations", d.newton_iterations)?;
            let newton_chunk = u32_param(p, "newton_chunk", d.newton_chunk)?;
            let escalate = u32_param(p, "escalate", d.escalate)?;
            let finish = u32_param(p, "finish", d.finish)?;
            let finish_chunk = u32_param(p, "finish_chunk", d.finish_chunk)?;
            let sweeps_first = p.bool("sweeps_first", d.sweeps_first)?;
            let settings = RescueSettings {
                trigger,
                start,
                window,
                factor: p.f64("factor", d.factor)?,
                above: p.f64("above", d.above)?,
                newton_iterations,
                newton_chunk,
                newton_progress: p.f64("newton_progress", d.newton_progress)?,
                newton_tolerance: p.f64("newton_tolerance", d.newton_tolerance)?,
                escalate,
                escalate_above: p.f64("escalate_above", d.escalate_above)?,
                finish,
                finish_chunk,
                sweeps_first,
                ..d
            };
            if let Err(e) = settings.validate() {
                return Err(match e {
                    LcpError::InvalidSetting {
                        name,
                        value,
                        reason,
                    } => p.invalid(name, &value.to_string(), reason),
                    other => p.invalid("newton", "default", other.to_string()),
                });
            }
            Ok(Box::new(PgsRescueSolver::with_settings(settings)) as Box<dyn VelocitySolver>)
        },
    );
}
