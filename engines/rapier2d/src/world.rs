//! [`RapierWorld`]: rapier2d's usual set of structures in one value, built from a deepcontact
//! [`Scene`], stepped natively or through [`WarmStartHooks`], with the measures deepcontact's
//! step reports use.

use deepcontact_core::scene::Scene;
use deepcontact_core::{BodyKind, Real, ShapeDesc, Vector};
use rapier2d::prelude::*;

use crate::error::AdapterError;
use crate::hooks::{StepStats, WarmStartHooks};

/// A rapier2d world: the pipeline and every set it steps.
pub struct RapierWorld {
    /// Gravity (m/s²; default `(0, −9.81)`).
    pub gravity: rapier2d::math::Vector,
    /// rapier's step settings (default: rapier's, dt 1/60 s, 4 substeps × 1 PGS pass).
    pub params: IntegrationParameters,
    /// The pipeline.
    pub pipeline: PhysicsPipeline,
    /// Islands.
    pub islands: IslandManager,
    /// Broad phase.
    pub broad_phase: DefaultBroadPhase,
    /// Narrow phase (contact pairs and manifolds).
    pub narrow_phase: NarrowPhase,
    /// Bodies.
    pub bodies: RigidBodySet,
    /// Colliders.
    pub colliders: ColliderSet,
    /// Impulse joints (unused by scenes).
    pub impulse_joints: ImpulseJointSet,
    /// Multibody joints (unused by scenes).
    pub multibody_joints: MultibodyJointSet,
    /// Continuous collision detection.
    pub ccd: CCDSolver,
    /// Rigid-body handles in scene order.
    pub handles: Vec<RigidBodyHandle>,
}

impl std::fmt::Debug for RapierWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RapierWorld")
            .field("bodies", &self.bodies.len())
            .field("colliders", &self.colliders.len())
            .finish()
    }
}

/// The contact measures of one step, as deepcontact's `StepReport` defines them.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepMeasures {
    /// Solver contact points of the step.
    pub contacts: usize,
    /// Mean of `max(0, −dist)` over the solver contacts, as the narrow phase found them (m).
    pub penetration_mean: Real,
    /// Largest of the same (m).
    pub penetration_max: Real,
    /// Mean normal velocity error after the step (m/s): `|vn|` where the step's normal
    /// impulse is positive, `max(0, −vn)` where it is zero (the scenes have no restitution,
    /// so the target `vn` is 0).
    pub normal_velocity_error_mean: Real,
    /// Largest of the same (m/s).
    pub normal_velocity_error_max: Real,
    /// Kinetic energy of the dynamic bodies after the step (J).
    pub kinetic_energy: Real,
}

impl RapierWorld {
    /// An empty world with rapier's default settings and gravity `(0, −9.81)`.
    pub fn new() -> Self {
        Self {
            gravity: rapier2d::math::Vector::new(0.0, -9.81),
            params: IntegrationParameters::default(),
            pipeline: PhysicsPipeline::new(),
            islands: IslandManager::new(),
            broad_phase: DefaultBroadPhase::new(),
            narrow_phase: NarrowPhase::new(),
            bodies: RigidBodySet::new(),
            colliders: ColliderSet::new(),
            impulse_joints: ImpulseJointSet::new(),
            multibody_joints: MultibodyJointSet::new(),
            ccd: CCDSolver::new(),
            handles: Vec::new(),
        }
    }

