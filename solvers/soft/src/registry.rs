//! Registration of the soft-step solver.

use deepcontact_core::registry::Registry;

use crate::{SoftSettings, SoftSolver};

/// The most substeps or relax passes `soft:` accepts.
pub const MAX_SUBSTEPS: u64 = 1024;

/// Registers `soft` (parameters `substeps=1..1024`, `relax=0..1024`, `hertz=HZ` (≥ 0),
/// `damping=RATIO` (≥ 0), `push=M_PER_S` (> 0); defaults: [`SoftSettings::default`]).
pub fn register(registry: &mut Registry) {
    registry.register_solver(
        "soft",
        "soft step (Box2D v3): per world step, substeps of integrate velocities, warm start, a \
         soft solve pass, integrate positions and relax passes without bias, then restitution; \
         the solver moves its islands' bodies (no position pass). substeps=N (default 4), \
         relax=N passes per substep (default 1), hertz=HZ contact stiffness (default 30, at \
         most a quarter of the substep rate), damping=RATIO (default 10), push=M/S largest \
         push-out speed (default 3). A fixed budget of K passes runs max(1, K/(1+relax)) \
         substeps",
        |p| {
            let d = SoftSettings::default();
            let substeps = p.u64("substeps", u64::from(d.substeps))?;
            if !(1..=MAX_SUBSTEPS).contains(&substeps) {
                return Err(p.invalid(
                    "substeps",
                    &substeps.to_string(),
                    format!("must be 1 to {MAX_SUBSTEPS}"),
                ));
            }
            let relax = p.u64("relax", u64::from(d.relax))?;
            if relax > MAX_SUBSTEPS {
                return Err(p.invalid(
                    "relax",
                    &relax.to_string(),
                    format!("must be 0 to {MAX_SUBSTEPS}"),
                ));
            }
            let hertz = p.f64("hertz", d.hertz)?;
            if hertz < 0.0 {
                return Err(p.invalid("hertz", &hertz.to_string(), "must be >= 0"));
            }
            let damping = p.f64("damping", d.damping)?;
            if damping < 0.0 {
                return Err(p.invalid("damping", &damping.to_string(), "must be >= 0"));
            }
            let push = p.f64("push", d.push)?;
            if push <= 0.0 {
                return Err(p.invalid("push", &push.to_string(), "must be > 0"));
            }
            Ok(Box::new(SoftSolver::with_settings(SoftSettings {
                substeps: substeps as u32,
                relax: relax as u32,
                hertz,
                damping,
                push,
                ..d
            })) as Box<dyn deepcontact_core::VelocitySolver>)
        },
    );
}

#[cfg(test)]
mod tests {
    use deepcontact_core::{Registry, SpecError};

    fn registry() -> Registry {
        let mut r = Registry::empty();
        super::register(&mut r);
        r
    }

    #[test]
    fn soft_builds_with_defaults_and_parameters() {
        let r = registry();
        assert_eq!(r.build_solver("soft").unwrap().name(), "soft");
        assert!(
            r.build_solver("soft:substeps=8,relax=2,hertz=60,damping=5,push=1")
                .is_ok()
        );
    }

    #[test]
    fn out_of_range_parameters_are_typed_errors_naming_them() {
        let r = registry();
        for (spec, param) in [
            ("soft:substeps=0", "substeps"),
            ("soft:substeps=5000", "substeps"),
            ("soft:relax=2000", "relax"),
            ("soft:hertz=-1", "hertz"),
            ("soft:damping=-0.5", "damping"),
            ("soft:push=0", "push"),
            ("soft:push=nan", "push"),
        ] {
            match r.build_solver(spec) {
                Err(SpecError::InvalidParameter { param: p, .. }) => assert_eq!(p, param, "{spec}"),
                Err(other) => panic!("{spec}: {other}"),
                Ok(_) => panic!("{spec} was accepted"),
            }
        }
        assert!(matches!(
            r.build_solver("soft:iterations=3"),
            Err(SpecError::UnknownParameter { .. })
        ));
    }
}
