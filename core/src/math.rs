//! Scalar and vector types, and the one place where parry2d's glam types meet nalgebra.

/// The scalar type of the whole public API.
pub type Real = f64;
/// A 2D vector (positions, velocities, normals, anchors).
pub type Vector = nalgebra::Vector2<Real>;

/// A body's velocity: linear (m/s) and angular (rad/s, counter-clockwise positive).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Velocity {
    /// Velocity of the centre of mass (m/s).
    pub linear: Vector,
    /// Angular velocity (rad/s).
    pub angular: Real,
}

impl Velocity {
    /// A velocity from its parts.
    pub fn new(linear: Vector, angular: Real) -> Self {
        Self { linear, angular }
    }
}

/// A body's pose: centre of mass (m) and orientation (rad, counter-clockwise positive).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    /// Centre of mass (m).
    pub position: Vector,
    /// Orientation (rad).
    pub angle: Real,
}

impl Pose {
    /// A pose from its parts.
    pub fn new(position: Vector, angle: Real) -> Self {
        Self { position, angle }
    }
}

/// 2D cross product of two vectors: `a.x * b.y - a.y * b.x`.
#[inline(always)]
pub fn cross(a: &Vector, b: &Vector) -> Real {
    a.x * b.y - a.y * b.x
}

/// Cross product of a scalar (angular velocity) with a vector: `w × r = (-w r.y, w r.x)`.
#[inline(always)]
pub fn cross_sv(w: Real, r: &Vector) -> Vector {
    Vector::new(-w * r.y, w * r.x)
}

/// Rotates `v` by `angle` radians.
#[inline(always)]
pub fn rotate(v: &Vector, angle: Real) -> Vector {
    let (s, c) = angle.sin_cos();
    rotate_sin_cos(v, s, c)
}

/// Rotates `v` by the angle whose sine and cosine are `s` and `c` (what [`rotate`] does once
/// it has them).
#[inline(always)]
pub fn rotate_sin_cos(v: &Vector, s: Real, c: Real) -> Vector {
    Vector::new(c * v.x - s * v.y, s * v.x + c * v.y)
}

/// Converts to parry2d's (glam, f32) vector.
#[inline]
pub fn to_parry(v: &Vector) -> parry2d::math::Vector {
    parry2d::math::Vector::new(v.x as f32, v.y as f32)
}

/// Converts from parry2d's (glam, f32) vector.
#[inline]
pub fn from_parry(v: parry2d::math::Vector) -> Vector {
    Vector::new(v.x as Real, v.y as Real)
}

/// A parry2d pose from a position and an angle.
#[inline]
pub fn parry_pose(position: &Vector, angle: Real) -> parry2d::math::Pose {
    parry2d::math::Pose::new(to_parry(position), angle as f32)
}
