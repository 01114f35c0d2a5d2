//! A hand-built contact problem shared by the tests.

use deepcontact_core::{ContactId, ContactProblem, PointDesc, ProblemBody, Registry, Vector};

/// A column of `n` unit-diameter circles (density 1) on static ground, falling at
/// 0.0981 m/s (one step of gravity), the top one also sliding sideways: every point has
/// a normal and a friction row to solve.
pub fn column(n: usize) -> ContactProblem {
    let mut p = ContactProblem::new();
    let ground = p.add_body(ProblemBody {
        world_index: 0,
        position: Vector::new(0.0, -0.5),
        angle: 0.0,
        linear_velocity: Vector::zeros(),
        angular_velocity: 0.0,
        inv_mass: 0.0,
        inv_inertia: 0.0,
    });
    let (r, mass) = (0.5, std::f64::consts::PI * 0.25);
    let inertia = 0.5 * mass * r * r;
    let mut below = ground;
    for i in 0..n {
        let vx = if i + 1 == n { 0.3 } else { 0.0 };
        let ball = p.add_body(ProblemBody {
            world_index: i as u32 + 1,
            position: Vector::new(0.0, 0.5 + i as f64),
            angle: 0.0,
            linear_velocity: Vector::new(vx, -0.0981),
            angular_velocity: 0.0,
            inv_mass: 1.0 / mass,
            inv_inertia: 1.0 / inertia,
        });
        p.begin_manifold();
        p.add_point(&PointDesc {
            id: ContactId {
                body_a: below,
                body_b: ball,
                feature_a: 0,
                feature_b: 0,
            },
            body_a: below,
            body_b: ball,
            point: Vector::new(0.0, i as f64),
            normal: Vector::new(0.0, 1.0),
            separation: 0.0,
            friction: 0.5,
            restitution: 0.0,
            restitution_threshold: 1.0,
        })
        .unwrap();
        below = ball;
    }
    p
}

/// The baseline providers and the PGS solver their oracles use.
pub fn registry() -> Registry {
    let mut r = Registry::empty();
    deepcontact_pgs::register(&mut r);
    deepcontact_warmstart::register(&mut r);
    r
}
