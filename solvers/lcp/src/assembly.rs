//! Assembly of the Delassus matrix `W = J M⁻¹ Jᵀ` and of `q = J v_free − bias`.
//!
//! # Layout
//! Point `i` of the problem owns two rows: `2i` (normal) and `2i + 1` (tangent, along
//! `t = (−n.y, n.x)`). Each body has three velocity degrees of freedom `(vx, vy, ω)` with
//! inverse mass `diag(m⁻¹, m⁻¹, I⁻¹)`. The normal row of a point between bodies A and B is
//! `J = [−nᵀ, −(r_A × n) | nᵀ, r_B × n]`, the tangent row the same with `t`, so that with
//! `λ` the impulses the relative velocity after the solve is `Wλ + q`:
//!
//! * `v = v_free + M⁻¹ Jᵀ λ`,
//! * `J v − bias = Wλ + q` with `q = J v_free − bias` (the restitution bias sits on
//!   normal rows only),
//!
//! and the frictional contact problem is: `λn ≥ 0 ⟂ (Wλ + q)n ≥ 0`, and per point `λt` in
//! `[−μλn, μλn]` with `(Wλ + q)t ≥ 0` at the lower bound, `≤ 0` at the upper bound and
//! `= 0` strictly inside.
//!
//! # Dense or sparse
//! Islands with at most [`DEFAULT_DENSE_THRESHOLD`] rows (64 points) are assembled into a
//! dense faer [`Mat`] (`W = (J M⁻¹) Jᵀ` through faer's matrix product); larger ones into
//! a compressed-column matrix read through faer's [`SparseColMatRef`], built by
//! accumulating `J_i M⁻¹ J_jᵀ` over the bodies that rows `i` and `j` share. A contact
//! island's `W` has `O(points)` non-zeros (each point couples only with the points of its
//! two bodies), so beyond a few dozen points the sparse form is both smaller and faster
//! for a sweep; the threshold is where a dense sweep (`rows²` multiply-adds) stops being
//! cheap. Both paths give the same matrix (tested) and all buffers are reused between
//! assemblies.

use deepcontact_core::math::{Real, Vector, Velocity, cross};
use deepcontact_core::{ContactProblem, Impulse};
#[cfg(feature = "sparse")]
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Accum, Mat, MatMut, MatRef, Par};

use crate::LcpError;

/// Default largest number of rows (2 per point) assembled densely in [`AssemblyMode::Auto`].
pub const DEFAULT_DENSE_THRESHOLD: usize = 128;

/// Largest number of rows a dense assembly accepts (a forced [`AssemblyMode::Dense`] above it
/// is an error rather than a multi-gigabyte allocation).
pub const MAX_DENSE_ROWS: usize = 4096;

/// How to store the assembled Delassus matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AssemblyMode {
    /// Dense up to the solver's `dense_threshold` rows, sparse above (default).
    #[default]
    Auto,
    /// Always dense (at most [`MAX_DENSE_ROWS`] rows).
    Dense,
    /// Always sparse.
    Sparse,
}

impl AssemblyMode {
    /// Whether a problem of `rows` rows is assembled densely under this mode.
    pub fn is_dense_for(self, rows: usize, threshold: usize) -> bool {
        match self {
            AssemblyMode::Auto => rows <= threshold,
            AssemblyMode::Dense => true,
            AssemblyMode::Sparse => false,
        }
    }
}

/// One row of `J`: the two bodies and the three coefficients on each.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct JacRow {
    pub(crate) a: u32,
    pub(crate) b: u32,
    pub(crate) ja: [Real; 3],
    pub(crate) jb: [Real; 3],
}

/// Whether a body with these inverse masses moves.
fn movable(m: &[Real; 3]) -> bool {
    m.iter().any(|&v| v != 0.0)
}

#[inline(always)]
fn dot3(x: &[Real; 3], m: &[Real; 3], y: &[Real; 3]) -> Real {
    x[0] * m[0] * y[0] + x[1] * m[1] * y[1] + x[2] * m[2] * y[2]
}

