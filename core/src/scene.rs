//! Scenes shared by the CLI, the tests and the benches: defined once, here.

use crate::body::{BodyDesc, BodyKind, Material};
use crate::error::CoreError;
use crate::math::{Real, Vector};
use crate::rng::PortableRng;
use crate::shape::ShapeDesc;
use crate::world::{World, WorldSettings};

/// A named list of bodies plus the region they live in.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Scene name (`"pile"`, `"pyramid"`, ...).
    pub name: String,
    /// Bodies in handle order.
    pub bodies: Vec<BodyDesc>,
    /// Lower corner of the region of interest (for rendering and grids).
    pub min: Vector,
    /// Upper corner of the region of interest.
    pub max: Vector,
}

impl Scene {
    /// Builds a world of this scene.
    pub fn build(&self, settings: WorldSettings) -> Result<World, CoreError> {
        World::with_bodies(settings, &self.bodies)
    }

    /// Number of dynamic bodies.
    pub fn dynamic_count(&self) -> usize {
        self.bodies
            .iter()
            .filter(|b| b.kind == BodyKind::Dynamic)
            .count()
    }
}

/// Parameters of the thesis pile (defaults are the thesis's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PileParams {
    /// Number of circles (default 100).
    pub bodies: usize,
    /// Circle radius (default 0.5 m).
    pub radius: Real,
    /// Side of the box for 100 bodies (default 15 m); scaled by `sqrt(bodies / 100)`.
    pub box_side: Real,
    /// Standard deviation of the placement per axis for 100 bodies (default 3.29 m); scaled alike.
    pub sigma: Real,
    /// Circle material (default density 1, friction 0.5, restitution 0).
    pub material: Material,
    /// Wall material (default friction 0.5, restitution 0).
    pub wall_material: Material,
}

impl Default for PileParams {
    fn default() -> Self {
        Self {
            bodies: 100,
            radius: 0.5,
            box_side: 15.0,
            sigma: 3.29,
            material: Material::default(),
            wall_material: Material::default(),
        }
    }
}

/// The static box of the pile: four segments (bottom, right, top, left) of side `side`
/// with the lower-left corner at the origin, one static body each.
pub fn walls(side: Real, material: Material) -> Vec<BodyDesc> {
    let c = [
        Vector::new(0.0, 0.0),
        Vector::new(side, 0.0),
        Vector::new(side, side),
        Vector::new(0.0, side),
    ];
    (0..4)
        .map(|i| {
            BodyDesc::fixed(
                ShapeDesc::Segment {
                    a: c[i],
                    b: c[(i + 1) % 4],
                },
                Vector::zeros(),
            )
            .with_material(material)
        })
        .collect()
}

