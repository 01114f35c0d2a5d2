//! Registration of the PGS velocity solver.

use deepcontact_core::registry::Registry;

use crate::{Ordering, PgsSettings, PgsSolver};

/// Registers `pgs` (parameters `block=true|false`, `order=coloured|sequential`,
/// `lanes=true|false`, `start=projected|raw`; defaults: [`PgsSettings::default`]).
pub fn register(registry: &mut Registry) {
    registry.register_solver(
        "pgs",
        "sequential-impulse projected Gauss-Seidel (Box2D v2.4); block=true|false, \
         order=coloured|sequential, lanes=true|false, start=projected|raw",
        |p| {
            let d = PgsSettings::default();
            let block_solver = p.bool("block", d.block_solver)?;
            let lanes = p.bool("lanes", d.lanes)?;
            let raw_start = match p.choice("start", &["projected", "raw"])? {
                None => d.raw_start,
                Some(v) => v == "raw",
            };
            let ordering = match p.choice("order", &["coloured", "colored", "sequential"])? {
                None => d.ordering,
                Some("sequential") => Ordering::Sequential,
                Some(_) => Ordering::Coloured,
            };
            Ok(Box::new(PgsSolver::with_settings(PgsSettings {
                block_solver,
                ordering,
                lanes,
                raw_start,
                ..d
            })) as Box<dyn deepcontact_core::VelocitySolver>)
        },
    );
}
