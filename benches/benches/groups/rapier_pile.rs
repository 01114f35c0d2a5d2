//! The thesis pile in rapier2d, the peer engine of the benchmarks (shared by the `peer` group
//! and by `examples/scaling.rs` through `#[path]`).
//!
//! Matching choices (see docs/BENCHMARKS.md): the very same bodies as deepcontact's
//! [`Scene`] (circles r 0.5, density 1, friction 0.5, restitution 0; the four static walls as
//! segments), gravity −9.81, dt 0.01, the solver passes of a [`RapierConfig`], no sleeping, CCD off (`max_ccd_substeps = 0`), friction mixed as the
//! geometric mean (Box2D's `sqrt(μ1 μ2)`; with μ = 0.5 everywhere rapier's default
//! `Average` would agree anyway) and restitution as the maximum, contact recycling and
//! clustering off (we run the narrow phase on every pair every step), prediction distance 0
//! (we keep touching points only) and allowed linear error = our linear slop 0.0005.

use deepcontact_core::scene::Scene;
use deepcontact_core::{BodyKind, ShapeDesc};
use rapier2d::prelude::*;

/// How rapier2d spends its velocity solve: the unit of work one of our PGS iterations is
/// set beside.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RapierConfig {
    /// One substep with `n` internal PGS passes, friction solved in every pass
    /// (`num_solver_iterations = 1`, `num_internal_pgs_iterations = n`,
    /// `friction_in_bias_pass = true`), then rapier's one stabilisation pass: one integration,
    /// one constraint update, `n + 1` passes over the contacts. The like-with-like
    /// configuration: each of our iterations is one such pass (normal and friction rows).
    Passes(usize),
    /// As [`Self::Passes`] with rapier's default friction rule: friction only in the final
    /// (unbiased) pass, the `n` biased passes solve the normal rows alone.
    PassesNormalOnly(usize),
    /// `n` substeps (`num_solver_iterations = n`), each an integration, a constraint update,
    /// one PGS pass (normal rows only: rapier's default friction rule) and one stabilisation
    /// pass (normal and friction rows): `2n` passes, `n` integrations.
    Substeps(usize),
}

impl RapierConfig {
    /// The label of the benchmarks and tables.
    pub fn label(self) -> String {
        match self {
            Self::Passes(n) => format!("rapier2d-passes{n}"),
            Self::PassesNormalOnly(n) => format!("rapier2d-passes{n}-normal-only"),
            Self::Substeps(n) => format!("rapier2d-substeps{n}"),
        }
    }

    /// Passes over the contacts in one step (PGS and stabilisation passes together).
    pub fn passes(self) -> usize {
        match self {
            Self::Passes(n) | Self::PassesNormalOnly(n) => n + 1,
            Self::Substeps(n) => 2 * n,
        }
    }

    /// The matched integration parameters with this configuration's solver passes.
    fn parameters(self) -> IntegrationParameters {
        let base = IntegrationParameters {
            dt: 0.01,
            max_ccd_substeps: 0,
            contact_recycling: false,
            contact_clustering: false,
            normalized_prediction_distance: 0.0,
            normalized_allowed_linear_error: 0.0005,
            ..IntegrationParameters::default()
        };
        match self {
            Self::Passes(n) | Self::PassesNormalOnly(n) => IntegrationParameters {
                num_solver_iterations: 1,
                num_internal_pgs_iterations: n,
                friction_in_bias_pass: matches!(self, Self::Passes(_)),
                ..base
            },
            Self::Substeps(n) => IntegrationParameters {
                num_solver_iterations: n,
                ..base
            },
        }
    }
}

/// A rapier2d world holding a deepcontact scene.
pub struct RapierPile {
    /// The rapier world.
    pub world: PhysicsWorld,
    config: RapierConfig,
}

impl RapierPile {
    /// Builds the scene in rapier2d with the matched settings and the solver passes of `config`.
    pub fn new(scene: &Scene, config: RapierConfig) -> Self {
        let mut world = PhysicsWorld {
            gravity: Vector::new(0.0, -9.81),
            integration_parameters: config.parameters(),
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
        Self { world, config }
    }

    /// Passes over the contacts per step in the configuration now in use.
    pub fn passes(&self) -> usize {
        self.config.passes()
    }

    /// Switches the solver configuration (the world's state is kept).
    pub fn set_config(&mut self, config: RapierConfig) {
        self.world.integration_parameters = config.parameters();
        self.config = config;
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
