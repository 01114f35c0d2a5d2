//! Registration of the PGS velocity solver.

use deepcontact_core::registry::Registry;

use crate::{Ordering, PgsSettings, PgsSolver};

/// Registers `pgs` (parameters `block=true|false`, `order=coloured|sequential`,
/// `lanes=true|false`; defaults: [`PgsSettings::default`]).
pub fn register(registry: &mut Registry) {
    registry.register_solver(
        "pgs",
        "sequential-impulse projected Gauss-Seidel (Box2D v2.4); block=true|false, \
         order=coloured|sequential, lanes=true|false",
        |p| {
            let d = PgsSettings::default();
            let block_solver = p.bool("block", d.block_solver)?;
            let lanes = p.bool("lanes", d.lanes)?;
            let ordering = match p.choice("order", &["coloured", "colored", "sequential"])? {
                None => d.ordering,
                Some("sequential") => Ordering::Sequential,
                Some(_) => Ordering::Coloured,
            };
            Ok(Box::new(PgsSolver::with_settings(PgsSettings {
                block_solver,
                ordering,
                lanes,
                ..d
            })) as Box<dyn deepcontact_core::VelocitySolver>)
        },
    );
}
