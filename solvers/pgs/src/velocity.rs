//! The sequential-impulse velocity solver.
//!
//! Data layout: a manifold touches one body pair, so the solver loop loads the two body
//! velocities once per manifold, runs all of its rows on local copies, and stores them
//! once. Rows hold the cross products precomputed (`rn = r × n`, `rt = r × t`).

use std::time::Instant;

use deepcontact_core::math::{Real, Vector, Velocity, cross};
use deepcontact_core::{
    ContactProblem, CoreError, Impulse, IslandSolve, ResidualNorm, SolveReport, SolverSettings,
    VelocitySolver,
};

use crate::PgsError;

#[cfg(target_arch = "x86_64")]
mod avx2;

/// Options of the PGS solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PgsSettings {
    /// Solve the two normal rows of a 2-point manifold together, as Box2D's block solver
    /// (default true; only polygon manifolds have two points).
    pub block_solver: bool,
    /// Validate the problem before solving (default true; costs one pass over the data).
    pub validate: bool,
    /// Order of the manifolds within a sweep (default [`Ordering::Coloured`]).
    pub ordering: Ordering,
    /// With [`Ordering::Coloured`], solve the single-point manifolds of a colour
    /// [`LANES`] at a time in structure-of-arrays batches (default true). The results are
    /// bit-identical to the one-at-a-time loop (the manifolds of a colour are independent and
    /// each lane does the scalar arithmetic); only `Σ Δλ²` is summed in another order.
    pub lanes: bool,
    /// Apply the warm start's tangent impulses as given, even outside the friction cone
    /// `|λt| ≤ μ λn`, as the original thesis code does (default false: projected onto the
    /// cone). Negative normal impulses are raised to 0 either way.
    pub raw_start: bool,
    /// Threads that share the sweep of one island in the chunked plan (default 1; 0 counts
    /// as 1; no more than the cores the process may use are started). The result is
    /// bit-identical for every thread count.
    pub threads: usize,
    /// Islands with at least this many contact points are swept in the domain plan or the
    /// chunked plan ([`domains`](Self::domains)) of [`threads`](Self::threads) (default
    /// 2048), with bodies renumbered in Z-order. Needs [`Ordering::Coloured`] and
    /// [`lanes`](Self::lanes). In the chunked plan each colour's batches are cut into fixed
    /// chunks whose impulse-change measures are combined in chunk order, whatever the thread
    /// count; the ∞ and contact norms, the impulses and the velocities are bit-identical to
    /// the unchunked sweep, only `Σ Δλ²` (the L2 norm) is summed in another order.
    pub parallel_min_points: usize,
    /// Domains of the domain plan for islands of [`parallel_min_points`](Self::parallel_min_points)
    /// points or more (default 16; 0: the chunked plan instead; more than 63 count as 63, and
    /// the registry refuses them). The island's movable bodies are layered by a breadth-first
    /// walk of their contacts and cut into this many bands of layers holding about as many
    /// manifolds each, each band's manifolds swept as an island of its own; a manifold's
    /// bodies lie in one band or in two neighbouring ones, so an iteration sweeps the even
    /// bands side by side on threads, then the odd ones, and threads take the bands of a phase
    /// from a queue (a slower thread takes fewer). Up to half the domains, rounded up, work on
    /// an island. Another Gauss-Seidel order than the unchunked sweep's, so other (equally
    /// valid) bits; the same bits for any thread count. The chunked plan (`0`) keeps the
    /// unchunked sweep's bits but shares every colour between threads through atomics, which
    /// scales worse.
    pub domains: usize,
}

impl Default for PgsSettings {
    fn default() -> Self {
        Self {
            block_solver: true,
            validate: true,
            ordering: Ordering::Coloured,
            lanes: true,
            raw_start: false,
            threads: 1,
            parallel_min_points: 2048,
            domains: 16,
        }
    }
}

/// Order in which a sweep visits the manifolds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Ordering {
    /// The problem's order (pairs sorted by body index), as Box2D v2.4. Consecutive
    /// manifolds usually share a body, so each waits for the previous one's velocity
    /// update: the loop is bound by that dependency chain's latency.
    Sequential,
    /// Greedy graph colouring: manifolds are grouped so that no two of a colour share a
    /// dynamic body, and visited colour by colour (Box2D v3, Rapier). Still Gauss-Seidel —
    /// every row sees the latest velocities — but neighbouring manifolds of a colour are
    /// independent, so the CPU overlaps them. Deterministic (the colouring depends only
    /// on the problem).
    #[default]
    Coloured,
}

/// One contact point laid out for the solver loop.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Row {
    nx: Real,
    ny: Real,
    rna: Real,
    rnb: Real,
    rta: Real,
    rtb: Real,
    normal_mass: Real,
    tangent_mass: Real,
    friction: Real,
    bias: Real,
    ln: Real,
    lt: Real,
}

impl Row {
    /// Point `p`'s row, starting from `s` projected onto the cone λn ≥ 0, |λt| ≤ μ λn (with
    /// `raw`, the tangent as given); a NaN start passes through to the non-finite check of
    /// the first sweep (a negative bound would make the friction clamp panic).
    fn of(p: &deepcontact_core::ContactPoint, s: &Impulse, raw: bool) -> Self {
        let t = p.tangent();
        let start_normal = if s.normal < 0.0 { 0.0 } else { s.normal };
        let bound = p.friction * start_normal;
        let start_tangent = if raw {
            s.tangent
        } else if s.tangent > bound {
            bound
        } else if s.tangent < -bound {
            -bound
        } else {
            s.tangent
        };
        Row {
            nx: p.normal.x,
            ny: p.normal.y,
            rna: cross(&p.r_a, &p.normal),
            rnb: cross(&p.r_b, &p.normal),
            rta: cross(&p.r_a, &t),
            rtb: cross(&p.r_b, &t),
            normal_mass: p.normal_mass,
            tangent_mass: p.tangent_mass,
            friction: p.friction,
            bias: p.velocity_bias,
            ln: start_normal,
            lt: start_tangent,
        }
    }
}

/// One manifold: its body pair with their inverse masses, its rows, and block-solver data.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Manifold {
    pub(crate) a: u32,
    pub(crate) b: u32,
    pub(crate) start: u32,
    pub(crate) count: u32,
    pub(crate) ma: Real,
    pub(crate) ia: Real,
    pub(crate) mb: Real,
    pub(crate) ib: Real,
    pub(crate) block: Option<Block>,
}

/// Block-solver data of a 2-point manifold: `K` and its inverse.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Block {
    k11: Real,
    k12: Real,
    k22: Real,
    i11: Real,
    i12: Real,
    i22: Real,
}

/// Manifolds solved side by side in one batch.
pub const LANES: usize = 4;

/// [`LANES`] single-point manifolds of one colour in structure-of-arrays form: each field
/// holds one value per lane. Padding lanes point at a dummy immovable body with zero masses,
/// so their impulse changes are exactly zero.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Batch {
    a: [u32; LANES],
    b: [u32; LANES],
    /// Where each lane's new velocity of `a` (of `b`) is stored: the body itself when it is
    /// movable, else a sink slot that nothing reads (so the scatter needs no branch; an
    /// immovable body is never written, and padding lanes write the sink too).
    wa: [u32; LANES],
    wb: [u32; LANES],
    /// Row of each lane in `rows` (`u32::MAX` for padding).
    row: [u32; LANES],
    nx: [Real; LANES],
    ny: [Real; LANES],
    rna: [Real; LANES],
    rnb: [Real; LANES],
    rta: [Real; LANES],
    rtb: [Real; LANES],
    normal_mass: [Real; LANES],
    tangent_mass: [Real; LANES],
    friction: [Real; LANES],
    bias: [Real; LANES],
    ma: [Real; LANES],
    ia: [Real; LANES],
    mb: [Real; LANES],
    ib: [Real; LANES],
    ln: [Real; LANES],
    lt: [Real; LANES],
}

impl Batch {
    /// A batch of padding lanes only: reading the `dummy` body, writing the `sink`.
    pub(crate) fn empty(dummy: u32, sink: u32) -> Self {
        Batch {
            a: [dummy; LANES],
            b: [dummy; LANES],
            wa: [sink; LANES],
            wb: [sink; LANES],
            row: [u32::MAX; LANES],
            ..Batch::default()
        }
    }

