//! The sweep plan of a coloured solve: greedy colouring, each colour's manifolds in
//! Z-order for the chunked plan, and the single-point manifolds packed into batches.

use deepcontact_core::ContactProblem;

use super::{Batch, LANES, Manifold, PgsSolver, Segment, Vel, movable};

impl PgsSolver {
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
        space: Option<(&crate::threads::z_order::ZOrder, &ContactProblem)>,
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
        z: &crate::threads::z_order::ZOrder,
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
}
