//! Static geometry on the grid: which nodes are wall nodes, and the region that the
//! static bodies span.

use deepcontact_core::math::rotate;
use deepcontact_core::{Body, BodyKind, ShapeDesc, Vector};

use crate::spec::GridSpec;

/// Distance from `p` to the segment `ab`.
fn segment_distance(p: &Vector, a: &Vector, b: &Vector) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + t * ab)).norm()
}

/// Distance from `p` to a closed convex polygon (counter-clockwise), 0 inside.
fn polygon_distance(p: &Vector, vertices: &[Vector]) -> f64 {
    let n = vertices.len();
    let mut inside = n >= 3;
    let mut d = f64::INFINITY;
    for i in 0..n {
        let (a, b) = (vertices[i], vertices[(i + 1) % n]);
        if deepcontact_core::math::cross(&(b - a), &(p - a)) < 0.0 {
            inside = false;
        }
        d = d.min(segment_distance(p, &a, &b));
    }
    if inside { 0.0 } else { d }
}

/// The shape's vertices in world coordinates (a ball gives its centre).
fn world_vertices(body: &Body, out: &mut Vec<Vector>) {
    out.clear();
    let origin = body.origin();
    let world = |v: &Vector| origin + rotate(v, body.angle);
    match &body.shape_desc {
        ShapeDesc::Ball { .. } => out.push(origin),
        ShapeDesc::Cuboid {
            half_width: w,
            half_height: h,
        } => out.extend(
            [
                Vector::new(-w, -h),
                Vector::new(*w, -h),
                Vector::new(*w, *h),
                Vector::new(-w, *h),
            ]
            .iter()
            .map(world),
        ),
        ShapeDesc::ConvexPolygon { vertices } | ShapeDesc::Polyline { vertices } => {
            out.extend(vertices.iter().map(world))
        }
        ShapeDesc::Segment { a, b } => out.extend([world(a), world(b)]),
    }
}

/// Distance from `p` to the body's shape given its world vertices (0 inside solids).
fn shape_distance(body: &Body, vertices: &[Vector], p: &Vector) -> f64 {
    match &body.shape_desc {
        ShapeDesc::Ball { radius } => ((p - vertices[0]).norm() - radius).max(0.0),
        ShapeDesc::Cuboid { .. } | ShapeDesc::ConvexPolygon { .. } => polygon_distance(p, vertices),
        ShapeDesc::Segment { .. } | ShapeDesc::Polyline { .. } => vertices
            .windows(2)
            .map(|w| segment_distance(p, &w[0], &w[1]))
            .fold(f64::INFINITY, f64::min),
    }
}

/// Axis-aligned bounds of a body's shape in world coordinates.
fn shape_bounds(body: &Body, vertices: &[Vector]) -> (Vector, Vector) {
    let r = match body.shape_desc {
        ShapeDesc::Ball { radius } => radius,
        _ => 0.0,
    };
    let mut lo = Vector::repeat(f64::INFINITY);
    let mut hi = Vector::repeat(f64::NEG_INFINITY);
    for v in vertices {
        lo = lo.inf(v);
        hi = hi.sup(v);
    }
    (lo - Vector::repeat(r), hi + Vector::repeat(r))
}

/// The region spanned by the static bodies' shapes, or `None` without static bodies.
/// For the thesis pile this is the box `[0, side]²`.
pub fn static_bounds(bodies: &[Body]) -> Option<(Vector, Vector)> {
    let mut vertices = Vec::new();
    let mut bounds: Option<(Vector, Vector)> = None;
    for b in bodies.iter().filter(|b| b.kind == BodyKind::Static) {
        world_vertices(b, &mut vertices);
        let (lo, hi) = shape_bounds(b, &vertices);
        bounds = Some(match bounds {
            None => (lo, hi),
            Some((a, c)) => (a.inf(&lo), c.sup(&hi)),
        });
    }
    bounds.filter(|(lo, hi)| lo.iter().chain(hi.iter()).all(|v| v.is_finite()))
}

/// Writes into `out` (sorted, no duplicates) the indices of the nodes of `spec` within
/// `band` metres of a static body's shape (on it, or inside a solid static shape).
pub fn wall_nodes(spec: &GridSpec, bodies: &[Body], band: f64, out: &mut Vec<u32>) {
    out.clear();
    let mut vertices = Vec::new();
    for b in bodies.iter().filter(|b| b.kind == BodyKind::Static) {
        world_vertices(b, &mut vertices);
        let (lo, hi) = shape_bounds(b, &vertices);
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        // Square box around the shape's bounds, grown by the band.
        let r = half.x.max(half.y) + band;
        let Some((ix0, ix1, iy0, iy1)) = spec.box_range(&centre, r) else {
            continue;
        };
        for iy in iy0..=iy1 {
            for ix in ix0..=ix1 {
                let p = spec.node(ix, iy);
                if (p.x - centre.x).abs() > half.x + band || (p.y - centre.y).abs() > half.y + band
                {
                    continue;
                }
                if shape_distance(b, &vertices, &p) <= band {
                    out.push(spec.index(ix, iy) as u32);
                }
            }
        }
    }
    out.sort_unstable();
    out.dedup();
}

