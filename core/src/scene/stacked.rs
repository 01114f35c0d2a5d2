//! Boxes stacked on a static ground box: the pyramid, the tall stack and the mass-ratio
//! stack. A seed moves each box sideways by up to `jitter` (default 0: the exact structure).

use crate::body::{BodyDesc, Material};
use crate::error::CoreError;
use crate::math::{Real, Vector};
use crate::rng::PortableRng;
use crate::shape::ShapeDesc;

use super::pile::check_friction;
use super::{MAX_STACK, Scene};

/// Half side of the unit boxes (m).
const HALF: Real = 0.5;

/// A static ground box of `width`, its top face on y = 0.
pub(super) fn ground(width: Real) -> BodyDesc {
    BodyDesc::fixed(
        ShapeDesc::Cuboid {
            half_width: 0.5 * width,
            half_height: 0.5,
        },
        Vector::new(0.0, -0.5),
    )
}

fn unit_box(position: Vector) -> BodyDesc {
    BodyDesc::dynamic(
        ShapeDesc::Cuboid {
            half_width: HALF,
            half_height: HALF,
        },
        position,
    )
}

/// Parameters shared by the stacked scenes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StackParams {
    /// Boxes on the bottom row of a pyramid, or boxes in a stack (default 10).
    pub count: usize,
    /// Friction of the boxes and the ground (default 0.5).
    pub friction: Real,
    /// Largest sideways shift of a box (m), uniform in `[-jitter, jitter]` from the seed
    /// (default 0: the seed changes nothing). Below 0.1 m.
    pub jitter: Real,
    /// Density of the top box over the others' (default 1; the mass-ratio stack's ratio).
    pub ratio: Real,
}

impl Default for StackParams {
    fn default() -> Self {
        Self {
            count: 10,
            friction: 0.5,
            jitter: 0.0,
            ratio: 1.0,
        }
    }
}

impl StackParams {
    /// Checks the parameters (`scene` names the scene in errors) and gives the material of
    /// the boxes and the ground and the seeded shifts.
    fn prepare(&self, scene: &'static str, seed: u64) -> Result<(Material, Jitter), CoreError> {
        if self.count == 0 || self.count > MAX_STACK {
            return Err(CoreError::InvalidSetting {
                name: scene,
                value: self.count as Real,
                reason: "must count 1 to 1 000 boxes (MAX_STACK)",
            });
        }
        check_friction("friction", self.friction)?;
        if !(self.jitter.is_finite() && (0.0..0.1).contains(&self.jitter)) {
            return Err(CoreError::InvalidSetting {
                name: "jitter",
                value: self.jitter,
                reason: "must be in [0, 0.1) m",
            });
        }
        if !(self.ratio.is_finite() && self.ratio > 0.0 && self.ratio <= 1e6) {
            return Err(CoreError::InvalidSetting {
                name: "ratio",
                value: self.ratio,
                reason: "must be in (0, 1e6]",
            });
        }
        let material = Material {
            friction: self.friction,
            ..Material::default()
        };
        Ok((
            material,
            Jitter {
                rng: PortableRng::new(seed),
                size: self.jitter,
            },
        ))
    }
}

/// The seeded sideways shifts of the boxes.
struct Jitter {
    rng: PortableRng,
    size: Real,
}

impl Jitter {
    fn next(&mut self) -> Real {
        if self.size == 0.0 {
            0.0
        } else {
            self.rng.uniform_range(-self.size, self.size)
        }
    }
}

/// A pyramid of unit boxes, `base` boxes on the bottom row, on a static ground box.
pub fn pyramid(base: usize) -> Scene {
    pyramid_jittered(base, Material::default(), None)
}

fn pyramid_jittered(base: usize, material: Material, mut jitter: Option<&mut Jitter>) -> Scene {
    // Neighbours stand 2 × jitter apart, so no shift makes two boxes overlap.
    let pitch = 2.0 * HALF + 2.0 * jitter.as_ref().map_or(0.0, |j| j.size);
    let width = base as Real * pitch + 4.0;
    let mut bodies = vec![ground(width).with_material(material)];
    for row in 0..base {
        let count = base - row;
        let y = HALF + row as Real * 2.0 * HALF;
        let x0 = -(count as Real - 1.0) * 0.5 * pitch;
        for i in 0..count {
            let dx = jitter.as_mut().map_or(0.0, |j| j.next());
            bodies.push(
                unit_box(Vector::new(x0 + i as Real * pitch + dx, y)).with_material(material),
            );
        }
    }
    let h = base as Real * 2.0 * HALF;
    Scene {
        name: "pyramid".into(),
        bodies,
        min: Vector::new(-0.5 * width, -1.0),
        max: Vector::new(0.5 * width, h + 1.0),
    }
}

/// A pyramid of `params.count` boxes at the base ([`pyramid`] with friction and seeded
/// jitter; the ratio is not used). With jitter the boxes of a row stand `2 × jitter` apart
/// before their shifts, so none overlaps its neighbour.
pub fn pyramid_with(seed: u64, params: &StackParams) -> Result<Scene, CoreError> {
    let (material, mut jitter) = params.prepare("pyramid.base", seed)?;
    Ok(pyramid_jittered(params.count, material, Some(&mut jitter)))
}

/// A vertical stack of `count` unit boxes on a static ground box.
pub fn stack(count: usize) -> Scene {
    stack_jittered("stack", count, Material::default(), None, 1.0)
}

fn stack_jittered(
    name: &str,
    count: usize,
    material: Material,
    mut jitter: Option<&mut Jitter>,
    ratio: Real,
) -> Scene {
    let mut bodies = vec![ground(6.0).with_material(material)];
    for i in 0..count {
        let dx = jitter.as_mut().map_or(0.0, |j| j.next());
        let top = i + 1 == count && ratio != 1.0;
        let box_material = Material {
            density: if top {
                material.density * ratio
            } else {
                material.density
            },
            ..material
        };
        bodies.push(unit_box(Vector::new(dx, HALF + i as Real)).with_material(box_material));
    }
    Scene {
        name: name.into(),
        bodies,
        min: Vector::new(-3.0, -1.0),
        max: Vector::new(3.0, count as Real + 1.0),
    }
}

/// A stack of `params.count` unit boxes ([`stack`] with friction and seeded jitter; the
/// ratio is not used).
pub fn stack_with(seed: u64, params: &StackParams) -> Result<Scene, CoreError> {
    let (material, mut jitter) = params.prepare("stack.count", seed)?;
    Ok(stack_jittered(
        "stack",
        params.count,
        material,
        Some(&mut jitter),
        1.0,
    ))
}

/// A stack of `params.count` unit boxes whose top box is `params.ratio` times denser (so
/// heavier) than the others: the mass ratio that slows Gauss-Seidel (a heavy box on light
/// ones).
pub fn ratio_stack(seed: u64, params: &StackParams) -> Result<Scene, CoreError> {
    let (material, mut jitter) = params.prepare("ratio-stack.count", seed)?;
    Ok(stack_jittered(
        "ratio-stack",
        params.count,
        material,
        Some(&mut jitter),
        params.ratio,
    ))
}
