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
    let (s, c) = sin_cos(angle);
    rotate_sin_cos(v, s, c)
}

/// Below this magnitude (2⁻²⁷ rad) the sine of an angle rounds to the angle itself and its
/// cosine to 1: the next terms, x³/6 and x²/2, are under half a unit in the last place.
const TINY_ANGLE: Real = 7.450_580_596_923_828e-9;

/// `(sin angle, cos angle)`, the bits of [`f64::sin_cos`]. Under 2⁻²⁷ rad the correctly
/// rounded values `(angle, 1)` are returned without the library call: glibc's and musl's
/// `sincos` return the same there, after saving and restoring the rounding mode, which costs
/// more than the rest of the call on some CPUs. The position pass rotates anchors by the
/// small angles its corrections turn a body through, most of them in that range.
#[inline(always)]
pub fn sin_cos(angle: Real) -> (Real, Real) {
    if angle.abs() < TINY_ANGLE {
        (angle, 1.0)
    } else {
        angle.sin_cos()
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiny_angle_sin_cos_has_the_bits_of_the_library() {
        // Both sides of the 2⁻²⁷ cut, zeros of both signs, subnormals, a NaN and ordinary
        // angles; a sweep of the tiny range in steps of a power of two.
        let mut angles = vec![
            0.0,
            -0.0,
            Real::MIN_POSITIVE / 4.0,
            TINY_ANGLE,
            -TINY_ANGLE,
            TINY_ANGLE.next_down(),
            -TINY_ANGLE.next_down(),
            TINY_ANGLE.next_up(),
            Real::NAN,
            0.3,
            -2.5,
        ];
        let mut x = TINY_ANGLE.next_down();
        while x > 1e-300 {
            angles.extend([x, -x, x * 0.7, -x * 0.9]);
            x /= 3.0;
        }
        let mut shortcut = 0;
        for angle in angles {
            let (s, c) = sin_cos(angle);
            let (ls, lc) = angle.sin_cos();
            assert_eq!(
                (s.to_bits(), c.to_bits()),
                (ls.to_bits(), lc.to_bits()),
                "angle {angle:e}"
            );
            shortcut += usize::from(angle.abs() < TINY_ANGLE);
        }
        assert!(shortcut > 100, "the shortcut was taken {shortcut} times");
    }
}
