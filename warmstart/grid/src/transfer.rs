//! [`Transfer`]: particles → grid (thesis Algorithm 1), grid → particles (Algorithm 2,
//! or bilinear interpolation), and the fused round trip.
//!
//! # Neighbour search
//!
//! Both directions need the pairs (particle, node) closer than `h`. The relation is
//! symmetric, so one list of pairs serves both. Two ways to find them:
//!
//! * [`NeighbourSearch::Exact`] (default): the grid is regular, so the nodes within `h`
//!   of a particle lie in the index box `ceil((x − h − origin) / spacing) ..=
//!   floor((x + h − origin) / spacing)` per axis; each node of the box is tested
//!   against `r² ≤ h²`. No tree, no allocation once the buffers have grown.
//! * [`NeighbourSearch::KdTree`]: the thesis's way, with kiddo. P2G queries an
//!   [`kiddo::ImmutableKdTree`] over the nodes (built once per grid, reused) for each
//!   particle; SPH G2P builds a tree over the particles on every call (this allocates)
//!   and queries it for each node holding a non-zero value (Algorithm 2; nodes whose
//!   values are all zero contribute nothing, so skipping them changes no result).
//!
//! Both give the same pairs up to floating-point ties at exactly `r = h` (where the
//! poly6 and spiky weights are zero anyway), so results agree to rounding.
//!
//! Measured in release (`cargo run --release -p deepcontact-grid --example
//! transfer_timing`; best on-CPU time per call over 31 batches, on a shared 2-core
//! machine under a load of ~6, so absolute figures are pessimistic), thesis grid
//! 61 × 61 at 0.25 m, `h = 0.5`, poly6, pile seed 0 of 100 circles after 200 steps
//! (163 contact points, 1956 pairs within `h`):
//!
//! | operation (2 channels, 163 contact points) | exact | k-d tree |
//! |---|---:|---:|
//! | P2G, including zeroing the 2 × 3721 grid | 14.5 µs | 25.3 µs |
//! | SPH G2P | 21.4 µs | 85.8 µs |
//! | fused round trip ([`Transfer::round_trip`]) | 25.4 µs | 35.9 µs |
//! | build the node tree (once per grid) | – | 93 µs |
//! | bilinear G2P | 2.0 µs | – |
//!
//! The exact lookup is 1.4–4× faster and never allocates, so it is the default. The
//! k-d tree's P2G queries a tree built once per grid, but its SPH G2P must rebuild a
//! tree over the particles on every call (they move) and query it for every non-zero
//! node. It stays available to reproduce the thesis literally and for checking.

//! # Buffers
//!
//! A [`Transfer`] keeps every buffer it needs (pair lists, per-node weight sums, a
//! zeroed scratch grid for the round trip) and reuses them: after the first call with
//! the largest input, the exact path performs no heap allocation.

use deepcontact_core::Vector;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use serde::{Deserialize, Serialize};

use crate::error::GridError;
use crate::kernel::{Kernel, Kind, Prepared};
use crate::spec::GridSpec;

/// `floor(v)` as an integer without a libm call (saturating for huge `v`; `v` finite).
#[inline(always)]
fn floor_i(v: f64) -> i64 {
    let t = v as i64;
    t.saturating_sub(i64::from((t as f64) > v))
}

/// `ceil(v)` as an integer without a libm call (saturating for huge `v`; `v` finite).
#[inline(always)]
fn ceil_i(v: f64) -> i64 {
    let t = v as i64;
    t.saturating_add(i64::from((t as f64) < v))
}

/// How the (particle, node) pairs within `h` are found. Default [`NeighbourSearch::Exact`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NeighbourSearch {
    /// Index range on the regular grid (default; faster, allocation-free).
    #[default]
    Exact,
    /// kiddo k-d trees (thesis Algorithms 1 and 2 literally).
    KdTree,
}

