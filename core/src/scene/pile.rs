//! Piles: bodies placed by a seeded Gaussian around the centre of a static box, the thesis's
//! scene and its box and polygon variants. One placement rule serves them all.

use crate::body::{BodyDesc, Material};
use crate::error::CoreError;
use crate::math::{Real, Vector};
use crate::rng::PortableRng;
use crate::shape::ShapeDesc;

use super::{MAX_BODIES, Scene};

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

/// One body to place: its shape, its bounding radius (m) and its angle (rad).
pub(super) struct Piece {
    pub(super) shape: ShapeDesc,
    pub(super) radius: Real,
    pub(super) angle: Real,
}

/// The box and spread of a pile of `bodies`: `(side, sigma)` scaled by `sqrt(bodies / 100)`
/// from the 100-body values, so the density is kept; `name` labels the errors.
pub(super) fn pile_box(
    name: &'static str,
    bodies: usize,
    box_side: Real,
    sigma: Real,
) -> Result<(Real, Real), CoreError> {
    if bodies > MAX_BODIES {
        return Err(CoreError::InvalidSetting {
            name,
            value: bodies as Real,
            reason: "is above the ceiling of 1 000 000 bodies (MAX_BODIES)",
        });
    }
    if bodies == 0 {
        // The box is scaled by sqrt(bodies / 100): an empty pile has no box.
        return Err(CoreError::InvalidSetting {
            name,
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    let scale = (bodies as Real / 100.0).sqrt();
    Ok((box_side * scale, sigma * scale))
}

/// Places `count` bodies in the box `[0, side]²` by a Gaussian of `sigma` per axis around its
/// centre: body `i`'s shape comes first from `piece(rng)`, then centres are drawn until one
/// keeps its bounding circle off the walls (a centre within twice the bounding radius of an
/// edge is rejected, as the thesis's placement does) and off every body already placed
/// (bounding circles do not overlap). `max_radius` bounds every piece's radius (the grid
/// cell). With `shapes: true` (the box and polygon piles) the wall rule is the exact one, a
/// centre within one bounding radius of an edge, and a body still unplaced after
/// [`UNIFORM_AFTER`] Gaussian draws is placed by uniform draws over the box instead (a large
/// piece drawn late may find no room near the centre). The bodies get `material` and are
/// appended to `bodies`.
///
/// A pile of circles (`shapes: false`) draws nothing in `piece` and keeps the thesis's rules,
/// so its random sequence is the thesis pile's.
#[allow(clippy::too_many_arguments)]
pub(super) fn place(
    name: &'static str,
    rng: &mut PortableRng,
    count: usize,
    side: Real,
    sigma: Real,
    max_radius: Real,
    material: Material,
    bodies: &mut Vec<BodyDesc>,
    shapes: bool,
    mut piece: impl FnMut(&mut PortableRng) -> Piece,
) -> Result<(), CoreError> {
    let centre = Vector::new(0.5 * side, 0.5 * side);
    // Placed centres bucketed on a grid of cell 2 r_max, so the overlap test is O(1).
    let cell = 2.0 * max_radius;
    let n_cells = (side / cell).ceil() as usize + 1;
    let mut grid: Vec<Vec<(Vector, Real)>> = vec![Vec::new(); n_cells * n_cells];
    let max_attempts = 10_000 * count.max(1);
    let mut attempts = 0;
    for _ in 0..count {
        let Piece {
            shape,
            radius: r,
            angle,
        } = piece(rng);
        let mut tries = 0;
        let p = loop {
            attempts += 1;
            tries += 1;
            if attempts > max_attempts {
                return Err(CoreError::InvalidSetting {
                    name,
                    value: count as Real,
                    reason: "could not place that many bodies",
                });
            }
            let margin = if shapes { r } else { 2.0 * r };
            let p = if shapes && tries > UNIFORM_AFTER {
                Vector::new(
                    rng.uniform_range(margin, side - margin),
                    rng.uniform_range(margin, side - margin),
                )
            } else {
                Vector::new(
                    centre.x + sigma * rng.normal(),
                    centre.y + sigma * rng.normal(),
                )
            };
            // The thesis's "closer than its radius to a wall": centre within 2r of an edge.
            if p.x < margin || p.y < margin || p.x > side - margin || p.y > side - margin {
                continue;
            }
            let (cx, cy) = ((p.x / cell) as usize, (p.y / cell) as usize);
            let overlaps = (cx.saturating_sub(1)..=(cx + 1).min(n_cells - 1)).any(|gx| {
                (cy.saturating_sub(1)..=(cy + 1).min(n_cells - 1)).any(|gy| {
                    grid[gx * n_cells + gy]
                        .iter()
                        .any(|(q, rq)| (q - p).norm_squared() < (r + rq).powi(2))
                })
            });
            if !overlaps {
                grid[cx * n_cells + cy].push((p, r));
                break p;
            }
        };
        bodies.push(
            BodyDesc::dynamic(shape, p)
                .with_material(material)
                .with_angle(angle),
        );
    }
    Ok(())
}

/// The thesis pile: circles placed by a Gaussian around the box centre, rejecting any
/// circle closer than its radius to a wall or overlapping one already placed. With
/// `params.bodies != 100` the box and the spread are scaled by `sqrt(bodies / 100)` so
/// the density is kept. The walls are bodies 0-3, the circles follow.
pub fn pile_with(seed: u64, params: &PileParams) -> Result<Scene, CoreError> {
    let (side, sigma) = pile_box("pile.bodies", params.bodies, params.box_side, params.sigma)?;
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
    place(
        "pile.bodies",
        &mut rng,
        params.bodies,
        side,
        sigma,
        r,
        params.material,
        &mut bodies,
        false,
        |_| Piece {
            shape: ShapeDesc::Ball { radius: r },
            radius: r,
            angle: 0.0,
        },
    )?;
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

/// Parameters of the box and polygon piles ([`box_pile`], [`polygon_pile`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapePileParams {
    /// Number of bodies (default 100).
    pub bodies: usize,
    /// Friction of the bodies and the walls (default 0.5, the thesis's).
    pub friction: Real,
}

impl Default for ShapePileParams {
    fn default() -> Self {
        Self {
            bodies: 100,
            friction: 0.5,
        }
    }
}

impl ShapePileParams {
    fn materials(&self, name: &'static str) -> Result<Material, CoreError> {
        check_friction(name, self.friction)?;
        Ok(Material {
            friction: self.friction,
            ..Material::default()
        })
    }
}

/// The box and spread of a box or polygon pile: the pile's, but the box at least
/// [`MIN_SHAPE_SIDE`] wide (a handful of bodies of up to 1.6 m across would not fit the
/// pile's box scaled down to them).
fn shape_pile_box(name: &'static str, bodies: usize) -> Result<(Real, Real), CoreError> {
    let defaults = PileParams::default();
    let (side, sigma) = pile_box(name, bodies, defaults.box_side, defaults.sigma)?;
    Ok((side.max(MIN_SHAPE_SIDE), sigma))
}

/// Smallest box of a box or polygon pile (m): room for 25 of its largest bodies.
const MIN_SHAPE_SIDE: Real = 8.0;

/// Rejects a friction coefficient that is negative or not finite.
pub(super) fn check_friction(name: &'static str, friction: Real) -> Result<(), CoreError> {
    if friction.is_finite() && friction >= 0.0 {
        Ok(())
    } else {
        Err(CoreError::InvalidSetting {
            name,
            value: friction,
            reason: "must be finite and >= 0",
        })
    }
}

/// Gaussian draws for one body of a box or polygon pile before uniform ones (see [`place`]).
const UNIFORM_AFTER: usize = 2_000;

/// Largest bounding radius of a box of [`box_pile`]: half-height up to 0.35 m, aspect up to
/// 2, so half-width up to 0.7 m.
const BOX_MAX_RADIUS: Real = 0.782_623_792_124_926_4; // sqrt(0.7² + 0.35²)

/// Boxes of random size and aspect in the thesis's box, placed as the pile's circles (their
/// bounding circles kept apart) at random angles: half-height uniform in [0.2, 0.35] m,
/// aspect (width / height) uniform in [1, 2], angle uniform in [0, π). The mean bounding
/// radius, ≈ 0.5 m, is the circles' radius, so the placement packs them as densely; the
/// mean area is ≈ 0.46 m². The box and the spread scale with `sqrt(bodies / 100)` as the
/// pile's. Walls are bodies 0-3.
pub fn box_pile(seed: u64, params: &ShapePileParams) -> Result<Scene, CoreError> {
    let (side, sigma) = shape_pile_box("box-pile.bodies", params.bodies)?;
    let material = params.materials("box-pile.friction")?;
    let mut bodies = walls(side, material);
    let mut rng = PortableRng::new(seed);
    place(
        "box-pile.bodies",
        &mut rng,
        params.bodies,
        side,
        sigma,
        BOX_MAX_RADIUS,
        material,
        &mut bodies,
        true,
        |rng| {
            let half_height = rng.uniform_range(0.2, 0.35);
            let half_width = half_height * rng.uniform_range(1.0, 2.0);
            Piece {
                shape: ShapeDesc::Cuboid {
                    half_width,
                    half_height,
                },
                radius: half_width.hypot(half_height),
                angle: rng.uniform_range(0.0, std::f64::consts::PI),
            }
        },
    )?;
    Ok(Scene {
        name: "box-pile".into(),
        bodies,
        min: Vector::zeros(),
        max: Vector::new(side, side),
    })
}

/// Largest bounding radius of a body of [`polygon_pile`].
const POLYGON_MAX_RADIUS: Real = 0.55;

/// Convex polygons of 3 to 8 sides mixed with circles, in the thesis's box, placed as the
/// pile's circles. Each body is a circle with probability 1/2 (radius uniform in
/// [0.3, 0.5] m), else an n-gon, n uniform in 3..=8, whose vertices lie on a circle of radius
/// uniform in [0.35, 0.55] m at angles 2πk/n shifted by up to a quarter of the spacing (so
/// the polygon stays convex and irregular), turned by a uniform angle. The box and the
/// spread scale with `sqrt(bodies / 100)` as the pile's. Walls are bodies 0-3.
pub fn polygon_pile(seed: u64, params: &ShapePileParams) -> Result<Scene, CoreError> {
    let (side, sigma) = shape_pile_box("polygon-pile.bodies", params.bodies)?;
    let material = params.materials("polygon-pile.friction")?;
    let mut bodies = walls(side, material);
    let mut rng = PortableRng::new(seed);
    place(
        "polygon-pile.bodies",
        &mut rng,
        params.bodies,
        side,
        sigma,
        POLYGON_MAX_RADIUS,
        material,
        &mut bodies,
        true,
        |rng| {
            if rng.uniform() < 0.5 {
                let radius = rng.uniform_range(0.3, 0.5);
                return Piece {
                    shape: ShapeDesc::Ball { radius },
                    radius,
                    angle: 0.0,
                };
            }
            let sides = 3 + (rng.uniform() * 6.0).min(5.0) as usize;
            let radius = rng.uniform_range(0.35, POLYGON_MAX_RADIUS);
            let spacing = std::f64::consts::TAU / sides as Real;
            let vertices: Vec<Vector> = (0..sides)
                .map(|k| {
                    let a = spacing * (k as Real + rng.uniform_range(-0.25, 0.25));
                    radius * Vector::new(a.cos(), a.sin())
                })
                .collect();
            Piece {
                shape: ShapeDesc::ConvexPolygon { vertices },
                radius,
                angle: rng.uniform_range(0.0, std::f64::consts::TAU),
            }
        },
    )?;
    Ok(Scene {
        name: "polygon-pile".into(),
        bodies,
        min: Vector::zeros(),
        max: Vector::new(side, side),
    })
}
