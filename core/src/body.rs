//! Rigid bodies.

use crate::error::CoreError;
use crate::math::{Real, Vector};
use crate::shape::ShapeDesc;
use parry2d::shape::SharedShape;

/// Index of a body in its [`World`](crate::World); handles are never reused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BodyHandle(pub u32);

/// How a body moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodyKind {
    /// Moved by forces and contacts; mass from shape × density.
    Dynamic,
    /// Never moves; infinite mass.
    Static,
    /// Moves with its prescribed velocity; infinite mass.
    Kinematic,
}

/// Surface properties. Friction mixes as `sqrt(μ1 μ2)`, restitution as `max`, as in Box2D.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Density in kg/m² (default 1; only dynamic bodies use it).
    pub density: Real,
    /// Coulomb friction coefficient (default 0.5).
    pub friction: Real,
    /// Restitution (default 0).
    pub restitution: Real,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            density: 1.0,
            friction: 0.5,
            restitution: 0.0,
        }
    }
}

/// Everything needed to add a body to a world.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyDesc {
    /// Dynamic, static or kinematic.
    pub kind: BodyKind,
    /// Collision shape in the body frame.
    pub shape: ShapeDesc,
    /// Density, friction, restitution.
    pub material: Material,
    /// Position of the body frame's origin (default 0).
    pub position: Vector,
    /// Orientation in radians (default 0).
    pub angle: Real,
    /// Initial linear velocity (default 0).
    pub linear_velocity: Vector,
    /// Initial angular velocity (default 0).
    pub angular_velocity: Real,
}

impl BodyDesc {
    /// A dynamic body with the default material at `position`.
    pub fn dynamic(shape: ShapeDesc, position: Vector) -> Self {
        Self {
            kind: BodyKind::Dynamic,
            shape,
            material: Material::default(),
            position,
            angle: 0.0,
            linear_velocity: Vector::zeros(),
            angular_velocity: 0.0,
        }
    }

    /// A static body with the default material at `position`.
    pub fn fixed(shape: ShapeDesc, position: Vector) -> Self {
        Self {
            kind: BodyKind::Static,
            ..Self::dynamic(shape, position)
        }
    }

    /// Replaces the material.
    pub fn with_material(mut self, material: Material) -> Self {
        self.material = material;
        self
    }

    /// Replaces the angle.
    pub fn with_angle(mut self, angle: Real) -> Self {
        self.angle = angle;
        self
    }
}

/// A body of a world. The position is that of the centre of mass.
#[derive(Debug, Clone)]
pub struct Body {
    /// Dynamic, static or kinematic.
    pub kind: BodyKind,
    /// The shape as described.
    pub shape_desc: ShapeDesc,
    pub(crate) shape: SharedShape,
    /// Surface properties.
    pub material: Material,
    /// Centre of mass in world coordinates.
    pub position: Vector,
    /// Orientation in radians.
    pub angle: Real,
    /// Linear velocity of the centre of mass.
    pub linear_velocity: Vector,
    /// Angular velocity.
    pub angular_velocity: Real,
    /// Mass (0 for static and kinematic bodies).
    pub mass: Real,
    /// Inverse mass (0 for static and kinematic bodies).
    pub inv_mass: Real,
    /// Moment of inertia about the centre of mass.
    pub inertia: Real,
    /// Inverse moment of inertia.
    pub inv_inertia: Real,
    /// Centre of mass in the body frame (the shape is offset by its negation).
    pub local_com: Vector,
}

impl Body {
    /// The body's state as `[x, y, angle, vx, vy, ω]`: what determinism hashes and
    /// finiteness checks read.
    pub fn state(&self) -> [Real; 6] {
        [
            self.position.x,
            self.position.y,
            self.angle,
            self.linear_velocity.x,
            self.linear_velocity.y,
            self.angular_velocity,
        ]
    }

