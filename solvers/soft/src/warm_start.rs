//! **Warm start** of a substep (Box2D v3's `b2WarmStartContactsTask`): every point's
//! accumulated impulses — the previous substep's, or for the first substep the world's start
//! divided by the substep count — applied to the velocities before the solve pass.

use crate::prepare::Island;
use crate::solve::apply;

/// Applies every point's accumulated impulses of this substep to the velocities.
pub(crate) fn warm_start(island: &mut Island) {
    let Island {
        bodies,
        points,
        manifolds,
    } = island;
    for m in manifolds.iter() {
        let (mut a, mut b) = (bodies[m.a as usize], bodies[m.b as usize]);
        for p in &points[m.start as usize..m.end as usize] {
            apply(&mut a, &mut b, p.normal_dir, p.rn_a, p.rn_b, p.normal);
            apply(&mut a, &mut b, p.tangent_dir, p.rt_a, p.rt_b, p.tangent);
        }
        bodies[m.a as usize] = a;
        bodies[m.b as usize] = b;
    }
}