    /// Lane `to` becomes lane `from` of `src`, its bodies and write targets moved by
    /// `offset` slots (the source island's velocities placed `offset` slots in).
    pub(crate) fn set_lane(&mut self, to: usize, src: &Batch, from: usize, offset: u32) {
        self.a[to] = src.a[from] + offset;
        self.b[to] = src.b[from] + offset;
        self.wa[to] = src.wa[from] + offset;
        self.wb[to] = src.wb[from] + offset;
        self.row[to] = src.row[from];
        for (dst, src) in [
            (&mut self.nx, &src.nx),
            (&mut self.ny, &src.ny),
            (&mut self.rna, &src.rna),
            (&mut self.rnb, &src.rnb),
            (&mut self.rta, &src.rta),
            (&mut self.rtb, &src.rtb),
            (&mut self.normal_mass, &src.normal_mass),
            (&mut self.tangent_mass, &src.tangent_mass),
            (&mut self.friction, &src.friction),
            (&mut self.bias, &src.bias),
            (&mut self.ma, &src.ma),
            (&mut self.ia, &src.ia),
            (&mut self.mb, &src.mb),
            (&mut self.ib, &src.ib),
            (&mut self.ln, &src.ln),
            (&mut self.lt, &src.lt),
        ] {
            dst[to] = src[from];
        }
    }

    /// How many lanes hold a manifold (they come first; the rest are padding).
    pub(crate) fn width(&self) -> usize {
        self.row.iter().take_while(|&&r| r != u32::MAX).count()
    }

    /// The impulses of lane `from` of `src` into lane `to` (all a sweep changes in a batch).
    pub(crate) fn set_impulses(&mut self, to: usize, src: &Batch, from: usize) {
        self.ln[to] = src.ln[from];
        self.lt[to] = src.lt[from];
    }
}

/// One colour of the sweep: its batches, then its other manifolds one at a time.
#[derive(Debug, Clone, Default)]
pub(crate) struct Segment {
    pub(crate) batches: std::ops::Range<usize>,
    pub(crate) manifolds: std::ops::Range<usize>,
}

/// Velocity `(vx, vy, ω)` of one body.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Vel {
    pub(crate) vx: Real,
    pub(crate) vy: Real,
    pub(crate) w: Real,
}

/// Projected Gauss-Seidel on sequential impulses (Box2D v2.4's `b2ContactSolver`).
#[derive(Debug, Clone, Default)]
pub struct PgsSolver {
    /// Options.
    pub settings: PgsSettings,
    pub(crate) rows: Vec<Row>,
    pub(crate) manifolds: Vec<Manifold>,
    pub(crate) vel: Vec<Vel>,
    /// Colour bit masks used per body while colouring.
    body_colours: Vec<u64>,
    /// Colour of each manifold, and the scratch copy used to reorder.
    colours: Vec<u8>,
    pub(crate) scratch: Vec<Manifold>,
    /// Batches of single-point manifolds and the sweep plan (empty: one at a time).
    pub(crate) batches: Vec<Batch>,
    pub(crate) segments: Vec<Segment>,
    /// For the chunked plan, the bodies of `vel` renumbered in Z-order of their positions (so
    /// that neighbours share cache lines); inactive: the problem's order.
    bodies: crate::z_order::Renumbering,
    /// The instruction set the sweep loops run in, detected once when the solver is made:
    /// AVX2 + FMA (x86-64-v3) where the CPU has them, else the baseline. Same bits either way.
    pub(crate) arch: pulp::Arch,
    /// The domain plan's domains ([`PgsSettings::domains`]; empty otherwise).
    domains: crate::velocity_domains::Domains,
    /// The solvers of the small islands solved together ([`crate::velocity_lanes`]), one per
    /// island of a step, kept for the next.
    pub(crate) lane_solvers: Vec<PgsSolver>,
    /// The small islands of a step (their indices), and how each is swept.
    pub(crate) small_islands: Vec<usize>,
    pub(crate) small_kinds: Vec<crate::velocity_lanes::Kind>,
}

impl PgsSolver {
    /// A solver with default options.
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options.
    pub fn with_settings(settings: PgsSettings) -> Self {
        Self {
            settings,
            ..Self::default()
        }
    }

    /// Stage 1, prepare: copy the problem into rows, manifolds and packed velocities.
    fn prepare(&mut self, problem: &ContactProblem, start: &[Impulse]) {
        self.reset_plan();
        // The chunked plan's grid (none for the plain sweep: not a pass over the points more).
        let z = self
            .plans_chunked(problem.points.len())
            .then(|| crate::z_order::ZOrder::of(&problem.points));
        match &z {
            Some(z) => self.bodies.build(z, &problem.bodies),
            None => self.bodies.clear(),
        }
        let vel = |b: &deepcontact_core::ProblemBody| Vel {
            vx: b.linear_velocity.x,
            vy: b.linear_velocity.y,
            w: b.angular_velocity,
        };
        self.vel.clear();
        if self.bodies.is_active() {
            let bodies = &problem.bodies;
            self.vel.extend(
                self.bodies
                    .body_of
                    .iter()
                    .map(|&b| vel(&bodies[b as usize])),
            );
        } else {
            self.vel.extend(problem.bodies.iter().map(vel));
        }
        self.rows.clear();
        let raw = self.settings.raw_start;
        self.rows.extend(
            problem
                .points
                .iter()
                .zip(start)
                .map(|(p, s)| Row::of(p, s, raw)),
        );
        self.manifolds.clear();
        for &(s, e) in &problem.manifolds {
            if e == s {
                continue;
            }
            let p = &problem.points[s as usize];
            let (ba, bb) = (
                &problem.bodies[p.body_a as usize],
                &problem.bodies[p.body_b as usize],
            );
            let mut m = Manifold {
                a: p.body_a,
                b: p.body_b,
                start: s,
                count: e - s,
                ma: ba.inv_mass,
                ia: ba.inv_inertia,
                mb: bb.inv_mass,
                ib: bb.inv_inertia,
                block: None,
            };
            if self.settings.block_solver && m.count == 2 {
                let (r1, r2) = (&self.rows[s as usize], &self.rows[s as usize + 1]);
                let k11 = m.ma + m.mb + m.ia * r1.rna * r1.rna + m.ib * r1.rnb * r1.rnb;
                let k22 = m.ma + m.mb + m.ia * r2.rna * r2.rna + m.ib * r2.rnb * r2.rnb;
                let k12 = m.ma + m.mb + m.ia * r1.rna * r2.rna + m.ib * r1.rnb * r2.rnb;
                let det = k11 * k22 - k12 * k12;
                // Box2D's condition-number guard: k11² < 1000 det.
                if det > 0.0 && k11 * k11 < 1000.0 * det {
                    let inv = 1.0 / det;
                    m.block = Some(Block {
                        k11,
                        k12,
                        k22,
                        i11: k22 * inv,
                        i22: k11 * inv,
                        i12: -k12 * inv,
                    });
                }
            }
            self.manifolds.push(m);
        }
        if self.bodies.is_active() {
            let new = &self.bodies.new_index;
            for m in &mut self.manifolds {
                (m.a, m.b) = (new[m.a as usize], new[m.b as usize]);
            }
        }
        // The domain plan colours each of its parts instead (after the warm start).
        if self.settings.ordering == Ordering::Coloured && !self.plans_domains(problem.points.len())
        {
            self.colour(problem.bodies.len(), z.as_ref().map(|z| (z, problem)));
        }
    }

    /// Whether an island of `points` contact points is swept in the chunked plan of
    /// [`crate::velocity_chunked`] (coloured, laned, and large enough).
    pub(crate) fn plans_chunked(&self, points: usize) -> bool {
        self.settings.ordering == Ordering::Coloured
            && self.settings.lanes
            && points >= self.settings.parallel_min_points
    }

    /// Whether an island of `points` contact points is swept in the domain plan of
    /// [`crate::velocity_domains`].
    fn plans_domains(&self, points: usize) -> bool {
        self.plans_chunked(points) && self.settings.domains > 0
    }

    /// Forgets the sweep plan (batches and colours), before a new one is built.
    pub(crate) fn reset_plan(&mut self) {
        self.batches.clear();
        self.segments.clear();
    }

