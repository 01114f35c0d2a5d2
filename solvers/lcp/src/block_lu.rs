//! Sparse LU of a matrix with the point-block pattern of the Delassus matrix, with static
//! 2×2 pivots (one per contact point) on a fill-reducing order.
//!
//! The Newton matrix of a solve keeps the block pattern of `W`: a free row is a row of `W`,
//! a bound row an identity row, possibly coupled to its own point's normal. So the ordering
//! (approximate minimum degree of the point graph, faer's AMD with the `sparse` feature, the
//! natural order without it), the filled pattern and every update of the elimination are
//! worked out once per solve ([`BlockLu::analyse`]), and a factorisation is a pass over
//! precomputed block indices: no search, no pivoting, no allocation ([`BlockLu::factor`]).
//!
//! Pivots are the points' 2×2 diagonal blocks (inverted explicitly), chosen in advance. The
//! free part of the Newton matrix is symmetric positive (semi)definite plus a relative
//! regularisation, where Gaussian elimination needs no pivoting; a bound row's diagonal is 1
//! and its coupling `∓μ` stays inside its point's block. A singular or non-finite pivot block
//! makes [`BlockLu::factor`] return `false`; the Newton solver checks every solution's residual
//! and grows the regularisation when it is not accurate.

use deepcontact_core::ContactProblem;
use deepcontact_core::math::Real;

use crate::LcpError;
use crate::assembly::Delassus;
use crate::point_graph::PointGraph;

/// A 2×2 block, row-major: `[a00, a01, a10, a11]`.
type Block = [Real; 4];

#[inline(always)]
fn mul(a: &Block, b: &Block) -> Block {
    [
        a[0] * b[0] + a[1] * b[2],
        a[0] * b[1] + a[1] * b[3],
        a[2] * b[0] + a[3] * b[2],
        a[2] * b[1] + a[3] * b[3],
    ]
}

/// The inverse of a 2×2 block, `None` when singular or not finite.
#[inline(always)]
fn inverse(a: &Block) -> Option<Block> {
    let det = a[0] * a[3] - a[1] * a[2];
    let inv = 1.0 / det;
    (det != 0.0 && inv.is_finite()).then(|| [a[3] * inv, -a[1] * inv, -a[2] * inv, a[0] * inv])
}

/// Sparse block LU with a fixed pattern; see the module documentation.
#[derive(Debug, Default)]
pub(crate) struct BlockLu {
    /// Elimination position → point.
    order: Vec<u32>,
    /// Point → elimination position.
    pos: Vec<u32>,
    /// Filled pattern in elimination order, by block rows: columns of row `k` are
    /// `col[row_ptr[k]..row_ptr[k + 1]]`, ascending (lower part, diagonal, upper part).
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    /// Index of the diagonal block of each row.
    diag: Vec<usize>,
    /// For pivot `k` and the `a`-th column `s_a` of its upper part: the index of block
    /// `(s_a, k)` (`lower[upper_start(k) + a]`, aligned with the upper part of row `k`).
    lower: Vec<usize>,
    /// For pivot `k`: the indices of blocks `(s_a, s_b)` for all `a`, `b` of its upper part,
    /// row-major, from `target_ptr[k]`.
    target_ptr: Vec<usize>,
    targets: Vec<u32>,
    /// `W`'s blocks in the filled pattern (zero where only fill-in).
    w_blocks: Vec<Block>,
    /// The matrix being factorised, then its factors: unit-lower `L` below the diagonal,
    /// `U` on and above it.
    blocks: Vec<Block>,
    /// Inverses of the pivot blocks.
    inv_diag: Vec<Block>,
    /// Solve scratch, in elimination order.
    y: Vec<[Real; 2]>,
    /// The point graph the current analysis was made for (`graph` at that call):
    /// a problem with the same graph reuses the whole analysis.
    analysed_ptr: Vec<usize>,
    analysed: Vec<u32>,
    /// Analyses made and reused (for tests and diagnostics).
    pub(crate) analyses: u64,
    pub(crate) reuses: u64,
    /// The point graph being analysed.
    graph: PointGraph,
    // Analysis scratch.
    upper_ptr: Vec<usize>,
    upper: Vec<u32>,
    first_child: Vec<u32>,
    next_sibling: Vec<u32>,
    mark: Vec<u32>,
    cursor: Vec<usize>,
    where_col: Vec<usize>,
    #[cfg(feature = "sparse")]
    amd: AmdScratch,
}

