//! The thread machinery shared by the velocity sweep and the position pass: the partition of
//! an island's bodies into domains, the domain sweep, the phase barrier and its padded cells,
//! and the Z-order renumbering of bodies.

pub(crate) mod domain_sweep;
pub(crate) mod partition;
pub(crate) mod sync;
pub(crate) mod z_order;