/// The assembled frictional contact problem of one island: `W`, `q`, the effective masses,
/// the friction coefficients and what is needed to recover velocities.
///
/// Built by [`Delassus::assemble`]; buffers are kept and reused by the next assembly.
#[derive(Debug)]
pub struct Delassus {
    rows: usize,
    bodies: usize,
    dense: bool,
    jac: Vec<JacRow>,
    inv_mass: Vec<[Real; 3]>,
    v_free: Vec<[Real; 3]>,
    q: Vec<Real>,
    m_eff: Vec<Real>,
    mu: Vec<Real>,
    diag: Vec<Real>,
    // Dense storage.
    w_dense: Mat<Real>,
    j_dense: Mat<Real>,
    jm_dense: Mat<Real>,
    // Sparse storage: compressed columns, rows sorted within each column.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<Real>,
    // Assembly scratch.
    adj_ptr: Vec<usize>,
    adj: Vec<u32>,
    mark: Vec<usize>,
    slot: Vec<usize>,
    blocks: Vec<(u32, [Real; 4])>,
}

impl Default for Delassus {
    fn default() -> Self {
        Self {
            rows: 0,
            bodies: 0,
            dense: true,
            jac: Vec::new(),
            inv_mass: Vec::new(),
            v_free: Vec::new(),
            q: Vec::new(),
            m_eff: Vec::new(),
            mu: Vec::new(),
            diag: Vec::new(),
            w_dense: Mat::new(),
            j_dense: Mat::new(),
            jm_dense: Mat::new(),
            col_ptr: Vec::new(),
            row_idx: Vec::new(),
            values: Vec::new(),
            adj_ptr: Vec::new(),
            adj: Vec::new(),
            mark: Vec::new(),
            slot: Vec::new(),
            blocks: Vec::new(),
        }
    }
}

impl Delassus {
    /// An empty assembly (0 rows).
    pub fn new() -> Self {
        Self::default()
    }

    /// Assembles `problem` (which the caller has validated, or trusts) with the given storage
    /// choice. Fails on non-finite results or a forced dense assembly above
    /// [`MAX_DENSE_ROWS`]; never panics on a problem whose indices are in range, and reports
    /// out-of-range body indices as [`LcpError::InvalidProblem`].
    pub fn assemble(
        &mut self,
        problem: &ContactProblem,
        mode: AssemblyMode,
        threshold: usize,
    ) -> Result<(), LcpError> {
        let rows = 2 * problem.points.len();
        let nb = problem.bodies.len();
        let dense = mode.is_dense_for(rows, threshold);
        if dense && rows > MAX_DENSE_ROWS {
            return Err(LcpError::TooLargeForDense {
                rows,
                limit: MAX_DENSE_ROWS,
            });
        }
        self.rows = rows;
        self.bodies = nb;
        self.dense = dense;
        self.load_bodies(problem);
        self.jacobian_rows(problem)?;
        if dense {
            self.assemble_dense()
        } else {
            self.assemble_sparse()
        }
        self.diag.clear();
        for i in 0..rows / 2 {
            let b = self.block(i, i);
            self.diag.extend([b[0], b[3]]);
        }
        self.check_finite()
    }

    /// Inverse masses and free velocities of the bodies.
    fn load_bodies(&mut self, problem: &ContactProblem) {
        self.inv_mass.clear();
        self.v_free.clear();
        for b in &problem.bodies {
            self.inv_mass.push([b.inv_mass, b.inv_mass, b.inv_inertia]);
            self.v_free
                .push([b.linear_velocity.x, b.linear_velocity.y, b.angular_velocity]);
        }
    }

    /// The rows of `J` (normal, then tangent, per point), `q`, the effective masses and the
    /// friction coefficients.
    fn jacobian_rows(&mut self, problem: &ContactProblem) -> Result<(), LcpError> {
        let nb = problem.bodies.len();
        self.jac.clear();
        self.q.clear();
        self.m_eff.clear();
        self.mu.clear();
        for (i, p) in problem.points.iter().enumerate() {
            if p.body_a as usize >= nb || p.body_b as usize >= nb {
                return Err(LcpError::InvalidProblem(
                    deepcontact_core::CoreError::InvalidProblem(format!(
                        "point {i} has bad body indices"
                    )),
                ));
            }
            let (n, t) = (p.normal, p.tangent());
            for (d, bias, mass) in [
                (n, p.velocity_bias, p.normal_mass),
                (t, 0.0, p.tangent_mass),
            ] {
                let row = JacRow {
                    a: p.body_a,
                    b: p.body_b,
                    ja: [-d.x, -d.y, -cross(&p.r_a, &d)],
                    jb: [d.x, d.y, cross(&p.r_b, &d)],
                };
                let (va, vb) = (&self.v_free[row.a as usize], &self.v_free[row.b as usize]);
                let jv = row.ja[0] * va[0]
                    + row.ja[1] * va[1]
                    + row.ja[2] * va[2]
                    + row.jb[0] * vb[0]
                    + row.jb[1] * vb[1]
                    + row.jb[2] * vb[2];
                self.q.push(jv - bias);
                self.m_eff.push(mass);
                self.jac.push(row);
            }
            self.mu.push(p.friction);
        }
        Ok(())
    }

