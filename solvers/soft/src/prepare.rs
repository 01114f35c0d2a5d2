//! Stage 1, **prepare**: the problem copied into the solver's rows, manifolds and body
//! states (Box2D v3's `b2PrepareContactsTask`), buffers reused between solves.

use deepcontact_core::math::{Real, Vector, cross};
use deepcontact_core::{ContactProblem, CoreError, Impulse, ProblemBody};

use crate::soft::{ContactSoftness, Softness};

/// One body during a solve.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BodyState {
    /// Linear velocity (m/s).
    pub(crate) v: Vector,
    /// Angular velocity (rad/s).
    pub(crate) w: Real,
    /// Displacement of the centre of mass since the contacts were computed (m).
    pub(crate) dp: Vector,
    /// Rotation since the contacts were computed (rad), and its sine and cosine.
    pub(crate) dq: Real,
    pub(crate) dq_sin: Real,
    pub(crate) dq_cos: Real,
    /// Inverse mass (1/kg) and inverse moment of inertia (1/(kg·m²)).
    pub(crate) inv_mass: Real,
    pub(crate) inv_inertia: Real,
    /// Whether gravity acts on the body (a positive inverse mass: the world's dynamic bodies).
    pub(crate) gravity: bool,
}

impl BodyState {
    /// `rot(dq) r − r`: how far anchor `r` has turned since the contacts were computed.
    #[inline(always)]
    pub(crate) fn turned(&self, r: &Vector) -> Vector {
        Vector::new(
            self.dq_cos * r.x - self.dq_sin * r.y,
            self.dq_sin * r.x + self.dq_cos * r.y,
        )
    }
}

/// One contact point: a normal row and a friction row.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Point {
    /// Anchors from each body's centre of mass at the time the contacts were computed (m).
    pub(crate) r_a: Vector,
    pub(crate) r_b: Vector,
    /// `r × n` and `r × t` of each anchor.
    pub(crate) rn_a: Real,
    pub(crate) rn_b: Real,
    pub(crate) rt_a: Real,
    pub(crate) rt_b: Real,
    /// Unit normal from A to B and the tangent `(−n.y, n.x)`.
    pub(crate) normal_dir: Vector,
    pub(crate) tangent_dir: Vector,
    /// `separation − (r_b − r_a)·n` (m): the separation at the current poses is this plus
    /// `(Δp_b + rot(Δθ_b) r_b − Δp_a − rot(Δθ_a) r_a)·n`.
    pub(crate) base_separation: Real,
    pub(crate) normal_mass: Real,
    pub(crate) tangent_mass: Real,
    pub(crate) friction: Real,
    /// The restitution target normal speed (m/s, the problem's `velocity_bias`; 0 = none).
    pub(crate) restitution_target: Real,
    /// This substep's accumulated impulses (N·s per substep).
    pub(crate) normal: Real,
    pub(crate) tangent: Real,
    /// The impulses summed over the step's substeps (N·s per step).
    pub(crate) total_normal: Real,
    pub(crate) total_tangent: Real,
}

/// The points of one body pair.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Manifold {
    pub(crate) a: u32,
    pub(crate) b: u32,
    pub(crate) start: u32,
    pub(crate) end: u32,
    pub(crate) softness: Softness,
}

/// Everything a solve works on.
#[derive(Debug, Clone, Default)]
pub(crate) struct Island {
    pub(crate) bodies: Vec<BodyState>,
    pub(crate) points: Vec<Point>,
    pub(crate) manifolds: Vec<Manifold>,
}

impl Island {
    /// Fills the island from `problem`, the world's `start` impulses (N·s per step) divided
    /// among `substeps` substeps, and the step's `dt` and `gravity`.
    ///
    /// The problem's velocities already hold the whole step's gravity (`v = v₀ + dt g`, the
    /// world's IntegrateVelocities stage); the soft step applies gravity per substep
    /// (`h g` each), so it is taken back out here: `v₀ = v − dt g` for every body with a
    /// positive inverse mass.
    ///
    /// A start outside the friction cone is projected onto it (`λn ≥ 0`, `|λt| ≤ μ λn`); a
    /// non-finite one is an error.
    pub(crate) fn prepare(
        &mut self,
        problem: &ContactProblem,
        start: &[Impulse],
        substeps: u32,
        dt: Real,
        gravity: Vector,
        softness: &ContactSoftness,
    ) -> Result<(), CoreError> {
        if let Some(i) = start.iter().position(|s| !s.is_finite()) {
            return Err(CoreError::Solver {
                solver: "soft".into(),
                reason: format!("non-finite start impulse at point {i}"),
            });
        }
        self.bodies.clear();
        self.bodies.extend(problem.bodies.iter().map(|b| {
            let gravity_acts = b.inv_mass > 0.0;
            BodyState {
                v: if gravity_acts {
                    b.linear_velocity - dt * gravity
                } else {
                    b.linear_velocity
                },
                w: b.angular_velocity,
                dp: Vector::zeros(),
                dq: 0.0,
                dq_sin: 0.0,
                dq_cos: 1.0,
                inv_mass: b.inv_mass,
                inv_inertia: b.inv_inertia,
                gravity: gravity_acts,
            }
        }));
        let per_substep = 1.0 / Real::from(substeps);
        self.points.clear();
        self.points
            .extend(problem.points.iter().zip(start).map(|(p, s)| {
                let t = p.tangent();
                let normal = s.normal.max(0.0) * per_substep;
                let bound = p.friction * normal;
                Point {
                    r_a: p.r_a,
                    r_b: p.r_b,
                    rn_a: cross(&p.r_a, &p.normal),
                    rn_b: cross(&p.r_b, &p.normal),
                    rt_a: cross(&p.r_a, &t),
                    rt_b: cross(&p.r_b, &t),
                    normal_dir: p.normal,
                    tangent_dir: t,
                    base_separation: p.separation - (p.r_b - p.r_a).dot(&p.normal),
                    normal_mass: p.normal_mass,
                    tangent_mass: p.tangent_mass,
                    friction: p.friction,
                    restitution_target: p.velocity_bias,
                    normal,
                    tangent: (s.tangent * per_substep).max(-bound).min(bound),
                    total_normal: 0.0,
                    total_tangent: 0.0,
                }
            }));
        let fixed = |b: &ProblemBody| b.inv_mass == 0.0 && b.inv_inertia == 0.0;
        self.manifolds.clear();
        for &(start, end) in &problem.manifolds {
            if end == start {
                continue;
            }
            let p = &problem.points[start as usize];
            let (a, b) = (
                &problem.bodies[p.body_a as usize],
                &problem.bodies[p.body_b as usize],
            );
            self.manifolds.push(Manifold {
                a: p.body_a,
                b: p.body_b,
                start,
                end,
                softness: if fixed(a) || fixed(b) {
                    softness.fixed
                } else {
                    softness.contact
                },
            });
        }
        Ok(())
    }
}