    /// Greedy colouring in problem order: each manifold takes the lowest colour that
    /// neither of its movable bodies has yet (64 colours; the rare manifold that finds
    /// none goes to a last, sequential colour). Immovable bodies never conflict: the
    /// loop does not write them. Manifolds are then stably sorted by colour.
    /// With `space` (the chunked plan's grid and the problem), each colour is then ordered in
    /// Z-order.
    pub(crate) fn colour(
        &mut self,
        bodies: usize,
        space: Option<(&crate::z_order::ZOrder, &ContactProblem)>,
    ) {
        const OVERFLOW: u8 = 64;
        self.body_colours.clear();
        self.body_colours.resize(bodies, 0);
        self.colours.clear();
        let mut counts = [0u32; 65];
        for m in &self.manifolds {
            let used_a = if movable(m.ma, m.ia) {
                self.body_colours[m.a as usize]
            } else {
                0
            };
            let used_b = if movable(m.mb, m.ib) {
                self.body_colours[m.b as usize]
            } else {
                0
            };
            let free = !(used_a | used_b);
            let c = if free == 0 {
                OVERFLOW
            } else {
                free.trailing_zeros() as u8
            };
            if c != OVERFLOW {
                if movable(m.ma, m.ia) {
                    self.body_colours[m.a as usize] |= 1 << c;
                }
                if movable(m.mb, m.ib) {
                    self.body_colours[m.b as usize] |= 1 << c;
                }
            }
            counts[c as usize] += 1;
            self.colours.push(c);
        }
        // Counting sort by colour, stable.
        let mut offsets = [0u32; 65];
        let mut acc = 0;
        for (o, c) in offsets.iter_mut().zip(counts) {
            *o = acc;
            acc += c;
        }
        self.scratch.clear();
        self.scratch
            .resize(self.manifolds.len(), Manifold::default());
        for (m, &c) in self.manifolds.iter().zip(&self.colours) {
            self.scratch[offsets[c as usize] as usize] = *m;
            offsets[c as usize] += 1;
        }
        std::mem::swap(&mut self.manifolds, &mut self.scratch);
        if let Some((z, problem)) = space {
            self.order_colours_in_space(problem, z, &counts);
        }
        if self.settings.lanes {
            self.batch(&counts);
        }
    }

    /// For the chunked plan: each colour's manifolds (but the overflow colour's, whose order
    /// matters) in Z-order of their first point, so that a chunk holds neighbours and two
    /// threads share few bodies. Manifolds of a colour are independent: their order changes
    /// no impulse, only the grouping of `Σ Δλ²`.
    fn order_colours_in_space(
        &mut self,
        problem: &ContactProblem,
        z: &crate::z_order::ZOrder,
        counts: &[u32; 65],
    ) {
        let key = |m: &Manifold| z.key(&problem.points[m.start as usize].point);
        let mut start = 0;
        for &count in &counts[..64] {
            let range = start..start + count as usize;
            start = range.end;
            self.manifolds[range].sort_by_cached_key(key);
        }
    }

    /// Builds the sweep plan from the colour-sorted manifolds (`counts` per colour): the
    /// single-point manifolds of each colour go into batches of [`LANES`], the others stay
    /// in `manifolds` (moved behind the batched ones, which are dropped from it). The
    /// overflow colour (64) may share bodies and stays one at a time, in order.
    fn batch(&mut self, counts: &[u32; 65]) {
        // The dummy body the padding lanes read (always zero), then the sink the immovable
        // and padding lanes write (never read; the chunked plan's threads skip it).
        let dummy = self.vel.len() as u32;
        let sink = dummy + 1;
        self.vel.extend([Vel::default(); 2]);
        self.scratch.clear();
        let mut start = 0usize;
        for (colour, &count) in counts.iter().enumerate() {
            let range = start..start + count as usize;
            start = range.end;
            if count == 0 {
                continue;
            }
            let first_batch = self.batches.len();
            let first_manifold = self.scratch.len();
            let mut lane = LANES;
            for m in &self.manifolds[range] {
                if colour == 64 || m.count != 1 {
                    self.scratch.push(*m);
                    continue;
                }
                if lane == LANES {
                    self.batches.push(Batch::empty(dummy, sink));
                    lane = 0;
                }
                let batch = self.batches.last_mut().expect("pushed above");
                let r = &self.rows[m.start as usize];
                batch.a[lane] = m.a;
                batch.b[lane] = m.b;
                batch.wa[lane] = if movable(m.ma, m.ia) { m.a } else { sink };
                batch.wb[lane] = if movable(m.mb, m.ib) { m.b } else { sink };
                batch.row[lane] = m.start;
                batch.nx[lane] = r.nx;
                batch.ny[lane] = r.ny;
                batch.rna[lane] = r.rna;
                batch.rnb[lane] = r.rnb;
                batch.rta[lane] = r.rta;
                batch.rtb[lane] = r.rtb;
                batch.normal_mass[lane] = r.normal_mass;
                batch.tangent_mass[lane] = r.tangent_mass;
                batch.friction[lane] = r.friction;
                batch.bias[lane] = r.bias;
                batch.ma[lane] = m.ma;
                batch.ia[lane] = m.ia;
                batch.mb[lane] = m.mb;
                batch.ib[lane] = m.ib;
                batch.ln[lane] = r.ln;
                batch.lt[lane] = r.lt;
                lane += 1;
            }
            self.segments.push(Segment {
                batches: first_batch..self.batches.len(),
                manifolds: first_manifold..self.scratch.len(),
            });
        }
        // `manifolds` keeps every manifold (warm start, projection and residual walk it);
        // the one-at-a-time remainder of the sweep lives in `scratch`.
    }

    /// Copies the batched impulses back into their rows.
    pub(crate) fn sync_rows(&mut self) {
        for batch in &self.batches {
            for lane in 0..LANES {
                if let Some(r) = self.rows.get_mut(batch.row[lane] as usize) {
                    r.ln = batch.ln[lane];
                    r.lt = batch.lt[lane];
                }
            }
        }
    }

    /// Stage 2, warm start: apply the start impulses to the velocities.
    fn warm_start(&mut self) {
        for m in &self.manifolds {
            let (mut va, mut vb) = (self.vel[m.a as usize], self.vel[m.b as usize]);
            for r in &self.rows[m.start as usize..(m.start + m.count) as usize] {
                apply(m, r, &mut va, &mut vb, r.ln, r.lt);
            }
            store(self.vel.as_mut_slice(), m, va, vb);
        }
    }

    /// Stage 3, one Gauss-Seidel sweep. Returns its impulse changes' measures; the
    /// per-contact measure only with `CONTACT` (the hot loop carries no extra work otherwise).
    /// Inlined into [`Self::solve_loop`]'s instruction-set context.
    #[inline(always)]
    pub(crate) fn iterate<const CONTACT: bool, K: BatchKernel>(&mut self, kernel: K) -> Sweep {
        let mut acc = Sweep::default();
        if self.segments.is_empty() {
            for m in &self.manifolds {
                sweep_manifold::<CONTACT, _>(m, &mut self.rows, self.vel.as_mut_slice(), &mut acc);
            }
            return acc;
        }
        let mut lanes = LaneSweep::default();
        for seg in &self.segments {
            kernel.sweep::<CONTACT>(
                &mut self.batches[seg.batches.clone()],
                self.vel.as_mut_slice(),
                &mut lanes,
            );
            for m in &self.scratch[seg.manifolds.clone()] {
                sweep_manifold::<CONTACT, _>(m, &mut self.rows, self.vel.as_mut_slice(), &mut acc);
            }
        }
        acc.add_lanes(&lanes);
        acc
    }

