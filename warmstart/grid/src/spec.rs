//! [`GridSpec`]: where the nodes of a regular grid are.

use deepcontact_core::Vector;
use serde::{Deserialize, Serialize};

use crate::error::GridError;

/// A regular 2D grid of `nx × ny` nodes, `spacing` apart on both axes, the node
/// `(0, 0)` at `origin`.
///
/// Node `(ix, iy)` sits at `origin + spacing · (ix, iy)`; its flat index is
/// `iy · nx + ix` (x fastest). A multi-channel grid is stored channel-major
/// (`CHW`): value of channel `c` at node `(ix, iy)` is at `(c · ny + iy) · nx + ix`,
/// row `iy = 0` being the lowest `y`. This is the layout of the tensors handed to
/// the ONNX models.
///
/// The thesis grid ([`GridSpec::thesis`]) is 61 × 61 nodes at 0.25 m over `[0, 15]²`.
///
/// ```
/// use deepcontact_grid::GridSpec;
/// use deepcontact_core::Vector;
///
/// let g = GridSpec::covering(Vector::new(0.0, 0.0), Vector::new(15.0, 15.0), 0.25).unwrap();
/// assert_eq!(g, GridSpec::thesis());
/// assert_eq!((g.nx, g.ny, g.len()), (61, 61, 3721));
/// assert_eq!(g.node(60, 0), Vector::new(15.0, 0.0));
/// assert!(GridSpec::new([0.0, 0.0], -1.0, 3, 3).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridSpec {
    /// Position of node `(0, 0)` (the lower-left node), metres. Must be finite.
    pub origin: [f64; 2],
    /// Distance between neighbouring nodes on both axes (the thesis's "grid resolution"),
    /// metres. Must be finite and > 0.
    pub spacing: f64,
    /// Number of nodes along x (≥ 1).
    pub nx: usize,
    /// Number of nodes along y (≥ 1).
    pub ny: usize,
}

impl GridSpec {
    /// Largest number of nodes accepted (2²⁶ ≈ 67 million), so that a bad region is an
    /// error rather than an out-of-memory abort.
    pub const MAX_NODES: usize = 1 << 26;

    /// A validated grid.
    pub fn new(origin: [f64; 2], spacing: f64, nx: usize, ny: usize) -> Result<Self, GridError> {
        let spec = Self {
            origin,
            spacing,
            nx,
            ny,
        };
        spec.validate()?;
        Ok(spec)
    }

    /// The smallest grid with node `(0, 0)` at `min` and the given spacing whose last
    /// node is at or beyond `max` on both axes: `n = ceil((max − min) / spacing) + 1`
    /// nodes per axis (a relative tolerance of 1e-9 keeps `[0, 15]` at 0.25 m at 61 nodes).
    pub fn covering(min: Vector, max: Vector, spacing: f64) -> Result<Self, GridError> {
        if !(min.x.is_finite() && min.y.is_finite() && max.x.is_finite() && max.y.is_finite())
            || min.x > max.x
            || min.y > max.y
        {
            return Err(GridError::InvalidRegion {
                min_x: min.x,
                min_y: min.y,
                max_x: max.x,
                max_y: max.y,
            });
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(GridError::InvalidSpacing { spacing });
        }
        let count = |extent: f64| -> Result<usize, GridError> {
            let cells = (extent / spacing - 1e-9).ceil().max(0.0);
            if cells >= Self::MAX_NODES as f64 {
                return Err(GridError::InvalidNodeCount {
                    nx: usize::MAX,
                    ny: usize::MAX,
                    reason: "region too large for the spacing",
                });
            }
            Ok(cells as usize + 1)
        };
        Self::new(
            [min.x, min.y],
            spacing,
            count(max.x - min.x)?,
            count(max.y - min.y)?,
        )
    }

    /// The thesis grid: 61 × 61 nodes, 0.25 m apart, covering `[0, 15]²`.
    pub fn thesis() -> Self {
        Self {
            origin: [0.0, 0.0],
            spacing: 0.25,
            nx: 61,
            ny: 61,
        }
    }