/// faer's AMD buffers.
#[cfg(feature = "sparse")]
#[derive(Default)]
struct AmdScratch {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    mem: Option<faer::dyn_stack::MemBuffer>,
}

#[cfg(feature = "sparse")]
impl std::fmt::Debug for AmdScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "AmdScratch({} points)", self.perm.len())
    }
}

/// No entry of a list.
const NONE: u32 = u32::MAX;

/// The error for a system whose `count` `what` do not fit the 32-bit block indices.
fn too_large(rows: usize, what: &str, count: usize) -> LcpError {
    LcpError::Factorization {
        rows,
        reason: format!("{count} {what}: block indices are 32-bit"),
    }
}

/// [`too_large`] for a system of `points` points and `rows` rows, when it is.
fn check_points(points: usize, rows: usize) -> Result<(), LcpError> {
    if points >= NONE as usize {
        return Err(too_large(rows, "points", points));
    }
    Ok(())
}

impl BlockLu {
    /// Works out the order, the filled pattern and the update lists of `del`'s block pattern,
    /// and copies `W` into that pattern.
    pub(crate) fn analyse(&mut self, del: &Delassus) -> Result<(), LcpError> {
        check_points(del.points(), del.rows())?;
        self.point_graph(del);
        self.analyse_graph(del.rows())?;
        self.load_w_values(del);
        Ok(())
    }

    /// The point graph of `problem` from its structure alone, without `W`'s values (a point
    /// is adjacent to itself and to every point that shares a movable body with it: the
    /// pattern of `W` assembled sparse), for [`Self::analyse_structure`]. Returns the blocks
    /// of the pattern.
    pub(crate) fn structure(&mut self, problem: &ContactProblem) -> Result<usize, LcpError> {
        let points = problem.points.len();
        check_points(points, 2 * points)?;
        self.graph.of_problem(problem)?;
        Ok(self.graph.blocks())
    }

    /// [`Self::analyse`] of the graph of the last [`Self::structure`]: what
    /// [`Self::filled_blocks`] and [`Self::updates`] count then is the factorisation of that
    /// pattern, and an [`Self::analyse`] of the same graph reuses the work.
    pub(crate) fn analyse_structure(&mut self) -> Result<(), LcpError> {
        let rows = 2 * (self.graph.ptr.len().max(1) - 1);
        self.analyse_graph(rows)
    }

    /// The order, filled pattern and update lists of the point graph in `graph`,
    /// kept from the last call when the graph is the same.
    fn analyse_graph(&mut self, rows: usize) -> Result<(), LcpError> {
        // The analysis is a function of the point graph alone: a settled pile's islands
        // keep theirs from step to step.
        if self.graph.ptr == self.analysed_ptr && self.graph.adj == self.analysed {
            self.reuses += 1;
            return Ok(());
        }
        self.analysed_ptr.clear();
        self.analysed.clear();
        self.fill_reducing_order()?;
        self.symbolic_fill();
        self.block_rows();
        if self.col.len() >= NONE as usize {
            return Err(too_large(rows, "blocks after fill", self.col.len()));
        }
        self.update_targets()?;
        self.analysed_ptr.extend_from_slice(&self.graph.ptr);
        self.analysed.extend_from_slice(&self.graph.adj);
        self.analyses += 1;
        Ok(())
    }

    /// The point graph of `W` (a point and another are adjacent when their block is
    /// non-zero; every point is adjacent to itself) into `graph`.
    fn point_graph(&mut self, del: &Delassus) {
        let np = del.points();
        self.graph.ptr.clear();
        self.graph.adj.clear();
        self.graph.ptr.push(0);
        for j in 0..np {
            del.for_each_block_in_column(j, |i| self.graph.adj.push(i as u32));
            self.graph.ptr.push(self.graph.adj.len());
        }
    }