    /// Fails on the first non-finite entry of `q`, the effective masses or `W`.
    fn check_finite(&self) -> Result<(), LcpError> {
        let non_finite = |what, row| LcpError::NonFinite {
            what,
            row,
            iteration: 0,
        };
        if let Some(row) = self.q.iter().position(|v| !v.is_finite()) {
            return Err(non_finite("free velocity q", row));
        }
        if let Some(row) = self.m_eff.iter().position(|v| !v.is_finite()) {
            return Err(non_finite("effective mass", row));
        }
        let bad = if self.dense {
            (0..self.rows).find(|&j| self.w_dense.col_as_slice(j).iter().any(|v| !v.is_finite()))
        } else {
            (0..self.rows).find(|&j| {
                self.values[self.col_ptr[j]..self.col_ptr[j + 1]]
                    .iter()
                    .any(|v| !v.is_finite())
            })
        };
        match bad {
            Some(row) => Err(non_finite("Delassus entry", row)),
            None => Ok(()),
        }
    }

    /// Dense path: `W = (J M⁻¹) Jᵀ` with faer's matrix product.
    fn assemble_dense(&mut self) {
        let (n, dof) = (self.rows, 3 * self.bodies);
        self.j_dense.resize_with(n, dof, |_, _| 0.0);
        self.jm_dense.resize_with(n, dof, |_, _| 0.0);
        self.w_dense.resize_with(n, n, |_, _| 0.0);
        self.j_dense.fill(0.0);
        self.jm_dense.fill(0.0);
        for (i, r) in self.jac.iter().enumerate() {
            for k in 0..3 {
                let (ca, cb) = (3 * r.a as usize + k, 3 * r.b as usize + k);
                self.j_dense[(i, ca)] += r.ja[k];
                self.j_dense[(i, cb)] += r.jb[k];
            }
        }
        for (body, m) in self.inv_mass.iter().enumerate() {
            for (k, &mk) in m.iter().enumerate() {
                let c = 3 * body + k;
                for i in 0..n {
                    self.jm_dense[(i, c)] = self.j_dense[(i, c)] * mk;
                }
            }
        }
        faer::linalg::matmul::matmul(
            self.w_dense.as_mut(),
            Accum::Replace,
            self.jm_dense.as_ref(),
            self.j_dense.as_ref().transpose(),
            1.0,
            Par::Seq,
        );
    }

    /// Sparse path: per point, accumulate the 2×2 blocks `J_i M_k⁻¹ J_jᵀ` over the dynamic
    /// bodies `k` it shares with every other point `j`.
    fn assemble_sparse(&mut self) {
        self.body_adjacency();
        let np = self.rows / 2;
        self.mark.clear();
        self.mark.resize(np, 0);
        self.slot.clear();
        self.slot.resize(np, 0);
        self.col_ptr.clear();
        self.row_idx.clear();
        self.values.clear();
        self.col_ptr.push(0);
        for i in 0..np {
            self.point_blocks(i);
            for c in 0..2 {
                for (j, blk) in &self.blocks {
                    let j = *j as usize;
                    self.row_idx.push(2 * j);
                    self.values.push(blk[2 * c]);
                    self.row_idx.push(2 * j + 1);
                    self.values.push(blk[2 * c + 1]);
                }
                self.col_ptr.push(self.row_idx.len());
            }
        }
    }

    /// Body → (point, side) adjacency of the dynamic bodies: `adj[adj_ptr[k]..adj_ptr[k + 1]]`
    /// holds `2 × point + side` for every point touching body `k`.
    fn body_adjacency(&mut self) {
        let np = self.rows / 2;
        let nb = self.bodies;
        self.adj_ptr.clear();
        self.adj_ptr.resize(nb + 1, 0);
        for p in 0..np {
            let r = &self.jac[2 * p];
            for body in [r.a, r.b] {
                if movable(&self.inv_mass[body as usize]) {
                    self.adj_ptr[body as usize + 1] += 1;
                }
            }
        }
        for k in 0..nb {
            self.adj_ptr[k + 1] += self.adj_ptr[k];
        }
        self.adj.clear();
        self.adj.resize(self.adj_ptr[nb], 0);
        self.slot.clear();
        self.slot.extend_from_slice(&self.adj_ptr[..nb]);
        for p in 0..np {
            let r = &self.jac[2 * p];
            for (side, body) in [(0u32, r.a), (1u32, r.b)] {
                if movable(&self.inv_mass[body as usize]) {
                    let s = &mut self.slot[body as usize];
                    self.adj[*s] = 2 * p as u32 + side;
                    *s += 1;
                }
            }
        }
    }

