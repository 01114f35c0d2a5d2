//! [`ContactProblem`]: everything a velocity or position solver needs, and nothing of the world.
//!
//! A foreign engine can build one by hand with [`ContactProblem::add_body`],
//! [`ContactProblem::begin_manifold`] and [`ContactProblem::add_point`], which derive the
//! anchors and effective masses.
//!
//! **Units and signs.** Lengths in m, velocities in m/s and rad/s, impulses in N·s. Each
//! point has a unit normal `n` pointing from body A to body B; a normal impulse `λn ≥ 0`
//! pushes B along `+n` and A along `−n` (contacts only push). The tangent is
//! `t = (−n.y, n.x)` (`n` turned a quarter counter-clockwise); a positive tangent impulse
//! pushes B along `+t`. Friction bounds `|λt| ≤ μ λn`.
//!
//! **A worked example:** three unit boxes stacked on the ground, falling at one step of
//! gravity. Hand-built problems need no world ([`ProblemBody::NO_WORLD`] is the world index
//! of their bodies) and no real [`ContactId`]s: solvers never read the ids; only a
//! [`crate::World`] matches them between steps.
//!
//! ```
//! use deepcontact_core::{ContactProblem, PointDesc, ProblemBody, Vector};
//!
//! let mut problem = ContactProblem::new();
//! let ground = problem.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
//! let falling = Vector::new(0.0, -0.0981); // one step of gravity at dt = 0.01
//! let boxes: Vec<u32> = (0..3)
//!     .map(|i| {
//!         let centre = Vector::new(0.0, 0.5 + i as f64);
//!         problem.add_body(ProblemBody::dynamic(centre, 0.0, falling, 0.0, 1.0, 1.0 / 6.0))
//!     })
//!     .collect();
//! for (below, above) in [(ground, boxes[0]), (boxes[0], boxes[1]), (boxes[1], boxes[2])] {
//!     let y = problem.bodies[above as usize].position.y - 0.5;
//!     problem.begin_manifold();
//!     for x in [-0.5, 0.5] {
//!         // The normal points from the body below (A) up to the body above (B).
//!         let desc = PointDesc::new(below, above, Vector::new(x, y), Vector::new(0.0, 1.0))
//!             .friction(0.5);
//!         problem.add_point(&desc).unwrap();
//!     }
//! }
//! assert_eq!(problem.len(), 6);
//! assert!(problem.validate().is_ok());
//! ```

use crate::contact::ContactId;
use crate::error::CoreError;
use crate::math::{Real, Vector, Velocity, cross, cross_sv};

/// A body as the solver sees it (local to one problem).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProblemBody {
    /// Index of the body in the world it came from ([`Self::NO_WORLD`] if none).
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

impl ProblemBody {
    /// The world index of a body that does not come from a [`crate::World`].
    pub const NO_WORLD: u32 = u32::MAX;

    /// An immovable body (zero inverse mass and inertia, at rest) at `position`.
    pub fn fixed(position: Vector) -> Self {
        Self {
            world_index: Self::NO_WORLD,
            position,
            angle: 0.0,
            linear_velocity: Vector::zeros(),
            angular_velocity: 0.0,
            inv_mass: 0.0,
            inv_inertia: 0.0,
        }
    }

    /// A moving body: centre of mass `position` (m), orientation `angle` (rad), velocities
    /// before the contact solve (m/s, rad/s), mass (kg) and moment of inertia (kg·m²);
    /// a mass or inertia of 0 or less, or infinite, gives an inverse of 0 (cannot move /
    /// cannot rotate).
    pub fn dynamic(
        position: Vector,
        angle: Real,
        linear_velocity: Vector,
        angular_velocity: Real,
        mass: Real,
        inertia: Real,
    ) -> Self {
        let inverse = |m: Real| {
            if m > 0.0 && m.is_finite() {
                1.0 / m
            } else {
                0.0
            }
        };
        Self {
            world_index: Self::NO_WORLD,
            position,
            angle,
            linear_velocity,
            angular_velocity,
            inv_mass: inverse(mass),
            inv_inertia: inverse(inertia),
        }
    }

    /// The same body tagged with its index in a world.
    pub fn with_world_index(mut self, index: u32) -> Self {
        self.world_index = index;
        self
    }
}

