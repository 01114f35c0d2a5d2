//! The thesis pile in rapier2d, the peer engine of the benchmarks (shared by the `peer` group
//! and by `examples/scaling.rs` through `#[path]`).
//!
//! Matching choices (see docs/BENCHMARKS.md): the very same bodies as deepcontact's
//! [`Scene`] (circles r 0.5, density 1, friction 0.5, restitution 0; the four static walls as
//! segments), gravity −9.81, dt 0.01, `num_solver_iterations` = our fixed velocity iteration
//! count (rapier runs that many substeps, each one PGS iteration plus one stabilisation
//! iteration), no sleeping, CCD off (`max_ccd_substeps = 0`), friction mixed as the
//! geometric mean (Box2D's `sqrt(μ1 μ2)`; with μ = 0.5 everywhere rapier's default
//! `Average` would agree anyway) and restitution as the maximum, contact recycling and
//! clustering off (we run the narrow phase on every pair every step), prediction distance 0
//! (we keep touching points only) and allowed linear error = our linear slop 0.0005.

use deepcontact_core::scene::Scene;
use deepcontact_core::{BodyKind, ShapeDesc};
use rapier2d::prelude::*;

/// A rapier2d world holding a deepcontact scene.
pub struct RapierPile {
    /// The rapier world.
    pub world: PhysicsWorld,
}

impl RapierPile {
    /// Builds the scene in rapier2d with the matched settings and `iterations` solver iterations.
    pub fn new(scene: &Scene, iterations: usize) -> Self {
        let parameters = IntegrationParameters {
            dt: 0.01,
            num_solver_iterations: iterations,
            max_ccd_substeps: 0,
            contact_recycling: false,
            contact_clustering: false,
            normalized_prediction_distance: 0.0,
            normalized_allowed_linear_error: 0.0005,
            ..IntegrationParameters::default()
        };
        let mut world = PhysicsWorld {
            gravity: Vector::new(0.0, -9.81),
            integration_parameters: parameters,
            ..PhysicsWorld::default()
        };
        for desc in &scene.bodies {
            let at = Vector::new(desc.position.x as f32, desc.position.y as f32);
            let body = match desc.kind {
                BodyKind::Dynamic => RigidBodyBuilder::dynamic()
                    .can_sleep(false)
                    .ccd_enabled(false),
                BodyKind::Static | BodyKind::Kinematic => RigidBodyBuilder::fixed(),
            }
            .translation(at)
            .rotation(desc.angle as f32);
            let collider = match &desc.shape {
                ShapeDesc::Ball { radius } => ColliderBuilder::ball(*radius as f32),
                ShapeDesc::Segment { a, b } => ColliderBuilder::segment(
                    Vector::new(a.x as f32, a.y as f32),
                    Vector::new(b.x as f32, b.y as f32),
                ),
                ShapeDesc::Cuboid {
                    half_width,
                    half_height,
                } => ColliderBuilder::cuboid(*half_width as f32, *half_height as f32),
                other => panic!("the peer pile has no {other:?}"),
            };
            let m = desc.material;
            let collider = collider
                .density(m.density as f32)
                .friction(m.friction as f32)
                .restitution(m.restitution as f32)
                .friction_combine_rule(CoefficientCombineRule::GeometricMean)
                .restitution_combine_rule(CoefficientCombineRule::Max);
            world.insert(body, collider);
        }
        Self { world }
    }

    /// One step of dt.
    pub fn step(&mut self) {
        self.world.step();
    }

    /// Contact points handed to the solver in the last step.
    pub fn contacts(&self) -> usize {
        self.world
            .narrow_phase
            .contact_pairs()
            .map(|pair| match &pair.contacts {
                PairContacts::Rigid(rigid) => rigid
                    .solver_manifolds()
                    .iter()
                    .map(|m| m.data.solver_contacts.len())
                    .sum::<usize>(),
                _ => 0,
            })
            .sum()
    }

    /// Seconds of the last step in rapier's velocity resolution (all substeps: solver
    /// iterations, stabilisation, integration, write-back; rapier's `profiler` counters).
    pub fn solver_seconds(&self) -> f64 {
        self.world
            .physics_pipeline
            .counters
            .solver
            .velocity_resolution_time
            .time()
            .as_secs_f64()
    }

    /// Seconds of the last step in rapier's collision detection (broad and narrow phase).
    pub fn collision_seconds(&self) -> f64 {
        self.world
            .physics_pipeline
            .counters
            .stages
            .collision_detection_time
            .time()
            .as_secs_f64()
    }

    /// Total kinetic energy of the dynamic bodies (for a sanity check against ours).
    pub fn kinetic_energy(&self) -> f64 {
        self.world
            .bodies
            .iter()
            .filter(|(_, b)| b.is_dynamic())
            .map(|(_, b)| f64::from(b.kinetic_energy()))
            .sum()
    }
}
