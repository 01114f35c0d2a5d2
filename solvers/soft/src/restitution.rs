//! **Restitution**, once after the substeps (Box2D v3's `b2ApplyRestitutionTask`).
//!
//! A point bounces when the problem gives it a restitution target (`velocity_bias > 0`: the
//! world set it to `−e vn` for points closing faster than the restitution threshold) and it
//! carried a normal impulse during the step (Box2D skips points whose total normal impulse
//! is zero: speculative points that never touched). Its normal row is solved once, rigidly,
//! to the target: `λ = −m (vn − target)`, `λ_acc ← max(λ_acc + λ, 0)`.
//!
//! One difference from Box2D: Box2D measures the closing speed before the step's gravity;
//! the problem's target was measured by the world after the whole step's gravity
//! (`dt g` more closing speed, `e dt |g|` more target).

use crate::prepare::Island;
use crate::solve::apply;

/// Applies restitution to every point that bounces.
pub(crate) fn restitution(island: &mut Island) {
    let Island {
        bodies,
        points,
        manifolds,
    } = island;
    for m in manifolds.iter() {
        let rows = &mut points[m.start as usize..m.end as usize];
        if rows
            .iter()
            .all(|p| p.restitution_target <= 0.0 || p.total_normal == 0.0)
        {
            continue;
        }
        let (mut a, mut b) = (bodies[m.a as usize], bodies[m.b as usize]);
        for p in rows.iter_mut() {
            if p.restitution_target <= 0.0 || p.total_normal == 0.0 {
                continue;
            }
            let va = a.v + deepcontact_core::math::cross_sv(a.w, &p.r_a);
            let vb = b.v + deepcontact_core::math::cross_sv(b.w, &p.r_b);
            let vn = (vb - va).dot(&p.normal_dir);
            let lambda = -p.normal_mass * (vn - p.restitution_target);
            let new = (p.normal + lambda).max(0.0);
            let delta = new - p.normal;
            p.normal = new;
            p.total_normal += delta;
            apply(&mut a, &mut b, p.normal_dir, p.rn_a, p.rn_b, delta);
        }
        bodies[m.a as usize] = a;
        bodies[m.b as usize] = b;
    }
}