    /// Stage 3's loop on this thread: sweep until the stop rule holds, the cap is reached or
    /// a change is not finite. Returns the iterations run and the last verdict. The whole
    /// loop runs compiled for the solver's instruction set ([`SolveLoop`]).
    fn solve_loop(
        &mut self,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> (u32, Verdict) {
        dispatch(
            self.arch,
            SolveLoop {
                solver: self,
                settings,
                report,
            },
        )
    }

    /// [`Self::solve_loop`]'s body, inlined into the instruction-set context.
    #[inline(always)]
    fn solve_loop_here<K: BatchKernel>(
        &mut self,
        settings: &SolverSettings,
        report: &mut SolveReport,
        kernel: K,
    ) -> (u32, Verdict) {
        let mut it = 0;
        while it < settings.max_iterations {
            let sweep = if settings.norm == ResidualNorm::Contact {
                self.iterate::<true, K>(kernel)
            } else {
                self.iterate::<false, K>(kernel)
            };
            it += 1;
            match judge(settings, it, &sweep, Some(report)) {
                Verdict::Continue => {}
                end => return (it, end),
            }
        }
        (it, Verdict::Continue)
    }

    /// Friction rows were clamped against the normal impulse of the previous sweep; a
    /// last projection onto the final cone `|λt| ≤ μ λn` (its change applied to the
    /// velocities, so both stay consistent) makes the returned impulses admissible even
    /// when the cap was hit. The change is at most μ × the last normal change.
    fn project_friction(&mut self) {
        for m in &self.manifolds {
            let (mut va, mut vb) = (self.vel[m.a as usize], self.vel[m.b as usize]);
            for r in &mut self.rows[m.start as usize..(m.start + m.count) as usize] {
                let new = clamp_sym(r.lt, r.friction * r.ln);
                if new != r.lt {
                    let d = new - r.lt;
                    r.lt = new;
                    apply_tangent(m, r, &mut va, &mut vb, d);
                }
            }
            store(self.vel.as_mut_slice(), m, va, vb);
        }
    }

    /// The error for a sweep that produced a non-finite impulse or velocity.
    fn diverged(&self, iteration: u32) -> PgsError {
        let point = self
            .rows
            .iter()
            .position(|r| !(r.ln.is_finite() && r.lt.is_finite()))
            .unwrap_or(0);
        PgsError::Diverged { point, iteration }
    }

    /// Natural-map residual of the current impulses and velocities, in impulse units.
    fn natural_residual(&self) -> Real {
        let mut res: Real = 0.0;
        for m in &self.manifolds {
            let (va, vb) = (&self.vel[m.a as usize], &self.vel[m.b as usize]);
            for r in &self.rows[m.start as usize..(m.start + m.count) as usize] {
                let rn = r.ln
                    - non_negative(r.ln - r.normal_mass * (normal_velocity(r, va, vb) - r.bias));
                let rt = r.lt
                    - clamp_sym(
                        r.lt - r.tangent_mass * tangent_velocity(r, va, vb),
                        r.friction * r.ln,
                    );
                res = res.max(rn.abs()).max(rt.abs());
            }
        }
        res
    }
}

/// [`PgsSolver::solve_loop`] as an operation of [`pulp::Arch::dispatch`]: the whole
/// iteration loop (every sweep, its kernels inlined) compiled once per instruction set — with
/// AVX2 and FMA enabled, each lane field of a [`Batch`] is one 256-bit register. The
/// arithmetic is the same IEEE operations in the same order (Rust never contracts `a * b + c`
/// into a fused multiply-add), so the bits do not depend on the instruction set.
struct SolveLoop<'a> {
    solver: &'a mut PgsSolver,
    settings: &'a SolverSettings,
    report: &'a mut SolveReport,
}

impl KernelOp for SolveLoop<'_> {
    type Output = (u32, Verdict);

    #[inline(always)]
    fn run<K: BatchKernel>(self, kernel: K) -> Self::Output {
        self.solver
            .solve_loop_here(self.settings, self.report, kernel)
    }
}

/// An operation of [`dispatch`]: sweeps compiled for one instruction set, running their
/// batches with that set's [`BatchKernel`].
pub(crate) trait KernelOp {
    /// What the operation returns.
    type Output;
    /// Runs the operation with `kernel`.
    fn run<K: BatchKernel>(self, kernel: K) -> Self::Output;
}

/// Runs `op` compiled for `arch` (its kernels inlined): with AVX2 detected, with the
/// intrinsics kernel of [`avx2`]; otherwise with the portable loop, which the compiler
/// vectorises for the set as it can. Both give the same bits.
#[inline]
pub(crate) fn dispatch<Op: KernelOp>(arch: pulp::Arch, op: Op) -> Op::Output {
    #[cfg(target_arch = "x86_64")]
    if let pulp::Arch::V3(simd) = arch {
        return <pulp::x86::V3 as pulp::Simd>::vectorize(simd, WithKernel(op, simd));
    }
    arch.dispatch(WithKernel(op, Portable))
}

/// [`dispatch`]'s operation with its kernel, as [`pulp::WithSimd`] wants it.
struct WithKernel<Op, K>(Op, K);

impl<Op: KernelOp, K: BatchKernel> pulp::WithSimd for WithKernel<Op, K> {
    type Output = Op::Output;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        self.0.run(self.1)
    }
}

/// How a sweep runs a [`Batch`]: the portable loop ([`sweep_batch`], which the compiler
/// vectorises as it can) or, with AVX2 detected, the same operations written out in its
/// intrinsics ([`avx2`]). Both give the same bits.
pub(crate) trait BatchKernel: Copy {
    /// Sweeps the batches of one colour in order on `vel`, folding their measures into
    /// `lanes`.
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch], vel: &mut [Vel], lanes: &mut LaneSweep);

    /// Sweeps all the batches of two islands, each in order on its own velocities and into
    /// its own measures (the portable loop: one island, then the other).
    #[inline(always)]
    fn sweep_two<const CONTACT: bool>(self, a: Island<'_>, b: Island<'_>) {
        for batch in a.batches {
            sweep_batch::<CONTACT, _>(batch, a.vel, a.lanes);
        }
        for batch in b.batches {
            sweep_batch::<CONTACT, _>(batch, b.vel, b.lanes);
        }
    }
}

/// One island's batches (all of them, colour after colour), velocities and measures, for
/// [`BatchKernel::sweep_two`].
pub(crate) struct Island<'a> {
    pub(crate) batches: &'a mut [Batch],
    pub(crate) vel: &'a mut [Vel],
    pub(crate) lanes: &'a mut LaneSweep,
}

/// [`BatchKernel`] of the portable loop.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

impl BatchKernel for Portable {
    #[inline(always)]
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch], vel: &mut [Vel], lanes: &mut LaneSweep) {
        for batch in b {
            sweep_batch::<CONTACT, _>(batch, vel, lanes);
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl BatchKernel for pulp::x86::V3 {
    #[inline(always)]
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch], vel: &mut [Vel], lanes: &mut LaneSweep) {
        avx2::sweep_colour::<CONTACT>(self, b, vel, lanes);
    }

    #[inline(always)]
    fn sweep_two<const CONTACT: bool>(self, a: Island<'_>, b: Island<'_>) {
        avx2::sweep_two::<CONTACT>(self, a, b);
    }
}

/// `x` clamped to `[-bound, bound]` as `f64::clamp` does it, without its panic for a
/// NaN or negative bound (a NaN then reaches the divergence check).
#[inline(always)]
fn clamp_sym(x: Real, bound: Real) -> Real {
    let lo = -bound;
    let x = if x < lo { lo } else { x };
    if x > bound { bound } else { x }
}

/// `max(x, 0)` that keeps a NaN (for the divergence check) and is the same in every lane.
#[inline(always)]
fn non_negative(x: Real) -> Real {
    if x < 0.0 { 0.0 } else { x }
}

/// The measures of one sweep's impulse changes.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Sweep {
    /// `max |Δλ|` over the rows.
    pub(crate) max: Real,
    /// `Σ Δλ²` over the rows.
    pub(crate) sum_sq: Real,
    /// The largest per-manifold `Δλn² + max(0, Δλt)²` (`Δλn` of one-point manifolds only),
    /// the square of [`ResidualNorm::Contact`].
    pub(crate) contact_sq: Real,
}

impl Sweep {
    /// Folds the lanes' measures in, lane by lane.
    #[inline]
    pub(crate) fn add_lanes(&mut self, lanes: &LaneSweep) {
        for lane in 0..LANES {
            self.max = self.max.max(lanes.max[lane]);
            self.sum_sq += lanes.sum_sq[lane];
            self.contact_sq = self.contact_sq.max(lanes.contact_sq[lane]);
        }
    }

    /// [`Self::add_lanes`] for an island that owns lanes `first..first + width` of `lanes`
    /// (the others being padding of its own batches, or other islands'). The same bits: a
    /// padding lane measures exactly +0, and folding a +0 into a sum of squares or a
    /// maximum of magnitudes (never NaN: `max` skips it) changes nothing.
    #[inline]
    pub(crate) fn add_span(&mut self, lanes: &LaneSweep, first: usize, width: usize) {
        for lane in first..first + width {
            self.max = self.max.max(lanes.max[lane]);
            self.sum_sq += lanes.sum_sq[lane];
            self.contact_sq = self.contact_sq.max(lanes.contact_sq[lane]);
        }
    }

    /// Folds in the measures of rows swept after this sweep's.
    #[inline]
    pub(crate) fn add(&mut self, other: &Sweep) {
        self.max = self.max.max(other.max);
        self.sum_sq += other.sum_sq;
        self.contact_sq = self.contact_sq.max(other.contact_sq);
    }
}

/// What the stop rule makes of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// Iterate again (if the cap allows).
    Continue,
    /// The stop rule holds.
    Converged,
    /// An impulse change is not finite.
    Diverged,
}

