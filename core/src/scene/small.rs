//! Small scenes for tests: one ball at rest, a box on a slope.

use crate::body::{BodyDesc, Material};
use crate::math::{Real, Vector};
use crate::shape::ShapeDesc;

use super::Scene;
use super::stacked::ground;

/// One circle of radius 0.5 resting on a static ground box.
pub fn resting_ball() -> Scene {
    Scene {
        name: "resting_ball".into(),
        bodies: vec![
            ground(6.0),
            BodyDesc::dynamic(ShapeDesc::Ball { radius: 0.5 }, Vector::new(0.0, 0.5)),
        ],
        min: Vector::new(-3.0, -1.0),
        max: Vector::new(3.0, 2.0),
    }
}

/// A unit box resting on a static slope of `degrees`, friction `friction` on both.
pub fn slope(degrees: Real, friction: Real) -> Scene {
    let angle = degrees.to_radians();
    let material = Material {
        friction,
        ..Material::default()
    };
    let (s, c) = angle.sin_cos();
    // Slope: a long thin static box through the origin, rotated.
    let slope = BodyDesc::fixed(
        ShapeDesc::Cuboid {
            half_width: 10.0,
            half_height: 0.5,
        },
        Vector::new(0.5 * s, -0.5 * c),
    )
    .with_material(material)
    .with_angle(angle);
    // Box on top, centred on the slope's upper surface at the origin.
    let body = BodyDesc::dynamic(
        ShapeDesc::Cuboid {
            half_width: 0.5,
            half_height: 0.5,
        },
        Vector::new(-0.5 * s, 0.5 * c),
    )
    .with_material(material)
    .with_angle(angle);
    Scene {
        name: "slope".into(),
        bodies: vec![slope, body],
        min: Vector::new(-10.0, -8.0),
        max: Vector::new(10.0, 8.0),
    }
}