/// A snapshot of the static bodies (index, pose, shape) to detect changes cheaply.
#[derive(Debug, Clone, Default)]
struct StaticSignature(Vec<(usize, Vector, f64, ShapeDesc)>);

impl StaticSignature {
    /// Whether `bodies` has other static bodies than the snapshot; updates it if so.
    fn update(&mut self, bodies: &[Body]) -> bool {
        let statics = bodies
            .iter()
            .enumerate()
            .filter(|(_, b)| b.kind == BodyKind::Static);
        let same = statics.clone().count() == self.0.len()
            && statics.clone().zip(&self.0).all(|((i, b), (j, p, a, s))| {
                i == *j && b.position == *p && b.angle == *a && b.shape_desc == *s
            });
        if !same {
            self.0.clear();
            self.0
                .extend(statics.map(|(i, b)| (i, b.position, b.angle, b.shape_desc.clone())));
        }
        !same
    }
}

/// Wall nodes cached for one set of static bodies: recomputed only when the grid, the
/// band, or a static body's index, pose or shape changes.
#[derive(Debug, Clone, Default)]
pub struct WallCache {
    key: Option<(GridSpec, f64)>,
    signature: StaticSignature,
    nodes: Vec<u32>,
}

impl WallCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// The wall nodes of `bodies` on `spec` (see [`wall_nodes`]).
    pub fn nodes(&mut self, spec: &GridSpec, bodies: &[Body], band: f64) -> &[u32] {
        let changed = self.signature.update(bodies);
        if changed || self.key != Some((*spec, band)) {
            self.key = Some((*spec, band));
            wall_nodes(spec, bodies, band, &mut self.nodes);
        }
        &self.nodes
    }
}

/// [`static_bounds`] cached for one set of static bodies.
#[derive(Debug, Clone, Default)]
pub struct StaticBoundsCache {
    signature: StaticSignature,
    bounds: Option<(Vector, Vector)>,
    valid: bool,
}

impl StaticBoundsCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// The bounds of the static bodies of `bodies` (recomputed only when they change).
    pub fn bounds(&mut self, bodies: &[Body]) -> Option<(Vector, Vector)> {
        if self.signature.update(bodies) || !self.valid {
            self.bounds = static_bounds(bodies);
            self.valid = true;
        }
        self.bounds
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepcontact_core::scene;
    use deepcontact_core::{BodyDesc, World, WorldSettings};

    #[test]
    fn pile_walls_are_the_border_nodes() {
        let world = scene::pile(0, 100)
            .unwrap()
            .build(WorldSettings::default())
            .unwrap();
        let spec = GridSpec::thesis();
        let mut nodes = Vec::new();
        wall_nodes(&spec, world.bodies(), 0.125, &mut nodes);
        assert_eq!(nodes.len(), 4 * 60);
        for &n in &nodes {
            let (ix, iy) = spec.coords(n as usize);
            assert!(ix == 0 || iy == 0 || ix == 60 || iy == 60);
        }
        let (lo, hi) = static_bounds(world.bodies()).unwrap();
        assert_eq!((lo, hi), (Vector::zeros(), Vector::new(15.0, 15.0)));
        let mut cache = WallCache::new();
        assert_eq!(cache.nodes(&spec, world.bodies(), 0.125).len(), 240);
        assert_eq!(
            cache.nodes(&spec, world.bodies(), 0.3).len(),
            61 * 61 - 57 * 57
        );
    }

    #[test]
    fn solid_and_round_statics() {
        let bodies = [
            BodyDesc::fixed(
                ShapeDesc::Cuboid {
                    half_width: 1.0,
                    half_height: 0.5,
                },
                Vector::new(2.0, 2.0),
            ),
            BodyDesc::fixed(ShapeDesc::Ball { radius: 0.5 }, Vector::new(6.0, 6.0)),
            BodyDesc::dynamic(ShapeDesc::Ball { radius: 0.5 }, Vector::new(10.0, 10.0)),
        ];
        let world = World::with_bodies(WorldSettings::default(), &bodies).unwrap();
        let spec = GridSpec::thesis();
        let mut nodes = Vec::new();
        wall_nodes(&spec, world.bodies(), 0.0, &mut nodes);
        // Box: 9 x 5 nodes (inclusive borders); ball: 13 nodes within 0.5 of its centre.
        assert_eq!(nodes.len(), 45 + 13);
        assert!(static_bounds(&world.bodies()[2..]).is_none());
    }
}