    /// The bodies of `scene` as rapier bodies (sleeping off, as deepcontact's worlds) and
    /// colliders with the same shape, pose, density, friction and restitution, every collider
    /// with `ActiveHooks::MODIFY_SOLVER_CONTACTS` (without hooks rapier never calls them).
    /// Friction mixes as rapier's `Average` and restitution as `Max`: deepcontact's
    /// `sqrt(μ1 μ2)` has no rapier rule, and equals the average where both are equal, as in
    /// every registered scene.
    pub fn from_scene(scene: &Scene) -> Result<Self, AdapterError> {
        let mut world = Self::new();
        let f = |x: Real| x as f32;
        let pt = |p: &Vector| rapier2d::math::Vector::new(p.x as f32, p.y as f32);
        for (i, desc) in scene.bodies.iter().enumerate() {
            let builder = match desc.kind {
                BodyKind::Dynamic => RigidBodyBuilder::dynamic(),
                BodyKind::Static => RigidBodyBuilder::fixed(),
                BodyKind::Kinematic => RigidBodyBuilder::kinematic_velocity_based(),
            };
            let rb = builder
                .translation(pt(&desc.position))
                .rotation(f(desc.angle))
                .linvel(pt(&desc.linear_velocity))
                .angvel(f(desc.angular_velocity))
                .can_sleep(false)
                .build();
            let shape = match &desc.shape {
                ShapeDesc::Ball { radius } => Some(ColliderBuilder::ball(f(*radius))),
                ShapeDesc::Cuboid {
                    half_width,
                    half_height,
                } => Some(ColliderBuilder::cuboid(f(*half_width), f(*half_height))),
                ShapeDesc::ConvexPolygon { vertices } => {
                    let v: Vec<_> = vertices.iter().map(pt).collect();
                    ColliderBuilder::convex_polyline(v)
                }
                ShapeDesc::Segment { a, b } => Some(ColliderBuilder::segment(pt(a), pt(b))),
                ShapeDesc::Polyline { vertices } => {
                    let v: Vec<_> = vertices.iter().map(pt).collect();
                    Some(ColliderBuilder::polyline(v, None))
                }
            };
            let Some(shape) = shape else {
                return Err(AdapterError::Scene {
                    body: i,
                    reason: "rapier could not build its convex polygon".into(),
                });
            };
            let m = &desc.material;
            let collider = shape
                .density(f(m.density))
                .friction(f(m.friction))
                .restitution(f(m.restitution))
                .friction_combine_rule(CoefficientCombineRule::Average)
                .restitution_combine_rule(CoefficientCombineRule::Max)
                .active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS)
                .build();
            let handle = world.bodies.insert(rb);
            world
                .colliders
                .insert_with_parent(collider, handle, &mut world.bodies);
            world.handles.push(handle);
        }
        Ok(world)
    }

    /// One native rapier2d step (no hooks).
    pub fn step_native(&mut self) {
        self.pipeline.step(
            self.gravity,
            &self.params,
            &mut self.islands,
            &mut self.broad_phase,
            &mut self.narrow_phase,
            &mut self.bodies,
            &mut self.colliders,
            &mut self.impulse_joints,
            &mut self.multibody_joints,
            &mut self.ccd,
            &(),
            &(),
        );
    }

    /// One step whose warm starts come from `hooks`' provider: [`WarmStartHooks::begin_step`],
    /// [`WarmStartHooks::plan_islands`] (a no-op unless the hooks group by island), the pipeline
    /// step, [`WarmStartHooks::finish_step`].
    pub fn step(&mut self, hooks: &WarmStartHooks) -> Result<StepStats, AdapterError> {
        let g = Vector::new(Real::from(self.gravity.x), Real::from(self.gravity.y));
        hooks.begin_step(&self.params, g)?;
        hooks.plan_islands(
            &self.bodies,
            &self.colliders,
            &self.narrow_phase,
            &self.params,
        )?;
        self.pipeline.step(
            self.gravity,
            &self.params,
            &mut self.islands,
            &mut self.broad_phase,
            &mut self.narrow_phase,
            &mut self.bodies,
            &mut self.colliders,
            &mut self.impulse_joints,
            &mut self.multibody_joints,
            &mut self.ccd,
            hooks,
            &(),
        );
        hooks.finish_step(&self.narrow_phase)
    }

    /// Every body's `[x, y, angle]` as raw `f32` bits, in scene order: what bit-for-bit
    /// comparisons read.
    pub fn pose_bits(&self) -> Vec<[u32; 3]> {
        self.handles
            .iter()
            .map(|&h| {
                let rb = &self.bodies[h];
                let t = rb.translation();
                [
                    t.x.to_bits(),
                    t.y.to_bits(),
                    rb.rotation().angle().to_bits(),
                ]
            })
            .collect()
    }

    /// The measures of the step just taken (see [`StepMeasures`]): penetration from the solver
    /// contacts the step used, velocities from the bodies after it, the step's normal impulse
    /// as the accumulated impulse minus the written warm start ([`crate::units`]).
    pub fn measures(&self) -> StepMeasures {
        let mut m = StepMeasures::default();
        let vel = |h: Option<RigidBodyHandle>, p: rapier2d::math::Vector| {
            h.and_then(|h| self.bodies.get(h))
                .map_or(rapier2d::math::Vector::ZERO, |rb| rb.velocity_at_point(p))
        };
        for pair in self.narrow_phase.contact_pairs() {
            for manifold in &pair.manifolds {
                let n = manifold.data.normal;
                for sc in &manifold.data.solver_contacts {
                    let depth = Real::from((-sc.dist).max(0.0));
                    m.contacts += 1;
                    m.penetration_mean += depth;
                    m.penetration_max = m.penetration_max.max(depth);
                    let Some(point) = manifold.points.get(sc.contact_id[0] as usize) else {
                        continue;
                    };
                    let impulse = point.data.impulse - sc.warmstart_impulse;
                    let dv = vel(manifold.data.rigid_body2, sc.point)
                        - vel(manifold.data.rigid_body1, sc.point);
                    let vn = Real::from(dv.dot(n));
                    let error = if impulse > 0.0 {
                        vn.abs()
                    } else {
                        (-vn).max(0.0)
                    };
                    m.normal_velocity_error_mean += error;
                    m.normal_velocity_error_max = m.normal_velocity_error_max.max(error);
                }
            }
        }
        if m.contacts > 0 {
            m.penetration_mean /= m.contacts as Real;
            m.normal_velocity_error_mean /= m.contacts as Real;
        }
        for rb in self
            .bodies
            .iter()
            .map(|(_, rb)| rb)
            .filter(|rb| rb.is_dynamic())
        {
            let v = rb.linvel();
            let w = Real::from(rb.angvel());
            let mass = Real::from(rb.mass());
            let inertia = Real::from(rb.mass_properties().local_mprops.principal_inertia());
            m.kinetic_energy += 0.5 * mass * Real::from(v.length_squared()) + 0.5 * inertia * w * w;
        }
        m
    }
}

impl Default for RapierWorld {
    fn default() -> Self {
        Self::new()
    }
}