/// Judges iteration `it` (1-based) from its sweep's measures, recording its residuals in
/// `report` when one is given (threads that share a sweep all judge; one records).
#[inline]
pub(crate) fn judge(
    settings: &SolverSettings,
    it: u32,
    sweep: &Sweep,
    report: Option<&mut SolveReport>,
) -> Verdict {
    let (max_d, l2) = (sweep.max, sweep.sum_sq.sqrt());
    if let Some(report) = report {
        report.residual_inf.push(max_d);
        report.residual_l2.push(l2);
    }
    // `max` skips NaN, so a NaN change shows only in the sum of squares.
    if !(max_d.is_finite() && l2.is_finite()) {
        Verdict::Diverged
    } else if settings.converged(it, max_d, l2, sweep.contact_sq.sqrt()) {
        Verdict::Converged
    } else {
        Verdict::Continue
    }
}

/// [`Sweep`] per lane of [`sweep_batch`], as structure of arrays (one register per measure).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LaneSweep {
    max: [Real; LANES],
    sum_sq: [Real; LANES],
    contact_sq: [Real; LANES],
}

/// One manifold's rows: friction first (bounded by the current normal impulse), then the
/// normal rows (block solver for a 2-point manifold with a well-conditioned `K`).
#[inline(always)]
pub(crate) fn sweep_manifold<const CONTACT: bool, V: Velocities + ?Sized>(
    m: &Manifold,
    rows: &mut [Row],
    vel: &mut V,
    acc: &mut Sweep,
) {
    let rows = &mut rows[m.start as usize..(m.start + m.count) as usize];
    // Accumulated in locals (registers), written back once.
    let (mut mx, mut sq, mut cs) = (acc.max, acc.sum_sq, acc.contact_sq);
    let (mut va, mut vb) = (vel.get(m.a), vel.get(m.b));
    // The original's per-contact measure: the largest signed friction change (from 0), and
    // the normal change of a one-point manifold.
    let (mut t_pos, mut n_one): (Real, Real) = (0.0, 0.0);
    for r in rows.iter_mut() {
        let vt = tangent_velocity(r, &va, &vb);
        let new = clamp_sym(r.lt - r.tangent_mass * vt, r.friction * r.ln);
        let d = new - r.lt;
        r.lt = new;
        apply_tangent(m, r, &mut va, &mut vb, d);
        mx = mx.max(d.abs());
        sq += d * d;
        if CONTACT {
            t_pos = t_pos.max(d);
        }
    }
    if let Some(k) = &m.block {
        let (d1, d2) = solve_block(m, rows, k, &mut va, &mut vb);
        mx = mx.max(d1.abs()).max(d2.abs());
        sq += d1 * d1 + d2 * d2;
    } else {
        for r in rows.iter_mut() {
            let vn = normal_velocity(r, &va, &vb);
            let new = non_negative(r.ln - r.normal_mass * (vn - r.bias));
            let d = new - r.ln;
            r.ln = new;
            apply_normal(m, r, &mut va, &mut vb, d);
            mx = mx.max(d.abs());
            sq += d * d;
            n_one = d;
        }
        if m.count != 1 {
            n_one = 0.0;
        }
    }
    if CONTACT {
        cs = cs.max(n_one * n_one + t_pos * t_pos);
    }
    (acc.max, acc.sum_sq, acc.contact_sq) = (mx, sq, cs);
    store(vel, m, va, vb);
}

/// [`LANES`] single-point manifolds of one colour: gather the body velocities, run the
/// friction row and the normal row of every lane with exactly the arithmetic of
/// [`sweep_manifold`] (so each lane's result is bit-identical to it), scatter the movable
/// bodies back. The lanes' bodies are distinct (one colour), except immovable ones, which
/// are read but never written (their lanes store into the sink slot instead).
#[inline(always)]
pub(crate) fn sweep_batch<const CONTACT: bool, V: Velocities + ?Sized>(
    b: &mut Batch,
    vel: &mut V,
    lanes: &mut LaneSweep,
) {
    let mut t_pos = [0.0; LANES];
    let (mut avx, mut avy, mut aw) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
    let (mut bvx, mut bvy, mut bw) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
    for i in 0..LANES {
        let (va, vb) = (vel.get(b.a[i]), vel.get(b.b[i]));
        (avx[i], avy[i], aw[i]) = (va.vx, va.vy, va.w);
        (bvx[i], bvy[i], bw[i]) = (vb.vx, vb.vy, vb.w);
    }
    // Friction rows: `tangent_velocity`, clamp, then `apply_tangent`.
    for i in 0..LANES {
        let vt = (bvx[i] - avx[i]) * -b.ny[i] + (bvy[i] - avy[i]) * b.nx[i] + bw[i] * b.rtb[i]
            - aw[i] * b.rta[i];
        let new = clamp_sym(b.lt[i] - b.tangent_mass[i] * vt, b.friction[i] * b.ln[i]);
        let d = new - b.lt[i];
        b.lt[i] = new;
        let (px, py) = (d * -b.ny[i], d * b.nx[i]);
        avx[i] -= b.ma[i] * px;
        avy[i] -= b.ma[i] * py;
        aw[i] -= b.ia[i] * (d * b.rta[i]);
        bvx[i] += b.mb[i] * px;
        bvy[i] += b.mb[i] * py;
        bw[i] += b.ib[i] * (d * b.rtb[i]);
        lanes.max[i] = lanes.max[i].max(d.abs());
        lanes.sum_sq[i] += d * d;
        if CONTACT {
            t_pos[i] = d.max(0.0);
        }
    }
    // Normal rows: `normal_velocity`, projection, then `apply_normal`.
    for i in 0..LANES {
        let vn = (bvx[i] - avx[i]) * b.nx[i] + (bvy[i] - avy[i]) * b.ny[i] + bw[i] * b.rnb[i]
            - aw[i] * b.rna[i];
        let new = non_negative(b.ln[i] - b.normal_mass[i] * (vn - b.bias[i]));
        let d = new - b.ln[i];
        b.ln[i] = new;
        let (px, py) = (d * b.nx[i], d * b.ny[i]);
        avx[i] -= b.ma[i] * px;
        avy[i] -= b.ma[i] * py;
        aw[i] -= b.ia[i] * (d * b.rna[i]);
        bvx[i] += b.mb[i] * px;
        bvy[i] += b.mb[i] * py;
        bw[i] += b.ib[i] * (d * b.rnb[i]);
        lanes.max[i] = lanes.max[i].max(d.abs());
        lanes.sum_sq[i] += d * d;
        if CONTACT {
            lanes.contact_sq[i] = lanes.contact_sq[i].max(d * d + t_pos[i] * t_pos[i]);
        }
    }
    // Movable bodies back; immovable and padding lanes into the sink ([`Batch::wa`]).
    for i in 0..LANES {
        vel.set(
            b.wa[i],
            Vel {
                vx: avx[i],
                vy: avy[i],
                w: aw[i],
            },
        );
        vel.set(
            b.wb[i],
            Vel {
                vx: bvx[i],
                vy: bvy[i],
                w: bw[i],
            },
        );
    }
}

/// Whether a body with these inverse masses can move.
#[inline(always)]
pub(crate) fn movable(inv_mass: Real, inv_inertia: Real) -> bool {
    inv_mass != 0.0 || inv_inertia != 0.0
}

/// Writes the manifold's body velocities back; immovable bodies are never written, so
/// manifolds sharing only a wall stay independent.
#[inline(always)]
fn store<V: Velocities + ?Sized>(vel: &mut V, m: &Manifold, va: Vel, vb: Vel) {
    if movable(m.ma, m.ia) {
        vel.set(m.a, va);
    }
    if movable(m.mb, m.ib) {
        vel.set(m.b, vb);
    }
}

/// Body velocities as a sweep reads and writes them: a plain slice on one thread, shared
/// atomic cells when threads split a colour ([`crate::velocity_chunked`]).
pub(crate) trait Velocities {
    /// Velocity of body `i`.
    fn get(&self, i: u32) -> Vel;
    /// Sets the velocity of body `i`.
    fn set(&mut self, i: u32, v: Vel);
}

impl Velocities for [Vel] {
    #[inline(always)]
    fn get(&self, i: u32) -> Vel {
        self[i as usize]
    }

    #[inline(always)]
    fn set(&mut self, i: u32, v: Vel) {
        self[i as usize] = v;
    }
}

/// Relative normal velocity `(vB + ωB × rB − vA − ωA × rA) · n`.
#[inline(always)]
fn normal_velocity(r: &Row, va: &Vel, vb: &Vel) -> Real {
    (vb.vx - va.vx) * r.nx + (vb.vy - va.vy) * r.ny + vb.w * r.rnb - va.w * r.rna
}

/// Relative tangent velocity along `t = (−n.y, n.x)`; `(ω × r) · t = ω (r × t)`.
#[inline(always)]
fn tangent_velocity(r: &Row, va: &Vel, vb: &Vel) -> Real {
    (vb.vx - va.vx) * -r.ny + (vb.vy - va.vy) * r.nx + vb.w * r.rtb - va.w * r.rta
}