    /// `order` / `pos`: AMD on the point graph (natural order without the `sparse` feature).
    fn fill_reducing_order(&mut self) -> Result<(), LcpError> {
        let np = self.graph.ptr.len() - 1;
        self.order.clear();
        self.pos.clear();
        #[cfg(feature = "sparse")]
        {
            self.amd_order(np)?;
        }
        #[cfg(not(feature = "sparse"))]
        {
            self.order.extend(0..np as u32);
            self.pos.extend(0..np as u32);
        }
        Ok(())
    }

    #[cfg(feature = "sparse")]
    fn amd_order(&mut self, np: usize) -> Result<(), LcpError> {
        use faer::dyn_stack::{MemBuffer, MemStack};
        use faer::sparse::SymbolicSparseColMatRef;
        use faer::sparse::linalg::amd;
        let a = &mut self.amd;
        a.col_ptr.clear();
        a.col_ptr.extend(self.graph.ptr.iter().copied());
        a.row_idx.clear();
        a.row_idx.extend(self.graph.adj.iter().map(|&i| i as usize));
        a.perm.clear();
        a.perm.resize(np, 0);
        a.perm_inv.clear();
        a.perm_inv.resize(np, 0);
        let factorization = |e| LcpError::Factorization {
            rows: 2 * np,
            reason: format!("AMD ordering: {e:?}"),
        };
        let req = amd::order_scratch::<usize>(np, a.row_idx.len());
        let fits = a
            .mem
            .as_mut()
            .is_some_and(|m| MemStack::new(m).can_hold(req));
        if !fits {
            a.mem = Some(MemBuffer::try_new(req).map_err(|e| factorization(format!("{e:?}")))?);
        }
        let Some(mem) = a.mem.as_mut() else {
            return Err(factorization("no scratch".into()));
        };
        let pattern = SymbolicSparseColMatRef::new_checked(np, np, &a.col_ptr, None, &a.row_idx);
        amd::order(
            &mut a.perm,
            &mut a.perm_inv,
            pattern,
            amd::Control::default(),
            MemStack::new(mem),
        )
        .map_err(|e| factorization(format!("{e:?}")))?;
        self.order.extend(a.perm.iter().map(|&p| p as u32));
        self.pos.extend(a.perm_inv.iter().map(|&p| p as u32));
        Ok(())
    }

    /// The upper part of every row of the filled pattern (`upper_ptr` / `upper`, positions,
    /// ascending): the later neighbours of a pivot and those of its children in the
    /// elimination tree.
    fn symbolic_fill(&mut self) {
        let np = self.order.len();
        self.first_child.clear();
        self.first_child.resize(np, NONE);
        self.next_sibling.clear();
        self.next_sibling.resize(np, NONE);
        self.mark.clear();
        self.mark.resize(np, NONE);
        self.upper_ptr.clear();
        self.upper.clear();
        self.upper_ptr.push(0);
        for k in 0..np {
            let start = self.upper.len();
            self.mark[k] = k as u32;
            let point = self.order[k] as usize;
            for &i in &self.graph.adj[self.graph.ptr[point]..self.graph.ptr[point + 1]] {
                let p = self.pos[i as usize];
                if p as usize > k && self.mark[p as usize] != k as u32 {
                    self.mark[p as usize] = k as u32;
                    self.upper.push(p);
                }
            }
            let mut child = self.first_child[k];
            while child != NONE {
                let c = child as usize;
                for idx in self.upper_ptr[c]..self.upper_ptr[c + 1] {
                    let p = self.upper[idx];
                    if self.mark[p as usize] != k as u32 {
                        self.mark[p as usize] = k as u32;
                        self.upper.push(p);
                    }
                }
                child = self.next_sibling[c];
            }
            self.upper[start..].sort_unstable();
            if let Some(&parent) = self.upper.get(start) {
                self.next_sibling[k] = self.first_child[parent as usize];
                self.first_child[parent as usize] = k as u32;
            }
            self.upper_ptr.push(self.upper.len());
        }
    }

