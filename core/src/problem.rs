//! [`ContactProblem`]: everything a velocity or position solver needs, and nothing of the world.
//!
//! A foreign engine can build one by hand with [`ContactProblem::add_body`] and
//! [`ContactProblem::add_point`], which derive the anchors and effective masses.

use crate::contact::ContactId;
use crate::error::CoreError;
use crate::math::{Real, Vector, cross};

/// A body as the solver sees it (local to one problem).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProblemBody {
    /// Index of the body in the world it came from (`u32::MAX` if none).
    pub world_index: u32,
    /// Centre of mass at the time the contacts were computed.
    pub position: Vector,
    /// Orientation at the time the contacts were computed.
    pub angle: Real,
    /// Linear velocity before the contact solve (gravity already applied).
    pub linear_velocity: Vector,
    /// Angular velocity before the contact solve.
    pub angular_velocity: Real,
    /// Inverse mass (0 = immovable).
    pub inv_mass: Real,
    /// Inverse moment of inertia (0 = cannot rotate).
    pub inv_inertia: Real,
}

/// One contact point: one normal row and one friction row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPoint {
    /// Identity across steps.
    pub id: ContactId,
    /// Index of body A in [`ContactProblem::bodies`].
    pub body_a: u32,
    /// Index of body B in [`ContactProblem::bodies`].
    pub body_b: u32,
    /// Contact point in world coordinates.
    pub point: Vector,
    /// Unit normal pointing from A to B.
    pub normal: Vector,
    /// Anchor `point - position_a`.
    pub r_a: Vector,
    /// Anchor `point - position_b`.
    pub r_b: Vector,
    /// Signed distance (negative = penetration).
    pub separation: Real,
    /// Mixed friction coefficient.
    pub friction: Real,
    /// Mixed restitution.
    pub restitution: Real,
    /// Target normal velocity from restitution (`-e vn` above the threshold, else 0).
    pub velocity_bias: Real,
    /// `1 / (mA + mB + iA (rA×n)² + iB (rB×n)²)`.
    pub normal_mass: Real,
    /// Same with the tangent `t = (-n.y, n.x)`.
    pub tangent_mass: Real,
    /// Index of the manifold (pair) this point belongs to; points of one manifold are contiguous.
    pub manifold: u32,
}

impl ContactPoint {
    /// Unit tangent `(-n.y, n.x)`, the direction of the tangent impulse.
    #[inline]
    pub fn tangent(&self) -> Vector {
        Vector::new(-self.normal.y, self.normal.x)
    }
}

/// The contact problem of one island.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContactProblem {
    /// Bodies referenced by the points (static ones included with zero inverse mass).
    pub bodies: Vec<ProblemBody>,
    /// Contact points, grouped by manifold.
    pub points: Vec<ContactPoint>,
    /// `[start, end)` ranges of `points`, one per manifold (1 or 2 points each).
    pub manifolds: Vec<(u32, u32)>,
}

impl ContactProblem {
    /// An empty problem.
    pub fn new() -> Self {
        Self::default()
    }

    /// Empties the problem, keeping its allocations.
    pub fn clear(&mut self) {
        self.bodies.clear();
        self.points.clear();
        self.manifolds.clear();
    }

    /// Number of contact points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no contact points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Adds a body and returns its index in this problem.
    pub fn add_body(&mut self, body: ProblemBody) -> u32 {
        self.bodies.push(body);
        (self.bodies.len() - 1) as u32
    }