impl std::str::FromStr for NeighbourSearch {
    type Err = GridError;
    /// `exact` or `kdtree` (also `kd-tree`, `kd`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "exact" => Ok(Self::Exact),
            "kdtree" | "kd-tree" | "kd" => Ok(Self::KdTree),
            _ => Err(GridError::UnknownName {
                what: "neighbour search",
                value: s.into(),
                accepted: "exact, kdtree",
            }),
        }
    }
}

/// How grid values are brought back to particles. Default [`G2pMethod::Sph`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum G2pMethod {
    /// Thesis Algorithm 2: each node shares its value among the particles within `h`,
    /// weights normalised per node (default). Needs all particles at once.
    #[default]
    Sph,
    /// Bilinear interpolation of the four nodes around each particle (thesis 5.4.1);
    /// positions outside the grid are clamped onto its border.
    Bilinear,
}

impl std::str::FromStr for G2pMethod {
    type Err = GridError;
    /// `sph` or `bilinear`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "sph" => Ok(Self::Sph),
            "bilinear" => Ok(Self::Bilinear),
            _ => Err(GridError::UnknownName {
                what: "transfer",
                value: s.into(),
                accepted: "sph, bilinear",
            }),
        }
    }
}

/// Counts from one transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TransferStats {
    /// Particles transferred.
    pub particles: usize,
    /// Particles with no node within `h` (P2G: their value is lost; SPH G2P: they get 0).
    pub lost: usize,
    /// (particle, node) pairs with a non-zero weight.
    pub pairs: usize,
}

/// Particle ↔ grid transfer with a smoothing kernel, reusing its buffers across calls.
///
/// Values are laid out particle-major (`values[p · C + c]`, `C` channels) and grids
/// channel-major (`grid[c · N + node]`, `N` nodes; see [`GridSpec`]). Particles
/// → grid **adds** into the grid (zero it first for a fresh grid); grid → particles
/// **overwrites** its output.
///
/// ```
/// use deepcontact_core::Vector;
/// use deepcontact_grid::{GridSpec, Kernel, Transfer};
///
/// let mut t = Transfer::new(GridSpec::thesis(), Kernel::Poly6, 0.5).unwrap();
/// let positions = [Vector::new(3.1, 4.2), Vector::new(7.0, 0.3)];
/// let masses = [0.785, 2.0];
/// let mut grid = vec![0.0; t.spec().len()];
/// t.particles_to_grid(&positions, &masses, 1, &mut grid).unwrap();
/// assert!((grid.iter().sum::<f64>() - 2.785).abs() < 1e-12); // conserved
/// let mut back = [0.0; 2];
/// t.grid_to_particles(&grid, 1, &positions, &mut back).unwrap();
/// assert!((back[0] - 0.785).abs() < 1e-12 && (back[1] - 2.0).abs() < 1e-12);
/// ```
pub struct Transfer {
    spec: GridSpec,
    kernel: Kernel,
    prepared: Prepared,
    search: NeighbourSearch,
    g2p: G2pMethod,
    /// CSR pair lists by particle: pairs of particle `p` are `starts[p]..starts[p + 1]`.
    starts: Vec<u32>,
    pair_nodes: Vec<u32>,
    pair_weights: Vec<f64>,
    particle_sum: Vec<f64>,
    /// Per-node weight sums; all zero between calls.
    node_sum: Vec<f64>,
    /// Scratch grid of the round trip; all zero between calls.
    round_grid: Vec<f64>,
    node_tree: Option<ImmutableKdTree<f64, 2>>,
    particle_points: Vec<[f64; 2]>,
    node_pairs: Vec<(u32, f64)>,
}

impl std::fmt::Debug for Transfer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Transfer")
            .field("spec", &self.spec)
            .field("kernel", &self.kernel)
            .field("h", &self.prepared.h)
            .field("search", &self.search)
            .field("g2p", &self.g2p)
            .field("node_tree_built", &self.node_tree.is_some())
            .finish_non_exhaustive()
    }
}

