//! The point graph of an island's Delassus matrix `W`, from the problem's structure alone.
//!
//! Block `(i, j)` of `W = J M⁻¹ Jᵀ` is a sum over the bodies points `i` and `j` share, with
//! each body's inverse mass and inertia: it is stored (sparse assembly) exactly when the two
//! points touch a common movable body, and the diagonal block always. So the pattern, and what
//! a solve on it costs, is known before any value of `W` is computed.

use deepcontact_core::{ContactProblem, CoreError};

use crate::LcpError;

/// Adjacency of contact points: `adj[ptr[j]..ptr[j + 1]]` are the points whose block in
/// block column `j` is stored, ascending, `j` itself included. Buffers are kept between uses.
#[derive(Debug, Default, Clone)]
pub(crate) struct PointGraph {
    /// Start of each point's list in `adj`, one more entry than points.
    pub(crate) ptr: Vec<usize>,
    /// The lists, concatenated.
    pub(crate) adj: Vec<u32>,
    // Scratch: the points touching each movable body, as `body_points[body_ptr[k]..]`.
    body_ptr: Vec<usize>,
    body_points: Vec<u32>,
    cursor: Vec<usize>,
}

impl PointGraph {
    /// The graph of `problem`: each point adjacent to itself and to the points that touch one
    /// of its movable bodies (non-zero inverse mass or inertia). A point naming a body the
    /// problem does not have is an error.
    pub(crate) fn of_problem(&mut self, problem: &ContactProblem) -> Result<(), LcpError> {
        let nb = problem.bodies.len();
        let movable = |b: u32| {
            let body = &problem.bodies[b as usize];
            body.inv_mass != 0.0 || body.inv_inertia != 0.0
        };
        self.body_ptr.clear();
        self.body_ptr.resize(nb + 1, 0);
        for (i, p) in problem.points.iter().enumerate() {
            if p.body_a as usize >= nb || p.body_b as usize >= nb {
                return Err(LcpError::InvalidProblem(CoreError::InvalidProblem(
                    format!("point {i} has bad body indices"),
                )));
            }
            for b in [p.body_a, p.body_b] {
                if movable(b) {
                    self.body_ptr[b as usize + 1] += 1;
                }
            }
        }
        for k in 0..nb {
            self.body_ptr[k + 1] += self.body_ptr[k];
        }
        self.body_points.clear();
        self.body_points.resize(self.body_ptr[nb], 0);
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.body_ptr[..nb]);
        for (i, p) in problem.points.iter().enumerate() {
            for b in [p.body_a, p.body_b] {
                if movable(b) {
                    let slot = &mut self.cursor[b as usize];
                    self.body_points[*slot] = i as u32;
                    *slot += 1;
                }
            }
        }
        self.ptr.clear();
        self.adj.clear();
        self.ptr.push(0);
        for (j, p) in problem.points.iter().enumerate() {
            let start = self.adj.len();
            self.adj.push(j as u32);
            for b in [p.body_a, p.body_b] {
                if movable(b) {
                    let (from, to) = (self.body_ptr[b as usize], self.body_ptr[b as usize + 1]);
                    self.adj.extend_from_slice(&self.body_points[from..to]);
                }
            }
            self.adj[start..].sort_unstable();
            let mut kept = start;
            for r in start..self.adj.len() {
                if r == start || self.adj[r] != self.adj[kept - 1] {
                    self.adj[kept] = self.adj[r];
                    kept += 1;
                }
            }
            self.adj.truncate(kept);
            self.ptr.push(self.adj.len());
        }
        Ok(())
    }

    /// Stored blocks of `W` (2 × 2 each).
    pub(crate) fn blocks(&self) -> usize {
        self.adj.len()
    }
}