/// Everything [`ContactProblem::add_point`] needs for one point; anchors, effective masses
/// and the restitution bias are derived from it and the bodies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointDesc {
    /// Identity across steps, used only by a world to carry impulses (default from
    /// [`PointDesc::new`]: the ordered body pair, features 0).
    pub id: ContactId,
    /// Index of body A in [`ContactProblem::bodies`].
    pub body_a: u32,
    /// Index of body B in [`ContactProblem::bodies`].
    pub body_b: u32,
    /// Contact point in world coordinates (m).
    pub point: Vector,
    /// Unit normal pointing from A to B.
    pub normal: Vector,
    /// Signed distance, negative = penetration (m; default 0).
    pub separation: Real,
    /// Friction coefficient, already mixed (default 0.5, the thesis's).
    pub friction: Real,
    /// Restitution, already mixed (default 0).
    pub restitution: Real,
    /// Closing speed above which restitution applies (m/s; default 1, Box2D's).
    pub restitution_threshold: Real,
}

impl PointDesc {
    /// A point between bodies `body_a` and `body_b` at `point` with normal `normal` (from A to
    /// B), touching (separation 0), friction 0.5, no restitution.
    pub fn new(body_a: u32, body_b: u32, point: Vector, normal: Vector) -> Self {
        Self {
            id: ContactId {
                body_a: body_a.min(body_b),
                body_b: body_a.max(body_b),
                feature_a: 0,
                feature_b: 0,
            },
            body_a,
            body_b,
            point,
            normal,
            separation: 0.0,
            friction: 0.5,
            restitution: 0.0,
            restitution_threshold: 1.0,
        }
    }
    /// Sets the id.
    pub fn id(mut self, id: ContactId) -> Self {
        self.id = id;
        self
    }
    /// Sets the separation (m, negative = penetration).
    pub fn separation(mut self, separation: Real) -> Self {
        self.separation = separation;
        self
    }
    /// Sets the friction coefficient.
    pub fn friction(mut self, friction: Real) -> Self {
        self.friction = friction;
        self
    }
    /// Sets the restitution and its threshold speed (m/s).
    pub fn restitution(mut self, restitution: Real, threshold: Real) -> Self {
        self.restitution = restitution;
        self.restitution_threshold = threshold;
        self
    }
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

    /// Velocity of body B against body A at point `i` (m/s), from the bodies' velocities as
    /// they are in the problem (before the solve): `vB + ωB × rB − vA − ωA × rA`.
    ///
    /// # Panics
    /// If `i` is not a point of the problem.
    pub fn relative_velocity(&self, i: usize) -> Vector {
        let p = &self.points[i];
        let (a, b) = (
            &self.bodies[p.body_a as usize],
            &self.bodies[p.body_b as usize],
        );
        (b.linear_velocity + cross_sv(b.angular_velocity, &p.r_b))
            - (a.linear_velocity + cross_sv(a.angular_velocity, &p.r_a))
    }