    /// The block rows of the filled pattern (lower part, diagonal, upper part) and `lower`,
    /// the index of block `(s, k)` for every `s` in the upper part of row `k`.
    fn block_rows(&mut self) {
        let np = self.order.len();
        // Lower-part counts: row s has one lower block per pivot k < s with s in upper(k).
        self.cursor.clear();
        self.cursor.resize(np, 0);
        for &s in &self.upper {
            self.cursor[s as usize] += 1;
        }
        self.row_ptr.clear();
        self.diag.clear();
        self.row_ptr.push(0);
        for k in 0..np {
            let lower = self.cursor[k];
            let upper = self.upper_ptr[k + 1] - self.upper_ptr[k];
            let start = self.row_ptr[k];
            self.diag.push(start + lower);
            self.row_ptr.push(start + lower + 1 + upper);
            self.cursor[k] = start;
        }
        self.col.clear();
        self.col.resize(self.row_ptr[np], 0);
        self.lower.clear();
        self.lower.resize(self.upper.len(), 0);
        for k in 0..np {
            let d = self.diag[k];
            self.col[d] = k as u32;
            for (a, idx) in (self.upper_ptr[k]..self.upper_ptr[k + 1]).enumerate() {
                let s = self.upper[idx] as usize;
                self.col[d + 1 + a] = s as u32;
                // Pivots run in ascending order, so row s's lower part fills ascending.
                let at = self.cursor[s];
                self.col[at] = k as u32;
                self.cursor[s] += 1;
                self.lower[idx] = at;
            }
        }
    }

    /// For every pivot, the index of each block `(s_a, s_b)` its elimination updates.
    fn update_targets(&mut self) -> Result<(), LcpError> {
        let np = self.order.len();
        self.where_col.clear();
        self.where_col.resize(np, usize::MAX);
        self.target_ptr.clear();
        self.targets.clear();
        self.target_ptr.push(0);
        for k in 0..np {
            let up = &self.upper[self.upper_ptr[k]..self.upper_ptr[k + 1]];
            for &sa in up {
                let row = self.row_ptr[sa as usize]..self.row_ptr[sa as usize + 1];
                for idx in row.clone() {
                    self.where_col[self.col[idx] as usize] = idx;
                }
                for &sb in up {
                    let idx = self.where_col[sb as usize];
                    if idx == usize::MAX || !row.contains(&idx) {
                        return Err(LcpError::Factorization {
                            rows: 2 * np,
                            reason: format!("block ({sa}, {sb}) missing from the filled pattern"),
                        });
                    }
                    self.targets.push(idx as u32);
                }
                for idx in row {
                    self.where_col[self.col[idx] as usize] = usize::MAX;
                }
            }
            self.target_ptr.push(self.targets.len());
        }
        Ok(())
    }

    /// `w_blocks`: `W` in the filled pattern.
    fn load_w_values(&mut self, del: &Delassus) {
        let np = self.order.len();
        self.w_blocks.clear();
        self.w_blocks.resize(self.col.len(), [0.0; 4]);
        for k in 0..np {
            let pi = self.order[k] as usize;
            for idx in self.row_ptr[k]..self.row_ptr[k + 1] {
                let pj = self.order[self.col[idx] as usize] as usize;
                self.w_blocks[idx] = del.block(pi, pj);
            }
        }
        self.blocks.clear();
        self.blocks.resize(self.col.len(), [0.0; 4]);
        self.inv_diag.clear();
        self.inv_diag.resize(np, [0.0; 4]);
        self.y.clear();
        self.y.resize(np, [0.0; 2]);
    }

    /// Starts a new matrix from `W` (the caller then edits rows).
    pub(crate) fn load_w(&mut self) {
        // Row by row: short copies run as vector moves (one long copy became a `rep movsb`
        // that cost more than the factorisation on the development machine).
        for k in 0..self.order.len() {
            let row = self.row_ptr[k]..self.row_ptr[k + 1];
            self.blocks[row.clone()].copy_from_slice(&self.w_blocks[row]);
        }
    }