    pub(crate) fn from_desc(desc: &BodyDesc, index: usize) -> Result<Self, CoreError> {
        let bad = |field, value: Real, reason| CoreError::InvalidBodyParameter {
            body: index,
            field,
            value,
            reason,
        };
        let m = &desc.material;
        if !(m.friction.is_finite() && m.friction >= 0.0) {
            return Err(bad("friction", m.friction, "must be finite and >= 0"));
        }
        if !(m.restitution.is_finite() && m.restitution >= 0.0) {
            return Err(bad("restitution", m.restitution, "must be finite and >= 0"));
        }
        for (field, v) in [
            ("position.x", desc.position.x),
            ("position.y", desc.position.y),
            ("angle", desc.angle),
            ("linear_velocity.x", desc.linear_velocity.x),
            ("linear_velocity.y", desc.linear_velocity.y),
            ("angular_velocity", desc.angular_velocity),
        ] {
            if !v.is_finite() {
                return Err(bad(field, v, "must be finite"));
            }
        }
        let shape = desc.shape.build(index)?;
        let (mut mass, mut inertia, mut local_com) = (0.0, 0.0, Vector::zeros());
        if desc.kind == BodyKind::Dynamic {
            if !(m.density.is_finite() && m.density > 0.0) {
                return Err(bad(
                    "density",
                    m.density,
                    "must be finite and > 0 for a dynamic body",
                ));
            }
            if !desc.shape.is_solid() {
                return Err(bad(
                    "density",
                    m.density,
                    "a dynamic body needs a shape with area",
                ));
            }
            (mass, inertia, local_com) = crate::shape::mass_properties(&shape, m.density);
            if !(mass.is_finite() && mass > 0.0 && inertia.is_finite() && inertia > 0.0) {
                return Err(bad("mass", mass, "shape gives no positive mass / inertia"));
            }
        }
        let inv = |x: Real| if x > 0.0 { 1.0 / x } else { 0.0 };
        let position = desc.position + crate::math::rotate(&local_com, desc.angle);
        Ok(Self {
            kind: desc.kind,
            shape_desc: desc.shape.clone(),
            shape,
            material: *m,
            position,
            angle: desc.angle,
            linear_velocity: if desc.kind == BodyKind::Static {
                Vector::zeros()
            } else {
                desc.linear_velocity
            },
            angular_velocity: if desc.kind == BodyKind::Static {
                0.0
            } else {
                desc.angular_velocity
            },
            mass,
            inv_mass: inv(mass),
            inertia,
            inv_inertia: inv(inertia),
            local_com,
        })
    }

    /// The parry2d shape (in the body frame, origin at the reference point).
    pub fn shape(&self) -> &SharedShape {
        &self.shape
    }

    /// Position of the body frame's origin (the reference point the shape is described in).
    pub fn origin(&self) -> Vector {
        self.position - crate::math::rotate(&self.local_com, self.angle)
    }

    /// Whether the body is dynamic.
    pub fn is_dynamic(&self) -> bool {
        self.kind == BodyKind::Dynamic
    }

    /// Kinetic energy `½ m v² + ½ I ω²`.
    pub fn kinetic_energy(&self) -> Real {
        0.5 * self.mass * self.linear_velocity.norm_squared()
            + 0.5 * self.inertia * self.angular_velocity.powi(2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{World, WorldSettings};

    #[test]
    fn add_body_refuses_a_nan_position_at_once() {
        let ball = || BodyDesc::dynamic(ShapeDesc::Ball { radius: 0.5 }, Vector::zeros());
        let material = |f: fn(&mut Material)| {
            let mut m = Material::default();
            f(&mut m);
            ball().with_material(m)
        };
        let cases: Vec<(&str, BodyDesc)> = vec![
            (
                "position.x",
                BodyDesc {
                    position: Vector::new(Real::NAN, 0.0),
                    ..ball()
                },
            ),
            (
                "position.y",
                BodyDesc {
                    position: Vector::new(0.0, Real::INFINITY),
                    ..ball()
                },
            ),
            ("angle", ball().with_angle(Real::NAN)),
            (
                "linear_velocity.x",
                BodyDesc {
                    linear_velocity: Vector::new(Real::NEG_INFINITY, 0.0),
                    ..ball()
                },
            ),
            (
                "linear_velocity.y",
                BodyDesc {
                    linear_velocity: Vector::new(0.0, Real::NAN),
                    ..ball()
                },
            ),
            (
                "angular_velocity",
                BodyDesc {
                    angular_velocity: Real::NAN,
                    ..ball()
                },
            ),
            ("friction", material(|m| m.friction = Real::INFINITY)),
            ("restitution", material(|m| m.restitution = -0.5)),
            ("restitution", material(|m| m.restitution = Real::NAN)),
            ("density", material(|m| m.density = 0.0)),
            (
                "radius",
                BodyDesc::dynamic(ShapeDesc::Ball { radius: Real::NAN }, Vector::zeros()),
            ),
        ];
        let mut world = World::new(WorldSettings::default()).unwrap();
        world.add_body(&ball()).unwrap();
        for (field, desc) in &cases {
            let err = world.add_body(desc).unwrap_err();
            assert!(
                matches!(err, CoreError::InvalidBodyParameter { body: 1, field: f, .. } if f == *field),
                "{field}: {err}"
            );
            // Refused at once: the world still holds the one good body.
            assert_eq!(world.bodies().len(), 1, "{field}");
            let err =
                World::with_bodies(WorldSettings::default(), &[ball(), desc.clone()]).unwrap_err();
            assert!(
                matches!(err, CoreError::InvalidBodyParameter { body: 1, field: f, .. } if f == *field),
                "with_bodies, {field}: {err}"
            );
        }
        // Every case was reached, and a good body is still accepted after the refusals.
        assert_eq!(cases.len(), 11);
        assert_eq!(world.add_body(&ball()).unwrap(), BodyHandle(1));
    }
}