    /// `blocks`: the 2×2 blocks of block column `i` (its normal and tangent columns), one per
    /// point sharing a dynamic body with point `i` and for `i` itself, sorted by point.
    fn point_blocks(&mut self, i: usize) {
        let side_of = |r: &JacRow, side: u32| if side == 0 { (r.a, r.ja) } else { (r.b, r.jb) };
        self.blocks.clear();
        let stamp = i + 1;
        // The point itself is always present (even between two immovable bodies).
        self.mark[i] = stamp;
        self.slot[i] = 0;
        self.blocks.push((i as u32, [0.0; 4]));
        for side_i in 0..2u32 {
            let (body, jn_i) = side_of(&self.jac[2 * i], side_i);
            let (_, jt_i) = side_of(&self.jac[2 * i + 1], side_i);
            let m = self.inv_mass[body as usize];
            if !movable(&m) {
                continue;
            }
            for &code in &self.adj[self.adj_ptr[body as usize]..self.adj_ptr[body as usize + 1]] {
                let (j, side_j) = ((code / 2) as usize, code % 2);
                let (body_j, jn_j) = side_of(&self.jac[2 * j], side_j);
                debug_assert_eq!(body_j, body);
                let (_, jt_j) = side_of(&self.jac[2 * j + 1], side_j);
                if self.mark[j] != stamp {
                    self.mark[j] = stamp;
                    self.slot[j] = self.blocks.len();
                    self.blocks.push((j as u32, [0.0; 4]));
                }
                let blk = &mut self.blocks[self.slot[j]].1;
                // Column 2i (normal of i): rows 2j, 2j+1; column 2i+1 (tangent of i).
                blk[0] += dot3(&jn_j, &m, &jn_i);
                blk[1] += dot3(&jt_j, &m, &jn_i);
                blk[2] += dot3(&jn_j, &m, &jt_i);
                blk[3] += dot3(&jt_j, &m, &jt_i);
            }
        }
        self.blocks.sort_unstable_by_key(|b| b.0);
    }

    /// Rows of the system (2 per point).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Points of the system.
    pub fn points(&self) -> usize {
        self.rows / 2
    }

    /// Whether the last assembly is dense.
    pub fn is_dense(&self) -> bool {
        self.dense
    }

    /// Stored entries of `W` (`rows²` when dense).
    pub fn nnz(&self) -> usize {
        if self.dense {
            self.rows * self.rows
        } else {
            self.values.len()
        }
    }

    /// `q = J v_free − bias`, one per row.
    pub fn q(&self) -> &[Real] {
        &self.q
    }

    /// The problem's effective masses, one per row (`normal_mass`, `tangent_mass`; these
    /// equal `1 / W_ii`). They scale the projected steps and the natural-map residual,
    /// exactly as in deepcontact-pgs.
    pub fn effective_mass(&self) -> &[Real] {
        &self.m_eff
    }

    /// The diagonal of `W`, one per row.
    pub fn diagonal(&self) -> &[Real] {
        &self.diag
    }

    /// Friction coefficient of each point.
    pub fn friction(&self) -> &[Real] {
        &self.mu
    }