/// Applies the impulse change `(dn, dt)` of row `r` to the manifold's two bodies.
#[inline(always)]
fn apply(m: &Manifold, r: &Row, va: &mut Vel, vb: &mut Vel, dn: Real, dt: Real) {
    let (px, py) = (dn * r.nx - dt * r.ny, dn * r.ny + dt * r.nx);
    va.vx -= m.ma * px;
    va.vy -= m.ma * py;
    va.w -= m.ia * (dn * r.rna + dt * r.rta);
    vb.vx += m.mb * px;
    vb.vy += m.mb * py;
    vb.w += m.ib * (dn * r.rnb + dt * r.rtb);
}

/// [`apply`] of a normal impulse change `dn` alone (`P = dn n`).
#[inline(always)]
fn apply_normal(m: &Manifold, r: &Row, va: &mut Vel, vb: &mut Vel, dn: Real) {
    let (px, py) = (dn * r.nx, dn * r.ny);
    va.vx -= m.ma * px;
    va.vy -= m.ma * py;
    va.w -= m.ia * (dn * r.rna);
    vb.vx += m.mb * px;
    vb.vy += m.mb * py;
    vb.w += m.ib * (dn * r.rnb);
}

/// [`apply`] of a tangent impulse change `dt` alone (`P = dt t`, `t = (−n.y, n.x)`).
#[inline(always)]
fn apply_tangent(m: &Manifold, r: &Row, va: &mut Vel, vb: &mut Vel, dt: Real) {
    let (px, py) = (dt * -r.ny, dt * r.nx);
    va.vx -= m.ma * px;
    va.vy -= m.ma * py;
    va.w -= m.ia * (dt * r.rta);
    vb.vx += m.mb * px;
    vb.vy += m.mb * py;
    vb.w += m.ib * (dt * r.rtb);
}

/// Box2D v2.4's 2-point block solver for the normal rows: solve the mixed LCP
/// `vn = K x + b, x ≥ 0, vn ≥ 0, x·vn = 0` on the accumulated impulses by enumerating
/// the four cases (both active, only 1, only 2, none). Returns the two Δλn.
fn solve_block(
    m: &Manifold,
    rows: &mut [Row],
    k: &Block,
    va: &mut Vel,
    vb: &mut Vel,
) -> (Real, Real) {
    let (r1, r2) = (rows[0], rows[1]);
    let (a1, a2) = (r1.ln, r2.ln);
    // b = vn − bias − K a
    let b1 = normal_velocity(&r1, va, vb) - r1.bias - (k.k11 * a1 + k.k12 * a2);
    let b2 = normal_velocity(&r2, va, vb) - r2.bias - (k.k12 * a1 + k.k22 * a2);
    let candidates = [
        // Case 1: both points active, x = −K⁻¹ b.
        (-(k.i11 * b1 + k.i12 * b2), -(k.i12 * b1 + k.i22 * b2)),
        // Case 2: only the first.
        (-r1.normal_mass * b1, 0.0),
        // Case 3: only the second.
        (0.0, -r2.normal_mass * b2),
        // Case 4: none.
        (0.0, 0.0),
    ];
    // If no case holds (round-off), keep the current impulses.
    let mut x = (a1, a2);
    for (case, &(x1, x2)) in candidates.iter().enumerate() {
        let vn1 = k.k11 * x1 + k.k12 * x2 + b1;
        let vn2 = k.k12 * x1 + k.k22 * x2 + b2;
        let ok = match case {
            0 => x1 >= 0.0 && x2 >= 0.0,
            1 => x1 >= 0.0 && vn2 >= 0.0,
            2 => x2 >= 0.0 && vn1 >= 0.0,
            _ => b1 >= 0.0 && b2 >= 0.0,
        };
        if ok {
            x = (x1, x2);
            break;
        }
    }
    let (d1, d2) = (x.0 - a1, x.1 - a2);
    rows[0].ln = x.0;
    rows[1].ln = x.1;
    apply_normal(m, &r1, va, vb, d1);
    apply_normal(m, &r2, va, vb, d2);
    (d1, d2)
}