    /// [`Self::relative_velocity`] with the bodies moving at `velocities` (one per body of the
    /// problem, e.g. a solve's result) instead of the problem's own, m/s; `None` when `i` or
    /// one of its bodies is out of range.
    pub fn relative_velocity_with(&self, i: usize, velocities: &[Velocity]) -> Option<Vector> {
        let p = self.points.get(i)?;
        let a = velocities.get(p.body_a as usize)?;
        let b = velocities.get(p.body_b as usize)?;
        Some((b.linear + cross_sv(b.angular, &p.r_b)) - (a.linear + cross_sv(a.angular, &p.r_a)))
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

    /// Adds a point to the manifold begun by the last [`Self::begin_manifold`], deriving
    /// anchors, effective masses and the restitution bias; returns the point's index.
    ///
    /// Checked here, so that a mistake is reported where it is made: a manifold was begun, is
    /// still open (the last range of [`Self::manifolds`] ends at this point: one edited by
    /// hand is refused) and has fewer than 2 points, both bodies exist and differ, the values
    /// are finite, the normal has unit length (within 1e-3), friction and restitution are ≥ 0.
    /// The direction of the normal cannot be checked (a wall's centre says nothing about its
    /// side): it must point from A to B.
    pub fn add_point(&mut self, desc: &PointDesc) -> Result<u32, CoreError> {
        let index = self.points.len();
        let bad = |why: &str| Err(CoreError::InvalidProblem(format!("point {index}: {why}")));
        match self.manifolds.last() {
            None => return bad("add_point before begin_manifold"),
            Some(&(start, end)) if start > end || end as usize != index => {
                return bad(&format!(
                    "the last manifold's range {start}..{end} does not end at this point \
                     (edited by hand? call begin_manifold)"
                ));
            }
            Some(&(start, end)) if end - start >= 2 => {
                return bad("a manifold has at most 2 points (call begin_manifold)");
            }
            Some(_) => {}
        }
        let nb = self.bodies.len() as u32;
        if desc.body_a >= nb || desc.body_b >= nb || desc.body_a == desc.body_b {
            return bad(&format!(
                "bodies {} and {} (the problem has {nb}; they must differ)",
                desc.body_a, desc.body_b
            ));
        }
        let d = desc;
        let values = [
            d.point.x,
            d.point.y,
            d.normal.x,
            d.normal.y,
            d.separation,
            d.friction,
            d.restitution,
            d.restitution_threshold,
        ];
        if values.iter().any(|v| !v.is_finite()) {
            return bad("a non-finite value");
        }
        if (d.normal.norm() - 1.0).abs() > 1e-3 {
            return bad(&format!("normal {:?} is not unit length", d.normal));
        }
        if d.friction < 0.0 || d.restitution < 0.0 || d.restitution_threshold < 0.0 {
            return bad("negative friction, restitution or threshold");
        }
        let PointDesc {
            id,
            body_a,
            body_b,
            point,
            normal,
            separation,
            friction,
            restitution,
            restitution_threshold,
        } = *desc;
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
        Ok(index as u32)
    }

    /// Starts a new manifold; the following [`Self::add_point`] calls belong to it.
    pub fn begin_manifold(&mut self) {
        let n = self.points.len() as u32;
        self.manifolds.push((n, n));
    }

    /// Checks indices, finiteness and ranges; solvers call this on foreign input.
    pub fn validate(&self) -> Result<(), CoreError> {
        if self.is_valid() {
            return Ok(());
        }
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

    /// The checks of [`Self::validate`] without its early exits (one branch-free pass over
    /// the data; every solve of a valid problem takes this path): whether it would return `Ok`.
    fn is_valid(&self) -> bool {
        let finite = |v: Real| v.is_finite();
        let mut ok = true;
        for b in &self.bodies {
            ok &= finite(b.position.x)
                & finite(b.position.y)
                & finite(b.angle)
                & finite(b.linear_velocity.x)
                & finite(b.linear_velocity.y)
                & finite(b.angular_velocity)
                & finite(b.inv_mass)
                & finite(b.inv_inertia)
                & (b.inv_mass >= 0.0)
                & (b.inv_inertia >= 0.0);
        }
        let mut covered = 0u32;
        for &(s, e) in &self.manifolds {
            ok &= (s == covered)
                & (e >= s)
                & (e.wrapping_sub(s) <= 2)
                & (e as usize <= self.points.len());
            covered = e;
        }
        ok &= covered as usize == self.points.len();
        let nb = self.bodies.len() as u32;
        for p in &self.points {
            ok &= (p.body_a < nb)
                & (p.body_b < nb)
                & (p.body_a != p.body_b)
                & finite(p.normal.x)
                & finite(p.normal.y)
                & finite(p.r_a.x)
                & finite(p.r_a.y)
                & finite(p.r_b.x)
                & finite(p.r_b.y)
                & finite(p.separation)
                & finite(p.friction)
                & finite(p.velocity_bias)
                & finite(p.normal_mass)
                & finite(p.tangent_mass)
                & (p.friction >= 0.0)
                & (p.normal_mass >= 0.0)
                & (p.tangent_mass >= 0.0)
                & ((p.normal.norm() - 1.0).abs() <= 1e-3);
        }
        ok
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_bodies() -> ContactProblem {
        let mut p = ContactProblem::new();
        p.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
        let v = Vector::new(0.0, -0.1);
        p.add_body(ProblemBody::dynamic(
            Vector::new(0.0, 0.5),
            0.0,
            v,
            0.0,
            1.0,
            0.2,
        ));
        p
    }

    fn up() -> PointDesc {
        PointDesc::new(0, 1, Vector::zeros(), Vector::new(0.0, 1.0))
    }

    /// Body B (centre 0.5 m above the point) falls at 0.1 m/s and spins at 2 rad/s: at the
    /// point, ω × r adds (−2 × (−0.5), 0) = (1, 0) m/s; body A is fixed.
    #[test]
    fn relative_velocity_adds_the_spin_at_the_point() {
        let mut p = two_bodies();
        p.bodies[1].angular_velocity = 2.0;
        p.begin_manifold();
        p.add_point(&up()).unwrap();
        let v = p.relative_velocity(0);
        assert!((v - Vector::new(1.0, -0.1)).norm() < 1e-12, "{v:?}");
    }

    #[test]
    fn add_point_before_begin_manifold_is_an_error_naming_it() {
        let mut p = two_bodies();
        let err = p.add_point(&up()).unwrap_err().to_string();
        assert!(err.contains("begin_manifold"), "{err}");
        assert!(p.points.is_empty());
    }

    #[test]
    fn add_point_refuses_unknown_or_equal_bodies_bad_normals_and_third_points() {
        let mut p = two_bodies();
        p.begin_manifold();
        let unknown = PointDesc::new(0, 7, Vector::zeros(), Vector::new(0.0, 1.0));
        assert!(
            p.add_point(&unknown)
                .unwrap_err()
                .to_string()
                .contains("bodies 0 and 7")
        );
        let same = PointDesc::new(1, 1, Vector::zeros(), Vector::new(0.0, 1.0));
        assert!(p.add_point(&same).is_err());
        let long = PointDesc::new(0, 1, Vector::zeros(), Vector::new(0.0, 2.0));
        assert!(
            p.add_point(&long)
                .unwrap_err()
                .to_string()
                .contains("unit length")
        );
        let nan = up().separation(Real::NAN);
        assert!(p.add_point(&nan).is_err());
        let negative = up().friction(-0.1);
        assert!(p.add_point(&negative).is_err());
        assert_eq!(p.add_point(&up()).unwrap(), 0);
        assert_eq!(p.add_point(&up()).unwrap(), 1);
        assert!(
            p.add_point(&up())
                .unwrap_err()
                .to_string()
                .contains("at most 2")
        );
        assert!(p.validate().is_ok());
    }

    #[test]
    fn point_desc_derives_masses_and_the_restitution_bias() {
        let mut p = two_bodies();
        p.begin_manifold();
        let desc = up().restitution(0.5, 0.05);
        p.add_point(&desc).unwrap();
        let point = p.points[0];
        // Body B (mass 1) at (0, 0.5), the point below its centre: no rotation along n.
        assert!((point.normal_mass - 1.0).abs() < 1e-12);
        // Closing at 0.1 m/s above the 0.05 m/s threshold: bias = -e vn = 0.05.
        assert!((point.velocity_bias - 0.05).abs() < 1e-12);
        assert_eq!(p.bodies[1].world_index, ProblemBody::NO_WORLD);
    }

    #[test]
    fn the_branch_free_check_refuses_every_problem_validate_refuses() {
        let mut valid = two_bodies();
        valid.begin_manifold();
        valid.add_point(&up()).unwrap();
        valid.add_point(&up()).unwrap();
        assert!(valid.is_valid() && valid.validate().is_ok());
        type Corrupt = fn(&mut ContactProblem);
        let corruptions: [(Corrupt, &str); 12] = [
            (|p| p.bodies[1].angle = Real::NAN, "body 1"),
            (|p| p.bodies[1].inv_mass = -1.0, "body 1"),
            (|p| p.bodies[0].inv_inertia = -0.5, "body 0"),
            (|p| p.manifolds[0] = (1, 2), "manifold 0"),
            (|p| p.manifolds[0] = (0, 3), "manifold 0"),
            (|p| p.manifolds[0] = (0, 1), "cover 1 of 2"),
            (|p| p.points[0].body_b = 2, "point 0"),
            (|p| p.points[1].body_a = 1, "point 1"),
            (|p| p.points[1].r_b.y = Real::INFINITY, "point 1"),
            (|p| p.points[0].tangent_mass = -1.0, "point 0"),
            (|p| p.points[1].normal = Vector::new(0.0, 1.01), "point 1"),
            (|p| p.points[0].velocity_bias = Real::NAN, "point 0"),
        ];
        for (corrupt, says) in corruptions {
            let mut p = valid.clone();
            corrupt(&mut p);
            assert!(!p.is_valid(), "{says}");
            let err = p.validate().unwrap_err().to_string();
            assert!(err.contains(says), "{err}");
        }
    }
}