    /// The dense `W` when the last assembly was dense.
    pub fn dense(&self) -> Option<MatRef<'_, Real>> {
        self.dense.then(|| self.w_dense.as_ref())
    }

    /// The sparse `W` (compressed columns, symmetric) when the last assembly was sparse
    /// (feature `sparse`, on by default).
    #[cfg(feature = "sparse")]
    pub fn sparse(&self) -> Option<SparseColMatRef<'_, usize, Real>> {
        (!self.dense).then(|| SparseColMatRef::new(self.sparse_symbolic(), &self.values))
    }

    /// Symbolic structure of the sparse `W` (call only when sparse).
    #[cfg(feature = "sparse")]
    pub(crate) fn sparse_symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        SymbolicSparseColMatRef::new_checked(
            self.rows,
            self.rows,
            &self.col_ptr,
            None,
            &self.row_idx,
        )
    }

    /// Stored entries of column `j` of the sparse `W`: `(row indices, values)`.
    #[inline]
    pub(crate) fn sparse_col(&self, j: usize) -> (&[usize], &[Real]) {
        let (s, e) = (self.col_ptr[j], self.col_ptr[j + 1]);
        (&self.row_idx[s..e], &self.values[s..e])
    }

    /// `W_ij` (0 outside the sparsity pattern or the matrix).
    pub fn entry(&self, i: usize, j: usize) -> Real {
        if i >= self.rows || j >= self.rows {
            return 0.0;
        }
        if self.dense {
            self.w_dense[(i, j)]
        } else {
            let (rows, vals) = self.sparse_col(j);
            rows.binary_search(&i).map(|k| vals[k]).unwrap_or(0.0)
        }
    }

    /// Calls `f(i)` for every point `i` whose 2×2 block in block column `j` is stored (sparse)
    /// or non-zero (dense), in ascending order; the diagonal block always.
    pub(crate) fn for_each_block_in_column(&self, j: usize, mut f: impl FnMut(usize)) {
        if self.dense {
            let (c0, c1) = (
                self.w_dense.col_as_slice(2 * j),
                self.w_dense.col_as_slice(2 * j + 1),
            );
            for i in 0..self.points() {
                let nonzero = [c0, c1]
                    .iter()
                    .any(|c| c[2 * i] != 0.0 || c[2 * i + 1] != 0.0);
                if nonzero || i == j {
                    f(i);
                }
            }
        } else {
            // Blocks are stored whole: the even rows of column 2j name them.
            for &r in self.sparse_col(2 * j).0.iter().step_by(2) {
                f(r / 2);
            }
        }
    }

    /// The 2×2 block of `W` of points `i` (rows) and `j` (columns), row-major.
    pub(crate) fn block(&self, i: usize, j: usize) -> [Real; 4] {
        let (r, c) = (2 * i, 2 * j);
        if !self.dense && c + 1 < self.rows {
            // Blocks are stored whole and columns 2j, 2j + 1 share their row pattern: one
            // search finds all four entries.
            let (rows, even) = self.sparse_col(c);
            let (_, odd) = self.sparse_col(c + 1);
            return match rows.binary_search(&r) {
                Ok(k) => [even[k], odd[k], even[k + 1], odd[k + 1]],
                Err(_) => [0.0; 4],
            };
        }
        [
            self.entry(r, c),
            self.entry(r, c + 1),
            self.entry(r + 1, c),
            self.entry(r + 1, c + 1),
        ]
    }

    /// `W` as a dense faer matrix (for tests and small problems).
    pub fn to_dense(&self) -> Mat<Real> {
        if self.dense {
            return self.w_dense.clone();
        }
        let mut m = Mat::zeros(self.rows, self.rows);
        for j in 0..self.rows {
            let (rows, vals) = self.sparse_col(j);
            for (&i, &v) in rows.iter().zip(vals) {
                m[(i, j)] = v;
            }
        }
        m
    }

    /// `(Wx)_i`, using the symmetry of `W` (column `i` is row `i`).
    #[inline]
    pub fn row_dot(&self, i: usize, x: &[Real]) -> Real {
        if self.dense {
            let col = self.w_dense.col_as_slice(i);
            col.iter().zip(x).map(|(a, b)| a * b).sum()
        } else {
            let (rows, vals) = self.sparse_col(i);
            rows.iter().zip(vals).map(|(&r, v)| v * x[r]).sum()
        }
    }

    /// `out = W x + q` (the relative velocity of every row after applying `x`).
    /// Slices shorter than [`Self::rows`] are a programming error and are not read.
    pub fn velocity_of(&self, x: &[Real], out: &mut [Real]) {
        let n = self.rows;
        if x.len() < n || out.len() < n {
            return;
        }
        out[..n].copy_from_slice(&self.q);
        self.mul_add(x, out);
    }

    /// `out += W x`.
    pub(crate) fn mul_add(&self, x: &[Real], out: &mut [Real]) {
        let n = self.rows;
        if n == 0 {
            return;
        }
        if self.dense {
            faer::linalg::matmul::matmul(
                MatMut::from_column_major_slice_mut(&mut out[..n], n, 1),
                Accum::Add,
                self.w_dense.as_ref(),
                MatRef::from_column_major_slice(&x[..n], n, 1),
                1.0,
                Par::Seq,
            );
        } else {
            for (j, &xj) in x[..n].iter().enumerate() {
                if xj != 0.0 {
                    let (rows, vals) = self.sparse_col(j);
                    for (&r, v) in rows.iter().zip(vals) {
                        out[r] += v * xj;
                    }
                }
            }
        }
    }

    /// `out += c × (column j of W)`.
    #[inline]
    pub(crate) fn add_column(&self, j: usize, c: Real, out: &mut [Real]) {
        if self.dense {
            for (o, &v) in out.iter_mut().zip(self.w_dense.col_as_slice(j)) {
                *o += c * v;
            }
        } else {
            let (rows, vals) = self.sparse_col(j);
            for (&r, &v) in rows.iter().zip(vals) {
                if let Some(o) = out.get_mut(r) {
                    *o += c * v;
                }
            }
        }
    }

    /// Projects row `i`'s candidate value onto its bounds given the current normal impulse
    /// `normal` of its point: `[0, ∞)` for a normal row, `[−μ λn, μ λn]` for a tangent row
    /// (the bound is taken as 0 when `μ λn` is negative).
    #[inline(always)]
    pub fn project_row(&self, i: usize, value: Real, normal: Real) -> Real {
        if i % 2 == 0 {
            value.max(0.0)
        } else {
            let bound = (self.mu[i / 2] * normal).max(0.0);
            value.max(-bound).min(bound)
        }
    }

    /// Projects every point of `x` onto its friction cone (normal first, then tangent), as
    /// one PGS sweep would clamp it.
    pub fn project(&self, x: &mut [Real]) {
        for (p, pair) in x.chunks_exact_mut(2).enumerate().take(self.rows / 2) {
            pair[0] = pair[0].max(0.0);
            let bound = self.mu[p] * pair[0];
            pair[1] = pair[1].max(-bound).min(bound);
        }
    }

    /// Natural-map residual `max_i |λ_i − proj(λ_i − m_i w_i)|` with `w = Wλ + q` given,
    /// in impulse units: the same definition as deepcontact-pgs's report (the change one
    /// Jacobi sweep would make).
    pub fn natural_residual(&self, lambda: &[Real], w: &[Real]) -> Real {
        self.natural_norms(lambda, w).0
    }

    /// `(max |H|, Σ H²)` of the natural map `H = λ − proj(λ − m ∘ w)`.
    pub(crate) fn natural_norms(&self, lambda: &[Real], w: &[Real]) -> (Real, Real) {
        let (mut inf, mut sq): (Real, Real) = (0.0, 0.0);
        let pairs = lambda
            .chunks_exact(2)
            .zip(w.chunks_exact(2))
            .zip(self.m_eff.chunks_exact(2));
        for (((l, w), m), &mu) in pairs.zip(&self.mu) {
            let hn = l[0] - (l[0] - m[0] * w[0]).max(0.0);
            let bound = (mu * l[0]).max(0.0);
            let ht = l[1] - (l[1] - m[1] * w[1]).max(-bound).min(bound);
            inf = inf.max(hn.abs()).max(ht.abs());
            sq += hn * hn + ht * ht;
        }
        (inf, sq)
    }

    /// Body velocities `v = v_free + M⁻¹ Jᵀ λ`, one `(linear, angular)` per body.
    pub fn body_velocities(&self, lambda: &[Real], out: &mut [Velocity]) {
        for (o, v) in out.iter_mut().zip(&self.v_free) {
            *o = Velocity::new(Vector::new(v[0], v[1]), v[2]);
        }
        for (r, &l) in self.jac.iter().zip(lambda) {
            if l == 0.0 {
                continue;
            }
            for (body, j) in [(r.a, &r.ja), (r.b, &r.jb)] {
                let m = &self.inv_mass[body as usize];
                if let Some(o) = out.get_mut(body as usize) {
                    o.linear.x += m[0] * j[0] * l;
                    o.linear.y += m[1] * j[1] * l;
                    o.angular += m[2] * j[2] * l;
                }
            }
        }
    }
}