/// The thesis pile: circles placed by a Gaussian around the box centre, rejecting any
/// circle closer than its radius to a wall or overlapping one already placed. With
/// `params.bodies != 100` the box and the spread are scaled by `sqrt(bodies / 100)` so
/// the density is kept. The walls are bodies 0-3, the circles follow.
pub fn pile_with(seed: u64, params: &PileParams) -> Result<Scene, CoreError> {
    if params.bodies > MAX_BODIES {
        return Err(CoreError::InvalidSetting {
            name: "pile.bodies",
            value: params.bodies as Real,
            reason: "is above the ceiling of 1 000 000 bodies (MAX_BODIES)",
        });
    }
    if params.bodies == 0 {
        // The box is scaled by sqrt(bodies / 100): an empty pile has no box.
        return Err(CoreError::InvalidSetting {
            name: "pile.bodies",
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    let scale = (params.bodies as Real / 100.0).sqrt();
    let side = params.box_side * scale;
    let sigma = params.sigma * scale;
    let r = params.radius;
    if !(r.is_finite() && r > 0.0 && side > 4.0 * r) {
        return Err(CoreError::InvalidSetting {
            name: "pile.radius",
            value: r,
            reason: "must be > 0 and fit the box",
        });
    }
    let mut bodies = walls(side, params.wall_material);
    let mut rng = PortableRng::new(seed);
    let centre = Vector::new(0.5 * side, 0.5 * side);
    // Placed centres bucketed on a grid of cell 2r, so the overlap test is O(1).
    let cell = 2.0 * r;
    let n_cells = (side / cell).ceil() as usize + 1;
    let mut grid: Vec<Vec<Vector>> = vec![Vec::new(); n_cells * n_cells];
    let max_attempts = 10_000 * params.bodies.max(1);
    let mut attempts = 0;
    let mut placed = 0;
    while placed < params.bodies {
        attempts += 1;
        if attempts > max_attempts {
            return Err(CoreError::InvalidSetting {
                name: "pile.bodies",
                value: params.bodies as Real,
                reason: "could not place that many circles",
            });
        }
        let p = Vector::new(
            centre.x + sigma * rng.normal(),
            centre.y + sigma * rng.normal(),
        );
        // Closer than its radius to a wall: centre within 2r of an edge.
        if p.x < 2.0 * r || p.y < 2.0 * r || p.x > side - 2.0 * r || p.y > side - 2.0 * r {
            continue;
        }
        let (cx, cy) = ((p.x / cell) as usize, (p.y / cell) as usize);
        let mut overlaps = false;
        'search: for gx in cx.saturating_sub(1)..=(cx + 1).min(n_cells - 1) {
            for gy in cy.saturating_sub(1)..=(cy + 1).min(n_cells - 1) {
                if grid[gx * n_cells + gy]
                    .iter()
                    .any(|q| (q - p).norm_squared() < (2.0 * r).powi(2))
                {
                    overlaps = true;
                    break 'search;
                }
            }
        }
        if overlaps {
            continue;
        }
        grid[cx * n_cells + cy].push(p);
        bodies.push(
            BodyDesc::dynamic(ShapeDesc::Ball { radius: r }, p).with_material(params.material),
        );
        placed += 1;
    }
    Ok(Scene {
        name: "pile".into(),
        bodies,
        min: Vector::zeros(),
        max: Vector::new(side, side),
    })
}

/// The thesis pile with `bodies` circles (100 = the thesis's scene).
pub fn pile(seed: u64, bodies: usize) -> Result<Scene, CoreError> {
    pile_with(
        seed,
        &PileParams {
            bodies,
            ..PileParams::default()
        },
    )
}

/// A pyramid of unit boxes, `base` boxes on the bottom row, on a static ground box.
pub fn pyramid(base: usize) -> Scene {
    let half = 0.5;
    let width = base as Real * 2.0 * half + 4.0;
    let mut bodies = vec![ground(width)];
    for row in 0..base {
        let count = base - row;
        let y = half + row as Real * 2.0 * half;
        let x0 = -(count as Real - 1.0) * half;
        for i in 0..count {
            bodies.push(BodyDesc::dynamic(
                ShapeDesc::Cuboid {
                    half_width: half,
                    half_height: half,
                },
                Vector::new(x0 + i as Real * 2.0 * half, y),
            ));
        }
    }
    let h = base as Real * 2.0 * half;
    Scene {
        name: "pyramid".into(),
        bodies,
        min: Vector::new(-0.5 * width, -1.0),
        max: Vector::new(0.5 * width, h + 1.0),
    }
}

/// A vertical stack of `count` unit boxes on a static ground box.
pub fn stack(count: usize) -> Scene {
    let mut bodies = vec![ground(6.0)];
    for i in 0..count {
        bodies.push(BodyDesc::dynamic(
            ShapeDesc::Cuboid {
                half_width: 0.5,
                half_height: 0.5,
            },
            Vector::new(0.0, 0.5 + i as Real),
        ));
    }
    Scene {
        name: "stack".into(),
        bodies,
        min: Vector::new(-3.0, -1.0),
        max: Vector::new(3.0, count as Real + 1.0),
    }
}

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

fn ground(width: Real) -> BodyDesc {
    BodyDesc::fixed(
        ShapeDesc::Cuboid {
            half_width: 0.5 * width,
            half_height: 0.5,
        },
        Vector::new(0.0, -0.5),
    )
}

/// Names accepted by [`by_name`].
pub const SCENES: &[&str] = &[
    "pile",
    "pyramid",
    "stack",
    "resting_ball",
    "thesis",
    "file:PATH",
];

/// The most circles a pile may have: placement, memory (≈ 1 KB per body with its broad-phase
/// and solver data) and step time (≈ 25 ms per step at 10 000 bodies) grow with it, so a
/// larger request is refused at once instead of running for minutes.
pub const MAX_BODIES: usize = 1_000_000;

/// The largest base of a pyramid or height of a stack (a pyramid of 1 000 holds 500 500 boxes).
pub const MAX_STACK: usize = 1_000;

/// A scene by name: `pile` (uses `seed` and `bodies`), `pyramid` (base of `bodies` boxes,
/// 10 if `bodies` is 100), `stack` (of `bodies` boxes, 10 if 100), `resting_ball`, `thesis`
/// (the original code's world of `seed`), or `file:PATH`: the world of `seed` in the scene
/// file at `PATH` ([`crate::scene_file`] format) in the thesis's 15 m box.
pub fn by_name(name: &str, seed: u64, bodies: usize) -> Result<Scene, CoreError> {
    if let Some(path) = name.strip_prefix("file:") {
        let circles = crate::scene_file::load(path)?;
        return crate::scene_file::pile_from_circles(&circles, seed, 15.0, path);
    }
    let small = if bodies == 100 { 10 } else { bodies };
    // A pyramid of base b holds b (b + 1) / 2 boxes, a stack b: both bounded like the pile.
    if (name == "pyramid" || name == "stack") && small > MAX_STACK {
        return Err(CoreError::InvalidSetting {
            name: "bodies",
            value: small as Real,
            reason: "is above the ceiling of 1 000 for pyramid and stack (MAX_STACK)",
        });
    }
    match name {
        "pile" => pile(seed, bodies),
        "pyramid" => Ok(pyramid(small)),
        "stack" => Ok(stack(small)),
        "resting_ball" => Ok(resting_ball()),
        "thesis" => crate::scene_file::thesis_world(seed),
        _ => Err(CoreError::UnknownScene {
            name: name.to_string(),
            known: SCENES.join(", "),
        }),
    }
}