impl Transfer {
    /// A transfer on `spec` with `kernel` of support radius `h` (exact search, SPH G2P).
    pub fn new(spec: GridSpec, kernel: Kernel, h: f64) -> Result<Self, GridError> {
        spec.validate()?;
        kernel.validate(h)?;
        Ok(Self {
            spec,
            kernel,
            prepared: kernel.prepare(h),
            search: NeighbourSearch::Exact,
            g2p: G2pMethod::Sph,
            starts: Vec::new(),
            pair_nodes: Vec::new(),
            pair_weights: Vec::new(),
            particle_sum: Vec::new(),
            node_sum: vec![0.0; spec.len()],
            round_grid: Vec::new(),
            node_tree: None,
            particle_points: Vec::new(),
            node_pairs: Vec::new(),
        })
    }

    /// Chooses the neighbour search (default [`NeighbourSearch::Exact`]).
    pub fn with_search(mut self, search: NeighbourSearch) -> Self {
        self.search = search;
        self
    }

    /// Chooses the grid → particles method (default [`G2pMethod::Sph`]).
    pub fn with_g2p(mut self, g2p: G2pMethod) -> Self {
        self.g2p = g2p;
        self
    }

    /// The grid.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// The kernel.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// The support radius.
    pub fn h(&self) -> f64 {
        self.prepared.h
    }

    /// The neighbour search in use.
    pub fn search(&self) -> NeighbourSearch {
        self.search
    }

    /// The grid → particles method in use.
    pub fn g2p(&self) -> G2pMethod {
        self.g2p
    }

    /// Moves to another grid (no-op if equal). Buffers are resized, keeping their
    /// capacity; a k-d tree over the old nodes is dropped and rebuilt on demand.
    pub fn set_spec(&mut self, spec: GridSpec) -> Result<(), GridError> {
        if spec == self.spec {
            return Ok(());
        }
        spec.validate()?;
        self.spec = spec;
        self.node_tree = None;
        self.node_sum.clear();
        self.node_sum.resize(spec.len(), 0.0);
        self.round_grid.clear();
        Ok(())
    }

    /// Builds the k-d tree over the grid nodes now (otherwise the first k-d query does).
    pub fn build_node_tree(&mut self) -> Result<(), GridError> {
        if self.node_tree.is_none() {
            let points = self.spec.positions();
            let tree = ImmutableKdTree::<f64, 2>::new_from_slice(&points)
                .map_err(|e| GridError::KdTree(format!("{e:?}")))?;
            self.node_tree = Some(tree);
        }
        Ok(())
    }

    fn check_positions(positions: &[Vector]) -> Result<(), GridError> {
        for (i, p) in positions.iter().enumerate() {
            if !p.x.is_finite() {
                return Err(GridError::NonFinite {
                    what: "particle position",
                    index: i,
                    value: p.x,
                });
            }
            if !p.y.is_finite() {
                return Err(GridError::NonFinite {
                    what: "particle position",
                    index: i,
                    value: p.y,
                });
            }
        }
        Ok(())
    }

    fn check_values(what: &'static str, values: &[f64]) -> Result<(), GridError> {
        match values.iter().position(|v| !v.is_finite()) {
            Some(i) => Err(GridError::NonFinite {
                what,
                index: i,
                value: values[i],
            }),
            None => Ok(()),
        }
    }

    fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), GridError> {
        if expected == got {
            Ok(())
        } else {
            Err(GridError::LengthMismatch {
                what,
                expected,
                got,
            })
        }
    }

    /// Fills the pair lists for `positions` (checked finite by the caller). Returns the
    /// number of particles without any node.
    fn gather(&mut self, positions: &[Vector]) -> Result<usize, GridError> {
        self.starts.clear();
        self.pair_nodes.clear();
        self.pair_weights.clear();
        self.particle_sum.clear();
        self.starts.push(0);
        let k = self.prepared;
        if self.search == NeighbourSearch::KdTree {
            self.build_node_tree()?;
            self.gather_kd(positions);
        } else {
            // One monomorphised loop per kernel, so the kernel is not dispatched per pair.
            let h2 = k.h2;
            match k.kind {
                Kind::Poly6 => self.gather_exact(positions, |r2| {
                    let d = h2 - r2;
                    d * d * d
                }),
                Kind::Spiky => self.gather_exact(positions, |r2| {
                    let d = k.h - r2.sqrt();
                    d * d * d
                }),
                Kind::Gaussian => self.gather_exact(positions, |r2| k.weight(r2)),
            }
        }
        let mut lost = 0;
        for p in 0..positions.len() {
            let (a, b) = (self.starts[p] as usize, self.starts[p + 1] as usize);
            lost += usize::from(a == b);
            self.particle_sum.push(self.pair_weights[a..b].iter().sum());
        }
        Ok(lost)
    }

    /// Exact lookup: per row of the index box, only the columns within the circle.
    /// Distances are computed in grid units (one unit = one spacing).
    #[inline(always)]
    fn gather_exact(&mut self, positions: &[Vector], weight: impl Fn(f64) -> f64) {
        let spec = self.spec;
        let (ox, oy, s) = (spec.origin[0], spec.origin[1], spec.spacing);
        let s2 = s * s;
        let inv = 1.0 / s;
        let hr = self.prepared.h * inv;
        let hr2 = hr * hr;
        let (last_x, last_y) = (spec.nx as i64 - 1, spec.ny as i64 - 1);
        // At most this many nodes per particle: the lists are grown to make room before
        // each particle and written by index (cheaper than a push per pair), then
        // truncated to what was written.
        let per = {
            let side = 2.0 * hr.ceil() + 1.0;
            (side * side).min((spec.len()) as f64) as usize
        };
        let (nodes, weights) = (&mut self.pair_nodes, &mut self.pair_weights);
        let mut k = nodes.len();
        for x in positions {
            if nodes.len() < k + per {
                nodes.resize(k + per, 0);
                weights.resize(k + per, 0.0);
            }
            let (tx, ty) = ((x.x - ox) * inv, (x.y - oy) * inv);
            let iy0 = ceil_i(ty - hr).max(0);
            let iy1 = floor_i(ty + hr).min(last_y);
            for iy in iy0..=iy1 {
                let dy = iy as f64 - ty;
                let dy2 = dy * dy;
                let rem = hr2 - dy2;
                if rem < 0.0 {
                    continue;
                }
                let half = rem.sqrt();
                let ix0 = ceil_i(tx - half).max(0);
                let ix1 = floor_i(tx + half).min(last_x);
                let row = iy as usize * spec.nx;
                for ix in ix0..=ix1 {
                    let dx = ix as f64 - tx;
                    let r2 = dx * dx + dy2;
                    if r2 <= hr2 {
                        let w = weight(r2 * s2);
                        if w > 0.0 {
                            nodes[k] = (row + ix as usize) as u32;
                            weights[k] = w;
                            k += 1;
                        }
                    }
                }
            }
            self.starts.push(k as u32);
        }
        nodes.truncate(k);
        weights.truncate(k);
    }

    /// k-d tree over the nodes (built by the caller), queried per particle.
    fn gather_kd(&mut self, positions: &[Vector]) {
        let k = self.prepared;
        let Some(tree) = &self.node_tree else {
            // Not reached (the caller builds the tree); keep the lists consistent anyway.
            self.starts.resize(positions.len() + 1, 0);
            return;
        };
        let (nodes, weights) = (&mut self.pair_nodes, &mut self.pair_weights);
        for x in positions {
            tree.query(&[x.x, x.y])
                .within::<SquaredEuclidean<f64>>(k.h2)
                .unsorted()
                .visit(|r| {
                    let w = k.weight(r.distance);
                    if w > 0.0 {
                        nodes.push(r.item);
                        weights.push(w);
                    }
                });
            self.starts.push(nodes.len() as u32);
        }
    }

    /// P2G of the gathered pairs into `grid` (adds).
    fn scatter(&self, values: &[f64], channels: usize, grid: &mut [f64]) {
        let n = self.spec.len();
        for p in 0..self.particle_sum.len() {
            let sum = self.particle_sum[p];
            if sum <= 0.0 {
                continue;
            }
            let inv = 1.0 / sum;
            let v = &values[p * channels..(p + 1) * channels];
            let (a, b) = (self.starts[p] as usize, self.starts[p + 1] as usize);
            for (&node, &w) in self.pair_nodes[a..b].iter().zip(&self.pair_weights[a..b]) {
                let f = w * inv;
                let node = node as usize;
                for (c, &vc) in v.iter().enumerate() {
                    grid[c * n + node] += f * vc;
                }
            }
        }
    }

    /// SPH G2P from the gathered pairs into `out` (overwrites). Errors on a non-finite
    /// grid value that reaches a particle.
    fn gather_back(
        &mut self,
        grid: &[f64],
        channels: usize,
        out: &mut [f64],
    ) -> Result<(), GridError> {
        let n = self.spec.len();
        out.fill(0.0);
        for (&node, &w) in self.pair_nodes.iter().zip(&self.pair_weights) {
            self.node_sum[node as usize] += w;
        }
        let mut bad = None;
        for p in 0..self.particle_sum.len() {
            let (a, b) = (self.starts[p] as usize, self.starts[p + 1] as usize);
            let o = &mut out[p * channels..(p + 1) * channels];
            for (&node, &w) in self.pair_nodes[a..b].iter().zip(&self.pair_weights[a..b]) {
                let node = node as usize;
                let f = w / self.node_sum[node];
                for (c, oc) in o.iter_mut().enumerate() {
                    let g = grid[c * n + node];
                    if !g.is_finite() && bad.is_none() {
                        bad = Some((c * n + node, g));
                    }
                    *oc += f * g;
                }
            }
        }
        for &node in &self.pair_nodes {
            self.node_sum[node as usize] = 0.0;
        }
        match bad {
            Some((index, value)) => Err(GridError::NonFinite {
                what: "grid value",
                index,
                value,
            }),
            None => Ok(()),
        }
    }

    /// Particles → grid (thesis Algorithm 1): each particle's `channels` values are
    /// spread over the nodes within `h` with kernel weights normalised to sum to one,
    /// and **added** to `grid` (`channels × N`, channel-major). A particle with no node
    /// within `h` is lost (counted in [`TransferStats::lost`]).
    pub fn particles_to_grid(
        &mut self,
        positions: &[Vector],
        values: &[f64],
        channels: usize,
        grid: &mut [f64],
    ) -> Result<TransferStats, GridError> {
        Self::check_len("particle values", positions.len() * channels, values.len())?;
        Self::check_len("grid", channels * self.spec.len(), grid.len())?;
        Self::check_positions(positions)?;
        Self::check_values("particle value", values)?;
        let lost = self.gather(positions)?;
        self.scatter(values, channels, grid);
        Ok(TransferStats {
            particles: positions.len(),
            lost,
            pairs: self.pair_nodes.len(),
        })
    }

    /// Grid → particles with the configured method ([`Transfer::with_g2p`]); `out`
    /// (`positions.len() × channels`, particle-major) is **overwritten**.
    ///
    /// SPH (thesis Algorithm 2): each node shares its values among the particles within
    /// `h`, weights normalised per node, so the particles receive exactly the total of
    /// the nodes that have a particle within `h` — never more than the grid holds.
    /// Bilinear: interpolation of the four surrounding nodes.
    pub fn grid_to_particles(
        &mut self,
        grid: &[f64],
        channels: usize,
        positions: &[Vector],
        out: &mut [f64],
    ) -> Result<TransferStats, GridError> {
        Self::check_len("grid", channels * self.spec.len(), grid.len())?;
        Self::check_len("particle output", positions.len() * channels, out.len())?;
        Self::check_positions(positions)?;
        match (self.g2p, self.search) {
            (G2pMethod::Bilinear, _) => self.bilinear(grid, channels, positions, out),
            (G2pMethod::Sph, NeighbourSearch::Exact) => {
                let lost = self.gather(positions)?;
                self.gather_back(grid, channels, out)?;
                Ok(TransferStats {
                    particles: positions.len(),
                    lost,
                    pairs: self.pair_nodes.len(),
                })
            }
            (G2pMethod::Sph, NeighbourSearch::KdTree) => {
                self.g2p_particle_tree(grid, channels, positions, out)
            }
        }
    }

    /// Thesis Algorithm 2 literally: a k-d tree over the particles, queried per node.
    fn g2p_particle_tree(
        &mut self,
        grid: &[f64],
        channels: usize,
        positions: &[Vector],
        out: &mut [f64],
    ) -> Result<TransferStats, GridError> {
        out.fill(0.0);
        if positions.is_empty() {
            return Ok(TransferStats::default());
        }
        let n = self.spec.len();
        let k = self.prepared;
        self.particle_points.clear();
        self.particle_points
            .extend(positions.iter().map(|p| [p.x, p.y]));
        let tree = ImmutableKdTree::<f64, 2>::new_from_slice(&self.particle_points)
            .map_err(|e| GridError::KdTree(format!("{e:?}")))?;
        // Particles reached by at least one node, for the stats.
        let mut pairs = 0;
        self.particle_sum.clear();
        self.particle_sum.resize(positions.len(), 0.0);
        for node in 0..n {
            if (0..channels).all(|c| grid[c * n + node] == 0.0) {
                continue;
            }
            for c in 0..channels {
                let g = grid[c * n + node];
                if !g.is_finite() {
                    return Err(GridError::NonFinite {
                        what: "grid value",
                        index: c * n + node,
                        value: g,
                    });
                }
            }
            let q = self.spec.node_at(node);
            self.node_pairs.clear();
            let np = &mut self.node_pairs;
            tree.query(&[q.x, q.y])
                .within::<SquaredEuclidean<f64>>(k.h2)
                .unsorted()
                .visit(|r| {
                    let w = k.weight(r.distance);
                    if w > 0.0 {
                        np.push((r.item, w));
                    }
                });
            let sum: f64 = self.node_pairs.iter().map(|&(_, w)| w).sum();
            if sum <= 0.0 {
                continue;
            }
            pairs += self.node_pairs.len();
            for &(p, w) in &self.node_pairs {
                let p = p as usize;
                let f = w / sum;
                self.particle_sum[p] += w;
                for c in 0..channels {
                    out[p * channels + c] += f * grid[c * n + node];
                }
            }
        }
        let lost = self.particle_sum.iter().filter(|&&s| s == 0.0).count();
        Ok(TransferStats {
            particles: positions.len(),
            lost,
            pairs,
        })
    }

    fn bilinear(
        &self,
        grid: &[f64],
        channels: usize,
        positions: &[Vector],
        out: &mut [f64],
    ) -> Result<TransferStats, GridError> {
        let spec = &self.spec;
        let n = spec.len();
        let inv = 1.0 / spec.spacing;
        let axis = |x: f64, o: f64, count: usize| -> (usize, usize, f64) {
            let f = ((x - o) * inv).clamp(0.0, (count - 1) as f64);
            let i0 = (f.floor() as usize).min(count.saturating_sub(2));
            let i1 = (i0 + 1).min(count - 1);
            (i0, i1, f - i0 as f64)
        };
        for (p, x) in positions.iter().enumerate() {
            let (i0, i1, tx) = axis(x.x, spec.origin[0], spec.nx);
            let (j0, j1, ty) = axis(x.y, spec.origin[1], spec.ny);
            let corners = [
                (spec.index(i0, j0), (1.0 - tx) * (1.0 - ty)),
                (spec.index(i1, j0), tx * (1.0 - ty)),
                (spec.index(i0, j1), (1.0 - tx) * ty),
                (spec.index(i1, j1), tx * ty),
            ];
            for c in 0..channels {
                let mut v = 0.0;
                for &(node, w) in &corners {
                    let g = grid[c * n + node];
                    if !g.is_finite() {
                        return Err(GridError::NonFinite {
                            what: "grid value",
                            index: c * n + node,
                            value: g,
                        });
                    }
                    v += w * g;
                }
                out[p * channels + c] = v;
            }
        }
        Ok(TransferStats {
            particles: positions.len(),
            lost: 0,
            pairs: 4 * positions.len(),
        })
    }

    /// Particles → grid → the same particles, in one pass over one list of pairs: what
    /// the thesis's Table 1 measures and what the `grid` warm start does. `out`
    /// (`positions.len() × channels`) is overwritten. The intermediate grid is internal
    /// (kept zeroed, only the touched nodes are cleared) and thus costs nothing outside
    /// the particles' neighbourhoods. With [`G2pMethod::Bilinear`] the grid is read back
    /// by interpolation instead.
    pub fn round_trip(
        &mut self,
        positions: &[Vector],
        values: &[f64],
        channels: usize,
        out: &mut [f64],
    ) -> Result<TransferStats, GridError> {
        Self::check_len("particle values", positions.len() * channels, values.len())?;
        Self::check_len("particle output", positions.len() * channels, out.len())?;
        Self::check_positions(positions)?;
        Self::check_values("particle value", values)?;
        let size = channels * self.spec.len();
        if self.round_grid.len() != size {
            self.round_grid.clear();
            self.round_grid.resize(size, 0.0);
        }
        let lost = self.gather(positions)?;
        let mut grid = std::mem::take(&mut self.round_grid);
        self.scatter(values, channels, &mut grid);
        let back = match self.g2p {
            G2pMethod::Sph => self.gather_back(&grid, channels, out).map(|_| ()),
            G2pMethod::Bilinear => self.bilinear(&grid, channels, positions, out).map(|_| ()),
        };
        // Clear what the scatter touched, so the scratch grid is zero again.
        let n = self.spec.len();
        for &node in &self.pair_nodes {
            for c in 0..channels {
                grid[c * n + node as usize] = 0.0;
            }
        }
        self.round_grid = grid;
        back?;
        Ok(TransferStats {
            particles: positions.len(),
            lost,
            pairs: self.pair_nodes.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn transfer(search: NeighbourSearch) -> Transfer {
        Transfer::new(GridSpec::thesis(), Kernel::Poly6, 0.5)
            .unwrap()
            .with_search(search)
    }

    fn points() -> Vec<Vector> {
        (0..40)
            .map(|i| Vector::new(0.37 * i as f64 % 15.0, (1.3 + 0.71 * i as f64) % 15.0))
            .collect()
    }

    #[test]
    fn integer_floor_and_ceil() {
        for v in [-2.5, -2.0, -0.5, -0.0, 0.0, 0.3, 1.0, 1.7, 1e300, -1e300] {
            assert_eq!(
                floor_i(v),
                v.floor().clamp(i64::MIN as f64, i64::MAX as f64) as i64,
                "{v}"
            );
            assert_eq!(
                ceil_i(v),
                v.ceil().clamp(i64::MIN as f64, i64::MAX as f64) as i64,
                "{v}"
            );
        }
    }

    #[test]
    fn kdtree_and_exact_agree() {
        let pos = points();
        let vals: Vec<f64> = (0..pos.len() * 2)
            .map(|i| (i as f64 * 0.37).sin())
            .collect();
        let n = GridSpec::thesis().len();
        let (mut ge, mut gk) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
        let (mut e, mut k) = (
            transfer(NeighbourSearch::Exact),
            transfer(NeighbourSearch::KdTree),
        );
        let se = e.particles_to_grid(&pos, &vals, 2, &mut ge).unwrap();
        let sk = k.particles_to_grid(&pos, &vals, 2, &mut gk).unwrap();
        assert_eq!(se, sk);
        for (a, b) in ge.iter().zip(&gk) {
            assert!((a - b).abs() < 1e-12);
        }
        let (mut oe, mut ok) = (vec![0.0; pos.len() * 2], vec![0.0; pos.len() * 2]);
        e.grid_to_particles(&ge, 2, &pos, &mut oe).unwrap();
        k.grid_to_particles(&ge, 2, &pos, &mut ok).unwrap();
        for (a, b) in oe.iter().zip(&ok) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        let mut rt = vec![0.0; pos.len() * 2];
        e.round_trip(&pos, &vals, 2, &mut rt).unwrap();
        for (a, b) in oe.iter().zip(&rt) {
            assert!((a - b).abs() < 1e-12);
        }
        // The scratch grid was cleared: a second round trip gives the same.
        let mut rt2 = vec![0.0; pos.len() * 2];
        e.round_trip(&pos, &vals, 2, &mut rt2).unwrap();
        assert_eq!(rt, rt2);
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut t = transfer(NeighbourSearch::Exact);
        let n = t.spec().len();
        let mut grid = vec![0.0; n];
        let pos = [Vector::new(1.0, 1.0)];
        assert!(matches!(
            t.particles_to_grid(&pos, &[1.0, 2.0], 1, &mut grid),
            Err(GridError::LengthMismatch { .. })
        ));
        assert!(matches!(
            t.particles_to_grid(&pos, &[1.0], 1, &mut grid[1..]),
            Err(GridError::LengthMismatch { .. })
        ));
        assert!(matches!(
            t.particles_to_grid(&[Vector::new(f64::NAN, 1.0)], &[1.0], 1, &mut grid),
            Err(GridError::NonFinite {
                what: "particle position",
                ..
            })
        ));
        assert!(matches!(
            t.particles_to_grid(&pos, &[f64::INFINITY], 1, &mut grid),
            Err(GridError::NonFinite {
                what: "particle value",
                ..
            })
        ));
        grid[t.spec().index(4, 4)] = f64::NAN;
        let mut out = [0.0];
        assert!(matches!(
            t.grid_to_particles(&grid, 1, &pos, &mut out),
            Err(GridError::NonFinite { .. })
        ));
        let mut b = transfer(NeighbourSearch::Exact).with_g2p(G2pMethod::Bilinear);
        assert!(
            b.grid_to_particles(&grid, 1, &[Vector::new(1.1, 1.1)], &mut out)
                .is_err()
        );
        assert!(
            b.grid_to_particles(&grid, 1, &[Vector::new(5.1, 1.1)], &mut out)
                .is_ok()
        );
        let mut k = transfer(NeighbourSearch::KdTree);
        assert!(k.grid_to_particles(&grid, 1, &pos, &mut out).is_err());
    }

    #[test]
    fn far_away_particles_are_lost_not_panics() {
        let mut t = transfer(NeighbourSearch::Exact);
        let mut grid = vec![0.0; t.spec().len()];
        let pos = [Vector::new(-1e300, 1e300), Vector::new(1.0, 1.0)];
        let s = t
            .particles_to_grid(&pos, &[1.0, 1.0], 1, &mut grid)
            .unwrap();
        assert_eq!(s.lost, 1);
        assert!((grid.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let mut out = [0.0; 2];
        let s = t.grid_to_particles(&grid, 1, &pos, &mut out).unwrap();
        assert_eq!((s.lost, out[0]), (1, 0.0));
        // Empty input is fine too.
        assert_eq!(
            t.particles_to_grid(&[], &[], 1, &mut grid)
                .unwrap()
                .particles,
            0
        );
        let mut k = transfer(NeighbourSearch::KdTree);
        assert_eq!(
            k.grid_to_particles(&grid, 1, &[], &mut [])
                .unwrap()
                .particles,
            0
        );
    }

    #[test]
    fn set_spec_resizes() {
        let mut t = transfer(NeighbourSearch::KdTree);
        let small = GridSpec::new([0.0, 0.0], 0.5, 5, 4).unwrap();
        t.set_spec(small).unwrap();
        let mut grid = vec![0.0; small.len()];
        t.particles_to_grid(&[Vector::new(1.0, 1.0)], &[3.0], 1, &mut grid)
            .unwrap();
        assert!((grid.iter().sum::<f64>() - 3.0).abs() < 1e-12);
        assert!(
            t.set_spec(GridSpec {
                spacing: -1.0,
                ..small
            })
            .is_err()
        );
        assert_eq!(t.spec(), &small);
    }
}