/// Copies impulses into the row layout (`[n0, t0, n1, t1, ...]`).
pub(crate) fn impulses_to_rows(impulses: &[Impulse], out: &mut Vec<Real>) {
    out.clear();
    for imp in impulses {
        out.push(imp.normal);
        out.push(imp.tangent);
    }
}

/// Copies the row layout back into impulses.
pub(crate) fn rows_to_impulses(x: &[Real], impulses: &mut [Impulse]) {
    for (imp, pair) in impulses.iter_mut().zip(x.chunks_exact(2)) {
        *imp = Impulse::new(pair[0], pair[1]);
    }
}

/// Row order of one Gauss-Seidel sweep, the same as deepcontact-pgs without its block
/// solver: per manifold, the tangent rows of its points, then their normal rows. Points not
/// covered by a well-formed manifold list (unvalidated input) are swept point by point.
pub(crate) fn sweep_order(problem: &ContactProblem, order: &mut Vec<u32>) {
    order.clear();
    let np = problem.points.len();
    let mut covered = 0usize;
    let well_formed = problem.manifolds.iter().all(|&(s, e)| {
        let ok = s as usize == covered && e >= s && e as usize <= np;
        covered = e as usize;
        ok
    }) && covered == np;
    if well_formed {
        for &(s, e) in &problem.manifolds {
            order.extend((s..e).map(|p| 2 * p + 1));
            order.extend((s..e).map(|p| 2 * p));
        }
    } else {
        for p in 0..np as u32 {
            order.push(2 * p + 1);
            order.push(2 * p);
        }
    }
}