    /// Sets the diagonal entry of matrix row `row` (`2 × point + {0, 1}`).
    pub(crate) fn set_diagonal(&mut self, row: usize, value: Real) {
        let k = self.pos[row / 2] as usize;
        let h = row % 2;
        self.blocks[self.diag[k]][3 * h] = value;
    }

    /// Replaces matrix row `row` by an identity row, with `coupling` at the other row of the
    /// same point (0 for none).
    pub(crate) fn set_bound_row(&mut self, row: usize, coupling: Real) {
        let k = self.pos[row / 2] as usize;
        let h = row % 2;
        for b in &mut self.blocks[self.row_ptr[k]..self.row_ptr[k + 1]] {
            b[2 * h] = 0.0;
            b[2 * h + 1] = 0.0;
        }
        let d = &mut self.blocks[self.diag[k]];
        d[3 * h] = 1.0;
        d[2 * h + (1 - h)] = coupling;
    }

    /// Factorises the loaded matrix in place; `false` on a singular or non-finite pivot.
    pub(crate) fn factor(&mut self) -> bool {
        for k in 0..self.order.len() {
            let Some(inv) = inverse(&self.blocks[self.diag[k]]) else {
                return false;
            };
            self.inv_diag[k] = inv;
            let (u0, u1) = (self.upper_ptr[k], self.upper_ptr[k + 1]);
            for &l in &self.lower[u0..u1] {
                self.blocks[l] = mul(&self.blocks[l], &inv);
            }
            let width = u1 - u0;
            let first_u = self.diag[k] + 1;
            let targets = &self.targets[self.target_ptr[k]..self.target_ptr[k + 1]];
            for (a, &l) in self.lower[u0..u1].iter().enumerate() {
                let la = self.blocks[l];
                for b in 0..width {
                    let u = self.blocks[first_u + b];
                    let t = &mut self.blocks[targets[a * width + b] as usize];
                    let p = mul(&la, &u);
                    t[0] -= p[0];
                    t[1] -= p[1];
                    t[2] -= p[2];
                    t[3] -= p[3];
                }
            }
        }
        true
    }

    /// Blocks of the filled pattern of the last analysis (the factors' storage: a triangular
    /// solve visits each once).
    pub(crate) fn filled_blocks(&self) -> usize {
        self.col.len()
    }

    /// Block updates `t ← t − l u` of one factorisation on the last analysis' pattern.
    pub(crate) fn updates(&self) -> usize {
        self.targets.len()
    }