impl PgsSolver {
    /// Stages 1 and 2 of a solve: checks, prepare, warm start.
    pub(crate) fn begin(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &[Impulse],
        velocities: &[Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        deepcontact_core::solver::begin_solve(
            problem,
            settings,
            self.settings.validate,
            impulses,
            velocities,
            report,
        )?;
        self.prepare(problem, impulses);
        self.warm_start();
        report
            .residual_inf
            .reserve(settings.max_iterations.min(4096) as usize);
        report
            .residual_l2
            .reserve(settings.max_iterations.min(4096) as usize);
        Ok(())
    }

    /// Stage 3 in the plan the island's size calls for: the iterations run and the verdict.
    pub(crate) fn run(
        &mut self,
        points: usize,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> (u32, Verdict) {
        if self.plans_domains(points) {
            self.domains.build(
                self.settings.domains,
                crate::sync::effective_threads(self.settings.threads),
                &self.manifolds,
                &self.rows,
                &self.vel,
                self.settings,
            );
            let run = self.domains.solve(
                crate::sync::effective_threads(self.settings.threads),
                self.arch,
                settings,
                report,
            );
            self.domains.write_back(&mut self.rows, &mut self.vel);
            run
        } else if self.plans_chunked(points) && !self.segments.is_empty() {
            crate::velocity_chunked::solve_chunked(
                &mut crate::velocity_chunked::Sweepable {
                    batches: &mut self.batches,
                    segments: &self.segments,
                    serial: &self.scratch,
                    rows: &mut self.rows,
                    vel: &mut self.vel,
                },
                crate::velocity_chunked::CHUNK,
                crate::sync::effective_threads(self.settings.threads),
                self.arch,
                settings,
                report,
            )
        } else {
            self.solve_loop(settings, report)
        }
    }

    /// Stage 4 of a solve that ran `it` iterations to `verdict`: the final projection, the
    /// checks, and the impulses, velocities and natural residual stored.
    pub(crate) fn end(
        &mut self,
        it: u32,
        verdict: Verdict,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.sync_rows();
        if verdict == Verdict::Diverged {
            return Err(self.diverged(it).into());
        }
        report.converged = verdict == Verdict::Converged;
        report.iterations = it;
        self.project_friction();
        let finite = |v: &Vel| v.vx.is_finite() && v.vy.is_finite() && v.w.is_finite();
        if !(self
            .rows
            .iter()
            .all(|r| r.ln.is_finite() && r.lt.is_finite())
            && self.vel.iter().all(finite))
        {
            return Err(self.diverged(it).into());
        }
        // Store impulses and velocities.
        for (imp, r) in impulses.iter_mut().zip(&self.rows) {
            *imp = Impulse::new(r.ln, r.lt);
        }
        let velocity = |v: &Vel| Velocity::new(Vector::new(v.vx, v.vy), v.w);
        if !self.bodies.is_active() {
            for (out, v) in velocities.iter_mut().zip(&self.vel) {
                *out = velocity(v);
            }
        } else {
            for (&b, v) in self.bodies.body_of.iter().zip(&self.vel) {
                velocities[b as usize] = velocity(v);
            }
        }
        report.natural_residual = self.natural_residual();
        Ok(())
    }
}

impl VelocitySolver for PgsSolver {
    fn name(&self) -> &str {
        "pgs"
    }

    /// The same settings on one thread (a fork solves one island beside others; the result
    /// does not depend on the thread count).
    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        Some(Box::new(PgsSolver::with_settings(PgsSettings {
            threads: 1,
            ..self.settings
        })))
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let t0 = Instant::now();
        self.begin(problem, settings, impulses, velocities, report)?;
        let (it, verdict) = self.run(problem.points.len(), settings, report);
        self.end(it, verdict, impulses, velocities, report)?;
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }

    fn solve_many(&mut self, settings: &SolverSettings, islands: &mut [IslandSolve<'_>]) {
        self.solve_islands(settings, islands);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};

    fn pile_problem() -> ContactProblem {
        let mut world = scene::pile(12345, 100)
            .unwrap()
            .build(WorldSettings::default())
            .unwrap();
        let (mut s, mut p) = (PgsSolver::new(), crate::PgsPositionSolver::new());
        for _ in 0..130 {
            world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
        }
        world
            .last_problems()
            .iter()
            .max_by_key(|p| p.len())
            .unwrap()
            .clone()
    }

    #[test]
    fn colouring_never_puts_two_manifolds_on_one_movable_body_in_a_colour() {
        let problem = pile_problem();
        let mut solver = PgsSolver::new();
        solver.prepare(&problem, &vec![Impulse::ZERO; problem.len()]);
        assert_eq!(solver.manifolds.len(), problem.manifolds.len());
        let mut colours = solver.colours.clone();
        colours.sort_unstable();
        let mut seen = std::collections::HashSet::new();
        for (i, m) in solver.manifolds.iter().enumerate() {
            if i > 0 && colours[i] != colours[i - 1] {
                seen.clear();
            }
            if colours[i] == 64 {
                continue;
            }
            for (body, im, ii) in [(m.a, m.ma, m.ia), (m.b, m.mb, m.ib)] {
                if movable(im, ii) {
                    assert!(
                        seen.insert(body),
                        "body {body} twice in colour {}",
                        colours[i]
                    );
                }
            }
        }
    }

    #[test]
    fn coloured_and_sequential_orders_reach_the_same_velocities() {
        let problem = pile_problem();
        let settings = SolverSettings {
            tolerance: 1e-10,
            max_iterations: 100_000,
            ..SolverSettings::default()
        };
        let mut out = Vec::new();
        for ordering in [Ordering::Sequential, Ordering::Coloured] {
            let mut solver = PgsSolver::with_settings(PgsSettings {
                ordering,
                ..PgsSettings::default()
            });
            let mut imp = vec![Impulse::ZERO; problem.len()];
            let mut vel = vec![Velocity::default(); problem.bodies.len()];
            let mut report = SolveReport::default();
            solver
                .solve(&problem, &settings, &mut imp, &mut vel, &mut report)
                .unwrap();
            assert!(report.converged);
            out.push(vel);
        }
        for (v1, v2) in out[0].iter().zip(&out[1]) {
            assert!(
                (v1.linear - v2.linear).norm() < 1e-6 && (v1.angular - v2.angular).abs() < 1e-6
            );
        }
    }

    /// Solves `problem` from `start` with the given options; returns the impulses and
    /// velocities as bits.
    fn solve_bits(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        iterations: u32,
    ) -> (Vec<u64>, Vec<u64>, u32) {
        let stop = SolverSettings {
            max_iterations: iterations,
            ..SolverSettings::default()
        };
        solve_bits_with(problem, start, settings, &stop).0
    }

    /// [`solve_bits`] under the stop rule `stop`; also returns the L2 residuals as bits.
    fn solve_bits_with(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        stop: &SolverSettings,
    ) -> ((Vec<u64>, Vec<u64>, u32), Vec<u64>) {
        solve_bits_on(problem, start, settings, stop, pulp::Arch::new())
    }

    /// [`solve_bits_with`] with the sweeps compiled for `arch`.
    fn solve_bits_on(
        problem: &ContactProblem,
        start: &[Impulse],
        settings: PgsSettings,
        stop: &SolverSettings,
        arch: pulp::Arch,
    ) -> ((Vec<u64>, Vec<u64>, u32), Vec<u64>) {
        let mut solver = PgsSolver::with_settings(settings);
        solver.arch = arch;
        let mut imp = start.to_vec();
        let mut vel = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        solver
            .solve(problem, stop, &mut imp, &mut vel, &mut report)
            .unwrap();
        let l2 = report.residual_l2.iter().map(|r| r.to_bits()).collect();
        let bits = (
            imp.iter()
                .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
                .collect(),
            vel.iter()
                .flat_map(|v| {
                    [
                        v.linear.x.to_bits(),
                        v.linear.y.to_bits(),
                        v.angular.to_bits(),
                    ]
                })
                .collect(),
            report.iterations,
        );
        (bits, l2)
    }

    /// The pile's largest island and the pyramid's (2-point manifolds, swept one at a time
    /// by thread 0 of the chunked plan).
    fn pile_and_pyramid() -> Vec<ContactProblem> {
        let mut problems = vec![pile_problem()];
        let mut world = scene::pyramid(6).build(WorldSettings::default()).unwrap();
        let (mut s, mut p) = (PgsSolver::new(), crate::PgsPositionSolver::new());
        for _ in 0..40 {
            world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
        }
        problems.extend(world.last_problems().iter().cloned());
        problems
    }

    /// A start with load on every point (growing with the point's index).
    fn loaded_start(problem: &ContactProblem) -> Vec<Impulse> {
        (0..problem.len())
            .map(|i| Impulse::new(0.01 * i as Real, 0.001 * i as Real))
            .collect()
    }

    /// A tight stop rule (1e-6) in each norm.
    fn tight_stops() -> [SolverSettings; 3] {
        [
            ResidualNorm::Infinity,
            ResidualNorm::Contact,
            ResidualNorm::L2,
        ]
        .map(|norm| SolverSettings {
            norm,
            tolerance: 1e-6,
            ..SolverSettings::default()
        })
    }

    /// The solver's impulses (rows) and velocities as bits.
    fn state_bits(solver: &PgsSolver) -> (Vec<u64>, Vec<u64>) {
        let rows = solver
            .rows
            .iter()
            .flat_map(|r| [r.ln.to_bits(), r.lt.to_bits()])
            .collect();
        let vel = solver
            .vel
            .iter()
            .flat_map(|v| [v.vx.to_bits(), v.vy.to_bits(), v.w.to_bits()])
            .collect();
        (rows, vel)
    }

    /// Runs `sweep` (a loop straight past the clamp to the machine's cores) on the 100-body
    /// pile from zero with 1 to 5 threads, after `settings`' prepare and warm start, and checks
    /// that every run converges to the same bits (impulses, velocities, iterations, L2 curve).
    fn same_bits_on_one_to_five_threads(
        settings: PgsSettings,
        sweep: impl Fn(&mut PgsSolver, usize, &SolverSettings, &mut SolveReport) -> (u32, Verdict),
    ) {
        let problem = pile_problem();
        let stop = SolverSettings {
            tolerance: 1e-5,
            ..SolverSettings::default()
        };
        let runs: Vec<_> = (1..=5)
            .map(|threads| {
                let mut solver = PgsSolver::with_settings(settings);
                solver.prepare(&problem, &vec![Impulse::ZERO; problem.len()]);
                solver.warm_start();
                let mut report = SolveReport::default();
                let (it, verdict) = sweep(&mut solver, threads, &stop, &mut report);
                let (rows, vel) = state_bits(&solver);
                (it, verdict, rows, vel, report.residual_l2)
            })
            .collect();
        assert_eq!(runs[0].1, Verdict::Converged);
        assert!(runs[0].0 > 10);
        for r in &runs[1..] {
            assert!(r == &runs[0]);
        }
    }

    #[test]
    fn chunked_plan_gives_the_same_bits_on_one_to_five_real_threads() {
        // One batch a chunk, so that a 100-body island has chunks for five threads.
        same_bits_on_one_to_five_threads(
            PgsSettings::default(),
            |solver, threads, stop, report| {
                let run = crate::velocity_chunked::solve_chunked(
                    &mut crate::velocity_chunked::Sweepable {
                        batches: &mut solver.batches,
                        segments: &solver.segments,
                        serial: &solver.scratch,
                        rows: &mut solver.rows,
                        vel: &mut solver.vel,
                    },
                    1,
                    threads,
                    solver.arch,
                    stop,
                    report,
                );
                solver.sync_rows();
                run
            },
        );
    }

    #[test]
    fn chunked_sweep_is_bit_identical_for_one_two_and_four_threads() {
        for problem in pile_and_pyramid() {
            let start = loaded_start(&problem);
            for stop in tight_stops() {
                let norm = stop.norm;
                let unchunked = solve_bits_with(&problem, &start, PgsSettings::default(), &stop);
                let runs: Vec<_> = [1, 2, 4]
                    .map(|threads| {
                        let settings = PgsSettings {
                            threads,
                            parallel_min_points: 0,
                            domains: 0,
                            ..PgsSettings::default()
                        };
                        solve_bits_with(&problem, &start, settings, &stop)
                    })
                    .into();
                assert!(runs[0].0.2 > 1, "ran {} iterations", runs[0].0.2);
                assert_eq!(runs[0], runs[1], "{norm:?}: 1 and 2 threads");
                assert_eq!(runs[0], runs[2], "{norm:?}: 1 and 4 threads");
                if norm != ResidualNorm::L2 {
                    // Only Σ Δλ² is summed in chunk order.
                    assert_eq!(runs[0].0, unchunked.0, "{norm:?}: chunked and unchunked");
                }
            }
        }
    }

    #[test]
    fn detected_instruction_set_and_baseline_give_the_same_bits() {
        // The detected set (AVX2 + FMA on most x86-64 machines) against the baseline build of
        // the same loops: plain, chunked on one thread (whole loop dispatched) and on two (each
        // item dispatched), both sweep variants (`CONTACT` or not).
        let detected = pulp::Arch::new();
        for problem in pile_and_pyramid() {
            let start = loaded_start(&problem);
            let plans = [
                (1, usize::MAX, 0),
                (1, 0, 0),
                (2, 0, 0),
                (1, 0, 2),
                (2, 0, 3),
            ];
            for (threads, parallel_min_points, domains) in plans {
                for norm in [ResidualNorm::Infinity, ResidualNorm::Contact] {
                    let stop = SolverSettings {
                        norm,
                        tolerance: 1e-6,
                        ..SolverSettings::default()
                    };
                    let settings = PgsSettings {
                        threads,
                        parallel_min_points,
                        domains,
                        ..PgsSettings::default()
                    };
                    let baseline =
                        solve_bits_on(&problem, &start, settings, &stop, pulp::Arch::Scalar);
                    let fast = solve_bits_on(&problem, &start, settings, &stop, detected);
                    assert!(baseline.0.2 > 1, "ran {} iterations", baseline.0.2);
                    assert_eq!(
                        baseline, fast,
                        "{threads} threads, {domains} domains, {norm:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn lanes_are_bit_identical_to_one_manifold_at_a_time() {
        // Circles (single-point manifolds, batched) and a pyramid of boxes (2-point
        // manifolds with the block solver, one at a time), from zero and carried starts.
        let problems = pile_and_pyramid();
        let mut batched = 0;
        for problem in &problems {
            let carried: Vec<Impulse> = (0..problem.len())
                .map(|i| Impulse::new(0.01 * i as Real, 0.001 * i as Real))
                .collect();
            for start in [vec![Impulse::ZERO; problem.len()], carried] {
                let one = PgsSettings {
                    lanes: false,
                    ..PgsSettings::default()
                };
                let reference = solve_bits(problem, &start, one, 300);
                let lanes = solve_bits(problem, &start, PgsSettings::default(), 300);
                assert_eq!(reference, lanes);
            }
            let mut solver = PgsSolver::new();
            solver.prepare(problem, &vec![Impulse::ZERO; problem.len()]);
            batched += solver.batches.len();
        }
        assert!(batched > 0, "no batch was formed");
    }

    #[test]
    fn domain_plan_is_bit_identical_for_one_to_four_threads_and_up_to_eight_domains() {
        // Every norm, 1 to 8 domains (8 give all four threads a domain of each phase), a
        // start with load on every point; the residuals of every iteration are compared too.
        for problem in pile_and_pyramid() {
            let start = loaded_start(&problem);
            for stop in tight_stops() {
                let norm = stop.norm;
                for domains in [1, 2, 3, 5, 8] {
                    let runs: Vec<_> = (1..=4)
                        .map(|threads| {
                            let settings = PgsSettings {
                                threads,
                                parallel_min_points: 0,
                                domains,
                                ..PgsSettings::default()
                            };
                            solve_bits_with(&problem, &start, settings, &stop)
                        })
                        .collect();
                    assert!(runs[0].0.2 > 1, "ran {} iterations", runs[0].0.2);
                    for (k, r) in runs.iter().enumerate().skip(1) {
                        assert!(
                            r == &runs[0],
                            "{norm:?}, {domains} domains: {} threads differ from 1",
                            k + 1
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn domain_plan_gives_the_same_bits_on_one_to_five_real_threads() {
        // 8 domains of the 100-body pile on up to five threads (more threads than the 4 even
        // domains work on none).
        let settings = PgsSettings {
            parallel_min_points: 0,
            ..PgsSettings::default()
        };
        same_bits_on_one_to_five_threads(settings, |solver, threads, stop, report| {
            // The parts built on the same threads as the sweep.
            let d = &mut solver.domains;
            d.build(
                8,
                threads,
                &solver.manifolds,
                &solver.rows,
                &solver.vel,
                solver.settings,
            );
            let run = d.solve(threads, solver.arch, stop, report);
            d.write_back(&mut solver.rows, &mut solver.vel);
            run
        });
    }

    #[test]
    fn domain_plan_reaches_the_unchunked_sweeps_accuracy() {
        // Another Gauss-Seidel order, the same problem: at a tight tolerance both stop at a
        // natural residual of the same order, and the velocities agree to that order.
        for problem in pile_and_pyramid() {
            let stop = SolverSettings {
                tolerance: 1e-9,
                max_iterations: 20_000,
                ..SolverSettings::default()
            };
            let solve = |settings: PgsSettings| {
                let mut solver = PgsSolver::with_settings(settings);
                let mut imp = vec![Impulse::ZERO; problem.len()];
                let mut vel = vec![Velocity::default(); problem.bodies.len()];
                let mut report = SolveReport::default();
                solver
                    .solve(&problem, &stop, &mut imp, &mut vel, &mut report)
                    .unwrap();
                (vel, report)
            };
            let (plain, plain_report) = solve(PgsSettings::default());
            let (split, split_report) = solve(PgsSettings {
                parallel_min_points: 0,
                threads: 2,
                ..PgsSettings::default()
            });
            assert!(plain_report.converged && split_report.converged);
            assert!(
                split_report.natural_residual < 1e-6,
                "domain plan stopped at {:e}",
                split_report.natural_residual
            );
            let scale = plain
                .iter()
                .map(|v| v.linear.norm().max(v.angular.abs()))
                .fold(1.0, Real::max);
            for (a, b) in plain.iter().zip(&split) {
                let d = (a.linear - b.linear)
                    .norm()
                    .max((a.angular - b.angular).abs());
                assert!(d < 1e-5 * scale, "velocities differ by {d:e}");
            }
        }
    }

    #[test]
    fn domains_share_movable_bodies_only_with_their_neighbours() {
        // Every manifold in exactly one domain, every row once; a movable body moved by one domain
        // or by two neighbouring ones (then it is a seam body, linked in both), so two domains
        // of one parity never move the same body.
        let problem = pile_problem();
        let mut solver = PgsSolver::with_settings(PgsSettings {
            parallel_min_points: 0,
            ..PgsSettings::default()
        });
        solver.prepare(&problem, &vec![Impulse::ZERO; problem.len()]);
        for n in 1..=9 {
            let d = &mut solver.domains;
            d.build(
                n,
                n % 3 + 1,
                &solver.manifolds,
                &solver.rows,
                &solver.vel,
                solver.settings,
            );
            let manifolds: usize = d.parts.iter().map(|p| p.manifolds.len()).sum();
            assert_eq!(manifolds, solver.manifolds.len(), "{n} domains");
            let mut rows: Vec<u32> = d.rows_of.iter().flatten().copied().collect();
            rows.sort_unstable();
            assert_eq!(rows, (0..problem.len() as u32).collect::<Vec<_>>());
            let mut movers = vec![Vec::new(); solver.vel.len()];
            for (p, part) in d.parts.iter().enumerate() {
                for m in &part.manifolds {
                    for (b, moves) in [(m.a, movable(m.ma, m.ia)), (m.b, movable(m.mb, m.ib))] {
                        let body = d.partition.bodies_of[p][b as usize] as usize;
                        if moves && !movers[body].contains(&p) {
                            movers[body].push(p);
                        }
                    }
                }
            }
            let mut seams = Vec::new();
            for (body, domains) in movers.iter().enumerate() {
                match domains[..] {
                    [] | [_] => {}
                    [p, q] => {
                        assert_eq!(p.abs_diff(q), 1, "body {body} in domains {p} and {q}");
                        seams.push(body as u32);
                    }
                    _ => panic!("body {body} moved by domains {domains:?}"),
                }
            }
            assert_eq!(d.partition.shared, seams, "{n} domains");
            // Each domain links exactly its seam bodies to their shared values.
            for (p, range) in d.partition.link_ranges.iter().enumerate() {
                let linked: Vec<u32> = d.partition.links[range.clone()]
                    .iter()
                    .map(|&(s, k)| {
                        let body = d.partition.bodies_of[p][s as usize];
                        assert_eq!(body, d.partition.shared[k as usize]);
                        body
                    })
                    .collect();
                let own: Vec<u32> = seams
                    .iter()
                    .copied()
                    .filter(|&b| movers[b as usize].contains(&p))
                    .collect();
                assert_eq!(linked, own, "domain {p} of {n}");
            }
            let used = d.parts.iter().filter(|p| !p.manifolds.is_empty()).count();
            assert_eq!(
                used, n,
                "{n} domains of a 100-body pile: {used} hold manifolds"
            );
            assert_eq!(seams.is_empty(), n == 1, "{n} domains");
        }
    }
}