/// One projected Gauss-Seidel / SOR sweep on the assembled system in `order`, updating `x`
/// in place: `x_i ← proj(x_i − ω m_i (Wx + q)_i)`. Returns `(max |Δ|, Σ Δ², all finite)`.
pub(crate) fn sor_sweep(
    del: &Delassus,
    order: &[u32],
    x: &mut [Real],
    omega: Real,
) -> (Real, Real, bool) {
    let mut max_d: Real = 0.0;
    let mut sum_sq: Real = 0.0;
    let mut finite = true;
    for &i in order {
        let i = i as usize;
        let w = del.row_dot(i, x) + del.q[i];
        finite &= w.is_finite();
        let new = del.project_row(i, x[i] - omega * del.m_eff[i] * w, x[i & !1]);
        let d = new - x[i];
        x[i] = new;
        max_d = max_d.max(d.abs());
        sum_sq += d * d;
    }
    (max_d, sum_sq, finite)
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepcontact_core::{ContactId, PointDesc, ProblemBody};

    fn body(x: Real, y: Real, inv_mass: Real, inv_inertia: Real, v: Vector) -> ProblemBody {
        ProblemBody {
            world_index: u32::MAX,
            position: Vector::new(x, y),
            angle: 0.0,
            linear_velocity: v,
            angular_velocity: 0.5,
            inv_mass,
            inv_inertia,
        }
    }

    /// A ball on the ground touching a second ball: two points sharing body 1.
    fn two_points() -> ContactProblem {
        let mut p = ContactProblem::new();
        let g = p.add_body(body(0.0, -1.0, 0.0, 0.0, Vector::zeros()));
        let a = p.add_body(body(0.0, 0.5, 1.0, 2.0, Vector::new(0.1, -1.0)));
        let b = p.add_body(body(0.6, 1.3, 0.5, 1.5, Vector::new(-0.2, -1.0)));
        let id = |f| ContactId {
            body_a: 0,
            body_b: 1,
            feature_a: f,
            feature_b: 0,
        };
        p.begin_manifold();
        p.add_point(&PointDesc {
            id: id(1),
            body_a: g,
            body_b: a,
            point: Vector::new(0.0, 0.0),
            normal: Vector::new(0.0, 1.0),
            separation: -0.01,
            friction: 0.5,
            restitution: 0.0,
            restitution_threshold: 1.0,
        })
        .unwrap();
        p.begin_manifold();
        let n = Vector::new(0.6, 0.8);
        p.add_point(&PointDesc {
            id: id(2),
            body_a: a,
            body_b: b,
            point: Vector::new(0.3, 0.9),
            normal: n,
            separation: -0.01,
            friction: 0.3,
            restitution: 0.0,
            restitution_threshold: 1.0,
        })
        .unwrap();
        p
    }

    #[test]
    #[allow(clippy::needless_range_loop)] // i and j are matrix indices
    fn w_is_j_minv_jt_and_q_the_free_relative_velocity() {
        let p = two_points();
        for mode in [AssemblyMode::Dense, AssemblyMode::Sparse] {
            let mut d = Delassus::new();
            d.assemble(&p, mode, DEFAULT_DENSE_THRESHOLD).unwrap();
            assert_eq!(d.is_dense(), mode == AssemblyMode::Dense);
            assert_eq!((d.rows(), d.points()), (4, 2));
            // Diagonal = inverse effective masses.
            for (i, pt) in [(0, &p.points[0]), (2, &p.points[1])] {
                assert!((d.diagonal()[i] * pt.normal_mass - 1.0).abs() < 1e-12);
                assert!((d.diagonal()[i + 1] * pt.tangent_mass - 1.0).abs() < 1e-12);
            }
            // Applying a unit impulse on row j changes the relative velocity of row i by W_ij.
            for j in 0..4 {
                let mut x = [0.0; 4];
                x[j] = 1.0;
                let mut v = vec![Velocity::default(); 3];
                d.body_velocities(&x, &mut v);
                let mut w = [0.0; 4];
                d.velocity_of(&x, &mut w);
                for i in 0..4 {
                    let pt = &p.points[i / 2];
                    let dir = if i % 2 == 0 { pt.normal } else { pt.tangent() };
                    let rel = |v: &[Velocity]| {
                        let (va, vb) = (v[pt.body_a as usize], v[pt.body_b as usize]);
                        let dv = vb.linear + deepcontact_core::math::cross_sv(vb.angular, &pt.r_b)
                            - va.linear
                            - deepcontact_core::math::cross_sv(va.angular, &pt.r_a);
                        dv.dot(&dir)
                    };
                    let bias = if i % 2 == 0 { pt.velocity_bias } else { 0.0 };
                    assert!(
                        (rel(&v) - bias - w[i]).abs() < 1e-12,
                        "{mode:?} row {i} col {j}"
                    );
                    assert!((d.entry(i, j) - d.entry(j, i)).abs() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn points_on_disjoint_bodies_do_not_couple() {
        let mut p = two_points();
        // Make body 1 immovable: the two points now share no movable body.
        p.bodies[1].inv_mass = 0.0;
        p.bodies[1].inv_inertia = 0.0;
        let mut d = Delassus::new();
        d.assemble(&p, AssemblyMode::Sparse, 0).unwrap();
        assert_eq!(d.entry(0, 2), 0.0);
        assert_eq!(d.entry(1, 3), 0.0);
        // Point 0 is between two immovable bodies: its block is stored, and zero.
        assert_eq!(d.entry(0, 0), 0.0);
        assert_eq!(d.nnz(), 8);
    }

    #[test]
    fn forced_dense_assembly_of_a_huge_problem_is_an_error() {
        let mut p = ContactProblem::new();
        let ground = p.add_body(body(0.0, 0.0, 0.0, 0.0, Vector::zeros()));
        let id = ContactId::default();
        for k in 0..MAX_DENSE_ROWS / 2 + 1 {
            let b = p.add_body(body(k as Real, 1.0, 1.0, 1.0, Vector::zeros()));
            p.begin_manifold();
            p.add_point(&PointDesc {
                id,
                body_a: ground,
                body_b: b,
                point: Vector::new(k as Real, 0.5),
                normal: Vector::new(0.0, 1.0),
                separation: 0.0,
                friction: 0.5,
                restitution: 0.0,
                restitution_threshold: 1.0,
            })
            .unwrap();
        }
        let mut d = Delassus::new();
        assert!(matches!(
            d.assemble(&p, AssemblyMode::Dense, 0),
            Err(LcpError::TooLargeForDense { .. })
        ));
        d.assemble(&p, AssemblyMode::Auto, DEFAULT_DENSE_THRESHOLD)
            .unwrap();
        assert!(!d.is_dense());
        assert_eq!(d.nnz(), 4 * p.points.len());
    }

    #[test]
    fn projection_and_natural_residual() {
        let p = two_points();
        let mut d = Delassus::new();
        d.assemble(&p, AssemblyMode::Dense, DEFAULT_DENSE_THRESHOLD)
            .unwrap();
        let mut x = [-1.0, 5.0, 2.0, -3.0];
        d.project(&mut x);
        assert_eq!(x, [0.0, 0.0, 2.0, -0.6]);
        // Zero impulses with approaching contacts: the residual is m |w| of the normals.
        let zero = [0.0; 4];
        let mut w = [0.0; 4];
        d.velocity_of(&zero, &mut w);
        let expect = (0..4)
            .step_by(2)
            .map(|i| (d.effective_mass()[i] * w[i]).min(0.0).abs())
            .fold(0.0, Real::max);
        assert!((d.natural_residual(&zero, &w) - expect).abs() < 1e-15);
    }

    #[test]
    fn sweep_order_is_pgs_order() {
        let mut p = two_points();
        let mut order = Vec::new();
        sweep_order(&p, &mut order);
        assert_eq!(order, [1, 0, 3, 2]);
        // One manifold with both points: tangents first, then normals.
        p.manifolds = vec![(0, 2)];
        sweep_order(&p, &mut order);
        assert_eq!(order, [1, 3, 0, 2]);
        // A malformed manifold list falls back to point order.
        p.manifolds = vec![(0, 1)];
        sweep_order(&p, &mut order);
        assert_eq!(order, [1, 0, 3, 2]);
    }
}
