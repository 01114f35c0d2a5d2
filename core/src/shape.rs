//! Collision shapes: a plain description ([`ShapeDesc`]) validated into a parry2d shape.

use crate::error::CoreError;
use crate::math::{Real, Vector, from_parry, to_parry};
use parry2d::shape::SharedShape;

/// The shape of a body, in the body's local frame (origin at the body's reference point).
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeDesc {
    /// A disc of the given radius centred at the origin.
    Ball {
        /// Radius in metres (> 0).
        radius: Real,
    },
    /// An axis-aligned box with the given half extents.
    Cuboid {
        /// Half width in metres (> 0).
        half_width: Real,
        /// Half height in metres (> 0).
        half_height: Real,
    },
    /// A convex polygon, vertices counter-clockwise (at least 3, non-degenerate).
    ConvexPolygon {
        /// Vertices in the local frame.
        vertices: Vec<Vector>,
    },
    /// A line segment (typically a static wall).
    Segment {
        /// First end point.
        a: Vector,
        /// Second end point.
        b: Vector,
    },
    /// A chain of segments (typically static walls); consecutive vertices are joined.
    Polyline {
        /// Vertices in order; a closed loop repeats the first vertex at the end.
        vertices: Vec<Vector>,
    },
}

impl ShapeDesc {
    /// Checks the parameters and builds the parry2d shape. `body` is only used in errors.
    pub fn build(&self, body: usize) -> Result<SharedShape, CoreError> {
        let positive = |field: &'static str, v: Real| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(CoreError::InvalidBodyParameter {
                    body,
                    field,
                    value: v,
                    reason: "must be finite and > 0",
                })
            }
        };
        let finite_pts = |pts: &[Vector]| {
            for p in pts {
                if !(p.x.is_finite() && p.y.is_finite()) {
                    return Err(CoreError::InvalidBodyParameter {
                        body,
                        field: "vertex",
                        value: if p.x.is_finite() { p.y } else { p.x },
                        reason: "must be finite",
                    });
                }
            }
            Ok(())
        };
        Ok(match self {
            ShapeDesc::Ball { radius } => {
                positive("radius", *radius)?;
                SharedShape::ball(*radius as f32)
            }
            ShapeDesc::Cuboid {
                half_width,
                half_height,
            } => {
                positive("half_width", *half_width)?;
                positive("half_height", *half_height)?;
                SharedShape::cuboid(*half_width as f32, *half_height as f32)
            }
            ShapeDesc::ConvexPolygon { vertices } => {
                finite_pts(vertices)?;
                if vertices.len() < 3 {
                    return Err(CoreError::DegeneratePolygon {
                        body,
                        reason: "fewer than 3 vertices",
                    });
                }
                let n = vertices.len();
                let mut area2 = 0.0;
                for i in 0..n {
                    let (a, b, c) = (vertices[i], vertices[(i + 1) % n], vertices[(i + 2) % n]);
                    let turn = crate::math::cross(&(b - a), &(c - b));
                    if turn <= 0.0 {
                        return Err(CoreError::DegeneratePolygon {
                            body,
                            reason: "not strictly convex and counter-clockwise",
                        });
                    }
                    area2 += crate::math::cross(&a, &b);
                }
                if area2 <= 1e-12 {
                    return Err(CoreError::DegeneratePolygon {
                        body,
                        reason: "zero area",
                    });
                }
                let pts = vertices.iter().map(to_parry).collect();
                SharedShape::convex_polyline_unmodified(pts).ok_or(
                    CoreError::DegeneratePolygon {
                        body,
                        reason: "rejected by parry2d",
                    },
                )?
            }
            ShapeDesc::Segment { a, b } => {
                finite_pts(&[*a, *b])?;
                if (a - b).norm() <= 1e-9 {
                    return Err(CoreError::DegeneratePolygon {
                        body,
                        reason: "zero-length segment",
                    });
                }
                SharedShape::segment(to_parry(a), to_parry(b))
            }
            ShapeDesc::Polyline { vertices } => {
                finite_pts(vertices)?;
                if vertices.len() < 2 {
                    return Err(CoreError::DegeneratePolygon {
                        body,
                        reason: "polyline needs 2 vertices",
                    });
                }
                SharedShape::polyline(vertices.iter().map(to_parry).collect(), None)
            }
        })
    }

    /// Whether the shape encloses area (and so can carry mass).
    pub fn is_solid(&self) -> bool {
        matches!(
            self,
            ShapeDesc::Ball { .. } | ShapeDesc::Cuboid { .. } | ShapeDesc::ConvexPolygon { .. }
        )
    }

    /// Bounding radius around the local origin (used by scenes and renderers).
    pub fn bounding_radius(&self) -> Real {
        match self {
            ShapeDesc::Ball { radius } => *radius,
            ShapeDesc::Cuboid {
                half_width,
                half_height,
            } => half_width.hypot(*half_height),
            ShapeDesc::ConvexPolygon { vertices } | ShapeDesc::Polyline { vertices } => {
                vertices.iter().map(|v| v.norm()).fold(0.0, Real::max)
            }
            ShapeDesc::Segment { a, b } => a.norm().max(b.norm()),
        }
    }

    /// Vertices of the outline in the local frame (for rendering); a ball gives `segments` points.
    pub fn outline(&self, segments: usize) -> Vec<Vector> {
        match self {
            ShapeDesc::Ball { radius } => (0..segments)
                .map(|i| {
                    let t = std::f64::consts::TAU * i as Real / segments as Real;
                    Vector::new(radius * t.cos(), radius * t.sin())
                })
                .collect(),
            ShapeDesc::Cuboid {
                half_width: w,
                half_height: h,
            } => {
                vec![
                    Vector::new(-w, -h),
                    Vector::new(*w, -h),
                    Vector::new(*w, *h),
                    Vector::new(-w, *h),
                ]
            }
            ShapeDesc::ConvexPolygon { vertices } | ShapeDesc::Polyline { vertices } => {
                vertices.clone()
            }
            ShapeDesc::Segment { a, b } => vec![*a, *b],
        }
    }
}

/// Mass, inertia about the centre of mass, and local centre of mass of `shape` at `density`.
pub(crate) fn mass_properties(shape: &SharedShape, density: Real) -> (Real, Real, Vector) {
    let mp = shape.mass_properties(density as f32);
    let mass = mp.mass() as Real;
    let inertia = mp.principal_inertia() as Real;
    (mass, inertia, from_parry(mp.local_com))
}