    /// Checks origin, spacing and node counts.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(self.origin[0].is_finite() && self.origin[1].is_finite()) {
            return Err(GridError::InvalidOrigin {
                x: self.origin[0],
                y: self.origin[1],
            });
        }
        if !(self.spacing.is_finite() && self.spacing > 0.0) {
            return Err(GridError::InvalidSpacing {
                spacing: self.spacing,
            });
        }
        if self.nx == 0 || self.ny == 0 {
            return Err(GridError::InvalidNodeCount {
                nx: self.nx,
                ny: self.ny,
                reason: "need at least one node per axis",
            });
        }
        match self.nx.checked_mul(self.ny) {
            Some(n) if n <= Self::MAX_NODES => {}
            _ => {
                return Err(GridError::InvalidNodeCount {
                    nx: self.nx,
                    ny: self.ny,
                    reason: "more nodes than GridSpec::MAX_NODES",
                });
            }
        }
        let last = [
            self.origin[0] + self.spacing * (self.nx - 1) as f64,
            self.origin[1] + self.spacing * (self.ny - 1) as f64,
        ];
        if !(last[0].is_finite() && last[1].is_finite()) {
            return Err(GridError::InvalidOrigin {
                x: last[0],
                y: last[1],
            });
        }
        Ok(())
    }

    /// Number of nodes, `nx · ny`.
    #[inline]
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// Whether the grid has no nodes (never true for a validated grid).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Flat index of node `(ix, iy)`: `iy · nx + ix`.
    #[inline]
    pub fn index(&self, ix: usize, iy: usize) -> usize {
        iy * self.nx + ix
    }

    /// `(ix, iy)` of a flat index.
    #[inline]
    pub fn coords(&self, index: usize) -> (usize, usize) {
        (index % self.nx, index / self.nx)
    }

    /// Position of node `(ix, iy)`.
    #[inline]
    pub fn node(&self, ix: usize, iy: usize) -> Vector {
        Vector::new(
            self.origin[0] + self.spacing * ix as f64,
            self.origin[1] + self.spacing * iy as f64,
        )
    }

    /// Position of the node with flat index `index`.
    #[inline]
    pub fn node_at(&self, index: usize) -> Vector {
        let (ix, iy) = self.coords(index);
        self.node(ix, iy)
    }

    /// Position of the last node `(nx − 1, ny − 1)`: the upper-right corner of the grid.
    pub fn max(&self) -> Vector {
        self.node(self.nx - 1, self.ny - 1)
    }

    /// All node positions in flat-index order (allocates; for building k-d trees and for tests).
    pub fn positions(&self) -> Vec<[f64; 2]> {
        (0..self.len())
            .map(|i| {
                let p = self.node_at(i);
                [p.x, p.y]
            })
            .collect()
    }

    /// Inclusive index ranges `(ix0, ix1, iy0, iy1)` of the nodes whose coordinates lie
    /// within `[p − r, p + r]` on both axes, or `None` if that box misses the grid.
    /// `None` for non-finite input; no overflow on far-away points.
    #[inline]
    pub fn box_range(&self, p: &Vector, r: f64) -> Option<(usize, usize, usize, usize)> {
        let inv = 1.0 / self.spacing;
        if !(p.x.is_finite() && p.y.is_finite() && r.is_finite()) {
            return None;
        }
        let axis = |x: f64, o: f64, n: usize| -> Option<(usize, usize)> {
            let lo = ((x - r - o) * inv).ceil().max(0.0);
            let hi = ((x + r - o) * inv).floor().min((n - 1) as f64);
            if lo <= hi {
                Some((lo as usize, hi as usize))
            } else {
                None
            }
        };
        let (ix0, ix1) = axis(p.x, self.origin[0], self.nx)?;
        let (iy0, iy1) = axis(p.y, self.origin[1], self.ny)?;
        Some((ix0, ix1, iy0, iy1))
    }
}

impl Default for GridSpec {
    /// The thesis grid ([`GridSpec::thesis`]).
    fn default() -> Self {
        Self::thesis()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covering_counts_nodes() {
        let (a, b) = (Vector::new(0.0, 0.0), Vector::new(15.0, 15.0));
        assert_eq!(GridSpec::covering(a, b, 0.125).unwrap().nx, 121);
        assert_eq!(GridSpec::covering(a, b, 0.5).unwrap().nx, 31);
        let g = GridSpec::covering(a, Vector::new(15.1, 0.0), 0.25).unwrap();
        assert_eq!((g.nx, g.ny), (62, 1));
        assert!(g.max().x >= 15.1);
        assert!(GridSpec::covering(b, a, 0.25).is_err());
        assert!(GridSpec::covering(a, Vector::new(f64::NAN, 1.0), 0.25).is_err());
        assert!(GridSpec::covering(a, Vector::new(1e12, 1.0), 0.25).is_err());
        assert!(GridSpec::covering(a, b, 0.0).is_err());
    }

    #[test]
    fn validation_rejects_bad_grids() {
        assert!(GridSpec::new([0.0, 0.0], 0.25, 0, 3).is_err());
        assert!(GridSpec::new([f64::INFINITY, 0.0], 0.25, 3, 3).is_err());
        assert!(GridSpec::new([0.0, 0.0], f64::NAN, 3, 3).is_err());
        assert!(GridSpec::new([0.0, 0.0], 0.25, usize::MAX, 3).is_err());
        assert!(GridSpec::new([0.0, 0.0], 1e306, 1 << 12, 3).is_err());
    }

    #[test]
    fn index_and_coords_agree() {
        let g = GridSpec::new([1.0, -2.0], 0.5, 4, 3).unwrap();
        for i in 0..g.len() {
            let (ix, iy) = g.coords(i);
            assert_eq!(g.index(ix, iy), i);
        }
        assert_eq!(g.node_at(g.index(3, 2)), Vector::new(2.5, -1.0));
    }

    #[test]
    fn box_range_clamps_and_rejects() {
        let g = GridSpec::thesis();
        assert_eq!(g.box_range(&Vector::new(1.0, 1.0), 0.5), Some((2, 6, 2, 6)));
        assert_eq!(
            g.box_range(&Vector::new(0.1, 14.9), 0.5),
            Some((0, 2, 58, 60))
        );
        assert_eq!(g.box_range(&Vector::new(-5.0, 1.0), 0.5), None);
        assert_eq!(g.box_range(&Vector::new(1e300, 1.0), 0.5), None);
        assert_eq!(g.box_range(&Vector::new(f64::NAN, 1.0), 0.5), None);
        // Between nodes with r < spacing / 2: nothing.
        assert_eq!(g.box_range(&Vector::new(0.125, 0.125), 0.1), None);
    }
}