    /// Solves `A x = rhs` in place with the last factorisation.
    pub(crate) fn solve(&mut self, rhs: &mut [Real]) {
        let np = self.order.len();
        if rhs.len() < 2 * np {
            return;
        }
        for (k, y) in self.y.iter_mut().enumerate() {
            let p = self.order[k] as usize;
            *y = [rhs[2 * p], rhs[2 * p + 1]];
        }
        for k in 0..np {
            let yk = self.y[k];
            for idx in self.upper_ptr[k]..self.upper_ptr[k + 1] {
                let l = &self.blocks[self.lower[idx]];
                let y = &mut self.y[self.upper[idx] as usize];
                y[0] -= l[0] * yk[0] + l[1] * yk[1];
                y[1] -= l[2] * yk[0] + l[3] * yk[1];
            }
        }
        for k in (0..np).rev() {
            let mut r = self.y[k];
            for idx in self.diag[k] + 1..self.row_ptr[k + 1] {
                let u = &self.blocks[idx];
                let x = self.y[self.col[idx] as usize];
                r[0] -= u[0] * x[0] + u[1] * x[1];
                r[1] -= u[2] * x[0] + u[3] * x[1];
            }
            let d = &self.inv_diag[k];
            self.y[k] = [d[0] * r[0] + d[1] * r[1], d[2] * r[0] + d[3] * r[1]];
        }
        for (k, y) in self.y.iter().enumerate() {
            let p = self.order[k] as usize;
            rhs[2 * p] = y[0];
            rhs[2 * p + 1] = y[1];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::AssemblyMode;
    use deepcontact_core::math::Vector;
    use deepcontact_core::rng::PortableRng;
    use deepcontact_core::{ContactId, ContactProblem, PointDesc, ProblemBody};
    use faer::Mat;
    use faer::linalg::solvers::Solve;

    /// A random island: `bodies` dynamic bodies (masses over two decades) and a ground,
    /// `points` contacts between random pairs, normals and anchors at random.
    fn random_island(seed: u64, bodies: usize, points: usize) -> ContactProblem {
        let mut rng = PortableRng::new(seed);
        let mut p = ContactProblem::new();
        let body = |rng: &mut PortableRng, inv_mass: Real, inv_inertia: Real| ProblemBody {
            world_index: u32::MAX,
            position: Vector::new(rng.uniform_range(-5.0, 5.0), rng.uniform_range(-5.0, 5.0)),
            angle: 0.0,
            linear_velocity: Vector::new(rng.normal(), rng.normal()),
            angular_velocity: rng.normal(),
            inv_mass,
            inv_inertia,
        };
        let ground = body(&mut rng, 0.0, 0.0);
        p.add_body(ground);
        for _ in 0..bodies {
            let (m, i) = (rng.uniform_range(0.1, 10.0), rng.uniform_range(0.1, 10.0));
            let b = body(&mut rng, m, i);
            p.add_body(b);
        }
        for f in 0..points {
            let b = 1 + (rng.next_u64() % bodies as u64) as u32;
            let a = (rng.next_u64() % (bodies as u64 + 1)) as u32;
            let a = if a == b { 0 } else { a };
            let angle = rng.uniform_range(0.0, std::f64::consts::TAU);
            p.begin_manifold();
            p.add_point(&PointDesc {
                id: ContactId {
                    body_a: a.min(b),
                    body_b: a.max(b),
                    feature_a: f as u64,
                    feature_b: 0,
                },
                body_a: a,
                body_b: b,
                point: p.bodies[b as usize].position
                    + Vector::new(rng.normal(), rng.normal()) * 0.5,
                normal: Vector::new(angle.cos(), angle.sin()),
                separation: -0.01,
                friction: rng.uniform_range(0.1, 1.0),
                restitution: 0.0,
                restitution_threshold: 0.5,
            })
            .unwrap();
        }
        p
    }

    /// A Newton-like matrix on `del`'s pattern: free rows of `W` with the diagonal ×
    /// (1 + reg), about a third of the rows bound (identity, tangents coupled ∓μ to their
    /// normal), loaded into `lu` and built densely for the reference.
    fn newton_like(
        del: &Delassus,
        lu: &mut BlockLu,
        rng: &mut PortableRng,
        reg: Real,
    ) -> Mat<Real> {
        let n = del.rows();
        let mut k = del.to_dense();
        lu.load_w();
        for r in 0..n {
            if rng.uniform() < 0.65 {
                let d = del.diagonal()[r] * (1.0 + reg);
                k[(r, r)] = d;
                lu.set_diagonal(r, d);
            } else {
                let c = if r % 2 == 1 {
                    del.friction()[r / 2] * rng.uniform_range(-1.0, 1.0)
                } else {
                    0.0
                };
                for j in 0..n {
                    k[(r, j)] = 0.0;
                }
                k[(r, r)] = 1.0;
                k[(r, r ^ 1)] = c;
                lu.set_bound_row(r, c);
            }
        }
        k
    }

    fn inf_norm(m: &Mat<Real>) -> Real {
        (0..m.nrows())
            .map(|i| (0..m.ncols()).map(|j| m[(i, j)].abs()).sum::<Real>())
            .fold(0.0, Real::max)
    }

    /// Solutions on seeded random islands of 1 to 150 points, dense and sparse assembly,
    /// have a backward error within a size-scaled bound, `‖Kx − b‖ ≤ c·n·ε·(‖K‖‖x‖ + ‖b‖)`,
    /// and agree with faer's dense partial-pivoting LU where `K` is well conditioned.
    #[test]
    fn solves_random_newton_systems_to_a_size_scaled_tolerance() {
        for seed in 0..40u64 {
            let points = 1 + (seed as usize * 37) % 150;
            let bodies = 1 + points / 2;
            let problem = random_island(seed, bodies, points);
            for mode in [AssemblyMode::Dense, AssemblyMode::Sparse] {
                let mut del = Delassus::new();
                del.assemble(&problem, mode, crate::DEFAULT_DENSE_THRESHOLD)
                    .unwrap();
                let mut lu = BlockLu::default();
                lu.analyse(&del).unwrap();
                let mut rng = PortableRng::new(seed ^ 0xb10c);
                let k = newton_like(&del, &mut lu, &mut rng, 1e-3);
                let n = del.rows();
                let b: Vec<Real> = (0..n).map(|_| rng.normal()).collect();
                assert!(lu.factor(), "seed {seed}: singular pivot");
                let mut x = b.clone();
                lu.solve(&mut x);
                let xm = Mat::from_fn(n, 1, |i, _| x[i]);
                let r = &k * &xm;
                let res = (0..n)
                    .map(|i| (r[(i, 0)] - b[i]).abs())
                    .fold(0.0, Real::max);
                let x_norm = x.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
                let b_norm = b.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
                let tol = 64.0 * n as Real * Real::EPSILON * (inf_norm(&k) * x_norm + b_norm);
                assert!(
                    res <= tol,
                    "seed {seed} {mode:?}: residual {res:e} > {tol:e}"
                );
                let reference = k.partial_piv_lu().solve(Mat::from_fn(n, 1, |i, _| b[i]));
                let diff = (0..n)
                    .map(|i| (reference[(i, 0)] - x[i]).abs())
                    .fold(0.0, Real::max);
                assert!(
                    diff <= 1e-6 * x_norm.max(1.0),
                    "seed {seed} {mode:?}: differs from faer's LU by {diff:e}"
                );
            }
        }
    }

    /// A factorisation reused for a second matrix of the same pattern gives bit-identical
    /// results to a fresh analysis.
    #[test]
    fn refactorising_is_bit_identical_to_a_fresh_analysis() {
        let problem = random_island(7, 60, 120);
        let mut del = Delassus::new();
        del.assemble(&problem, AssemblyMode::Sparse, 0).unwrap();
        let solve = |lu: &mut BlockLu, seed: u64| {
            let mut rng = PortableRng::new(seed);
            newton_like(&del, lu, &mut rng, 1e-6);
            assert!(lu.factor());
            let mut x: Vec<Real> = (0..del.rows()).map(|i| (i % 7) as Real - 3.0).collect();
            lu.solve(&mut x);
            x
        };
        let mut reused = BlockLu::default();
        reused.analyse(&del).unwrap();
        solve(&mut reused, 1);
        let again = solve(&mut reused, 2);
        let mut fresh = BlockLu::default();
        fresh.analyse(&del).unwrap();
        let first = solve(&mut fresh, 2);
        assert!(
            again
                .iter()
                .zip(&first)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }

    /// An analysis kept for the same contact graph with new values (the next step of a
    /// settled island) gives bit-identical results to a fresh analysis, and a changed graph
    /// is analysed afresh.
    #[test]
    fn an_analysis_reused_for_an_unchanged_graph_is_bit_identical_to_a_fresh_one() {
        let solve = |del: &Delassus, lu: &mut BlockLu| {
            let mut rng = PortableRng::new(5);
            newton_like(del, lu, &mut rng, 1e-6);
            assert!(lu.factor());
            let mut x: Vec<Real> = (0..del.rows()).map(|i| (i % 5) as Real - 2.0).collect();
            lu.solve(&mut x);
            x
        };
        let mut first = random_island(11, 50, 100);
        let mut lu = BlockLu::default();
        let mut del = Delassus::new();
        del.assemble(&first, AssemblyMode::Sparse, 0).unwrap();
        lu.analyse(&del).unwrap();
        solve(&del, &mut lu);
        // Same graph, other values: the bodies moved on.
        for b in &mut first.bodies {
            b.linear_velocity *= 0.5;
            b.inv_mass *= 1.25;
        }
        del.assemble(&first, AssemblyMode::Sparse, 0).unwrap();
        lu.analyse(&del).unwrap();
        assert_eq!((lu.analyses, lu.reuses), (1, 1));
        let reused = solve(&del, &mut lu);
        let mut fresh = BlockLu::default();
        fresh.analyse(&del).unwrap();
        let expected = solve(&del, &mut fresh);
        assert!(
            reused
                .iter()
                .zip(&expected)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        // Another graph: analysed again.
        let other = random_island(12, 50, 100);
        del.assemble(&other, AssemblyMode::Sparse, 0).unwrap();
        lu.analyse(&del).unwrap();
        assert_eq!((lu.analyses, lu.reuses), (2, 1));
    }

    /// The pattern worked out from the problem's structure is the pattern of `W` assembled
    /// sparse: the same blocks and factors, and an analysis of the assembled `W` after it is
    /// a reuse; an island with a static body among its points included.
    #[test]
    fn the_structural_pattern_is_the_assembled_one() {
        for (seed, bodies, points) in [(11, 50, 100), (3, 2, 1), (21, 120, 260)] {
            let problem = random_island(seed, bodies, points);
            let mut lu = BlockLu::default();
            let blocks = lu.structure(&problem).unwrap();
            lu.analyse_structure().unwrap();
            let (filled, updates) = (lu.filled_blocks(), lu.updates());
            let mut del = Delassus::new();
            del.assemble(&problem, AssemblyMode::Sparse, 0).unwrap();
            assert_eq!(4 * blocks, del.nnz(), "seed {seed}");
            lu.analyse(&del).unwrap();
            assert_eq!((lu.analyses, lu.reuses), (1, 1), "seed {seed}");
            let mut fresh = BlockLu::default();
            fresh.analyse(&del).unwrap();
            assert_eq!((fresh.filled_blocks(), fresh.updates()), (filled, updates));
            assert!(updates > 0 || points < 3, "seed {seed}: nothing eliminated");
        }
    }

    /// Under a budget too small for one iteration Newton may answer with a lower bound
    /// instead of analysing the factors: the bound is above the budget and below the exact
    /// weight, so the decision (no iteration) is the one the exact weight gives.
    #[test]
    fn a_newton_weight_bound_decides_as_the_exact_weight() {
        use deepcontact_core::VelocitySolver;
        for (seed, bodies, points) in [(11, 50, 100), (21, 120, 260), (4, 3, 5)] {
            let problem = random_island(seed, bodies, points);
            let exact = crate::NewtonSolver::new()
                .pass_cost(&problem, None)
                .unwrap();
            for budget in [0, 1, 7, 15, exact.passes(1) - 1, exact.passes(1), 10_000] {
                let cost = crate::NewtonSolver::new()
                    .pass_cost(&problem, Some(budget))
                    .unwrap();
                assert!(cost.passes(1) <= exact.passes(1), "seed {seed}");
                assert_eq!(
                    cost.iterations_within(budget, 20),
                    exact.iterations_within(budget, 20),
                    "seed {seed}, budget {budget}"
                );
                if exact.passes(1) <= budget {
                    assert_eq!(cost, exact, "seed {seed}, budget {budget}");
                }
            }
        }
    }

    /// A point naming a body the problem does not have is an error, not a panic.
    #[test]
    fn the_structural_pattern_rejects_bad_body_indices() {
        let mut problem = random_island(5, 10, 20);
        problem.points[3].body_b = 99;
        let mut lu = BlockLu::default();
        assert!(matches!(
            lu.structure(&problem),
            Err(LcpError::InvalidProblem(_))
        ));
    }

    /// A singular pivot block (a free row whose diagonal is zero on an isolated point) is
    /// reported, not divided by.
    #[test]
    fn a_singular_pivot_is_reported() {
        let problem = random_island(3, 2, 1);
        let mut del = Delassus::new();
        del.assemble(
            &problem,
            AssemblyMode::Dense,
            crate::DEFAULT_DENSE_THRESHOLD,
        )
        .unwrap();
        let mut lu = BlockLu::default();
        lu.analyse(&del).unwrap();
        lu.load_w();
        lu.set_diagonal(0, 0.0);
        lu.set_bound_row(1, 0.0);
        assert!(!lu.factor());
    }
}