    /// Adds a point of the manifold currently being built (call [`Self::begin_manifold`] first),
    /// deriving anchors, effective masses and the restitution bias
    /// (threshold `restitution_threshold` m/s, Box2D uses 1).
    ///
    /// # Panics
    /// If `body_a` or `body_b` is not the index of a body already added with
    /// [`Self::add_body`] (a programming error, like an out-of-range slice index).
    /// Problems from untrusted sources should be checked with [`Self::validate`].
    #[allow(clippy::too_many_arguments)]
    pub fn add_point(
        &mut self,
        id: ContactId,
        body_a: u32,
        body_b: u32,
        point: Vector,
        normal: Vector,
        separation: Real,
        friction: Real,
        restitution: Real,
        restitution_threshold: Real,
    ) {
        let a = self.bodies[body_a as usize];
        let b = self.bodies[body_b as usize];
        let r_a = point - a.position;
        let r_b = point - b.position;
        let tangent = Vector::new(-normal.y, normal.x);
        let k = |d: &Vector| {
            let (ra, rb) = (cross(&r_a, d), cross(&r_b, d));
            a.inv_mass + b.inv_mass + a.inv_inertia * ra * ra + b.inv_inertia * rb * rb
        };
        let (kn, kt) = (k(&normal), k(&tangent));
        // Relative normal velocity before the solve, for restitution.
        let dv = b.linear_velocity + crate::math::cross_sv(b.angular_velocity, &r_b)
            - a.linear_velocity
            - crate::math::cross_sv(a.angular_velocity, &r_a);
        let vn = dv.dot(&normal);
        let velocity_bias = if vn < -restitution_threshold {
            -restitution * vn
        } else {
            0.0
        };
        let manifold = self.manifolds.len().saturating_sub(1) as u32;
        self.points.push(ContactPoint {
            id,
            body_a,
            body_b,
            point,
            normal,
            r_a,
            r_b,
            separation,
            friction,
            restitution,
            velocity_bias,
            normal_mass: if kn > 0.0 { 1.0 / kn } else { 0.0 },
            tangent_mass: if kt > 0.0 { 1.0 / kt } else { 0.0 },
            manifold,
        });
        if let Some(m) = self.manifolds.last_mut() {
            m.1 = self.points.len() as u32;
        }
    }

    /// Starts a new manifold; the following [`Self::add_point`] calls belong to it.
    pub fn begin_manifold(&mut self) {
        let n = self.points.len() as u32;
        self.manifolds.push((n, n));
    }

    /// Checks indices, finiteness and ranges; solvers call this on foreign input.
    pub fn validate(&self) -> Result<(), CoreError> {
        let nb = self.bodies.len() as u32;
        for (i, b) in self.bodies.iter().enumerate() {
            let vals = [
                b.position.x,
                b.position.y,
                b.angle,
                b.linear_velocity.x,
                b.linear_velocity.y,
                b.angular_velocity,
                b.inv_mass,
                b.inv_inertia,
            ];
            if vals.iter().any(|v| !v.is_finite()) || b.inv_mass < 0.0 || b.inv_inertia < 0.0 {
                return Err(CoreError::InvalidProblem(format!(
                    "body {i} has a non-finite or negative value"
                )));
            }
        }
        let mut covered = 0u32;
        for (m, &(s, e)) in self.manifolds.iter().enumerate() {
            if s != covered || e < s || e - s > 2 || e as usize > self.points.len() {
                return Err(CoreError::InvalidProblem(format!(
                    "manifold {m} has bad range {s}..{e}"
                )));
            }
            covered = e;
        }
        if covered as usize != self.points.len() {
            return Err(CoreError::InvalidProblem(format!(
                "manifolds cover {covered} of {} points",
                self.points.len()
            )));
        }
        for (i, p) in self.points.iter().enumerate() {
            if p.body_a >= nb || p.body_b >= nb || p.body_a == p.body_b {
                return Err(CoreError::InvalidProblem(format!(
                    "point {i} has bad body indices"
                )));
            }
            let vals = [
                p.normal.x,
                p.normal.y,
                p.r_a.x,
                p.r_a.y,
                p.r_b.x,
                p.r_b.y,
                p.separation,
                p.friction,
                p.velocity_bias,
                p.normal_mass,
                p.tangent_mass,
            ];
            if vals.iter().any(|v| !v.is_finite()) {
                return Err(CoreError::InvalidProblem(format!(
                    "point {i} has a non-finite value"
                )));
            }
            if p.friction < 0.0 || p.normal_mass < 0.0 || p.tangent_mass < 0.0 {
                return Err(CoreError::InvalidProblem(format!(
                    "point {i} has a negative friction or mass"
                )));
            }
            if (p.normal.norm() - 1.0).abs() > 1e-3 {
                return Err(CoreError::InvalidProblem(format!(
                    "point {i} normal is not unit length"
                )));
            }
        }
        Ok(())
    }
}
