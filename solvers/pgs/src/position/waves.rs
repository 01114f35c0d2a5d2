//! An island's points in waves of independent points, corrected four at a time with the bits
//! of the point-by-point loop: the plain plan's pass, each domain of the domain plan
//! ([`super::domains`]) and each thread of the ordered plan ([`super::ordered`], the waves of
//! the whole island, its seam points one at a time).
//!
//! A correction reads and writes only its two bodies' poses, so two points that share no
//! movable body can be corrected in either order with the same result. Each point gets a
//! wave: one more than the latest wave of a point before it (in problem order) that moves one
//! of its movable bodies. The points of a wave share no movable body, and every body sees the
//! corrections of the problem order in that order, so visiting the waves in turn gives every
//! point the poses the problem order gives it: the same bits. Within a wave the points go
//! four to a batch, their arithmetic one lane each (the same operations in the same order as
//! [`correct_point`], no fused multiply-add), which the compiler vectorises for the
//! instruction set detected at run time; the rest of a wave, and the points re-measured as
//! circles ([`PosRow::remeasure`]), are corrected one at a time.
//!
//! Immovable bodies (a wall) are read, never written: a correction leaves their poses as they
//! are, since their inverse masses are zero, except that `-0.0 - 0.0 · p` may turn a negative
//! zero into a positive one. An island with a negative zero in an immovable body's pose is
//! not planned in waves ([`Waves::build`] returns `false`).

use deepcontact_core::PositionSettings;
use deepcontact_core::math::{Pose, Real};

use crate::position::{CachedRotations, PassMeasures, PosRow, correct_point};

/// Lanes of a batch.
const LANES: usize = 4;

/// Four points of one wave laid out lane by lane ([`PosRow`]'s fields, and the constant part
/// of the separation's estimate computed once).
#[derive(Debug, Clone, Copy, Default)]
struct Batch {
    a: [u32; LANES],
    b: [u32; LANES],
    /// Whether each body may be written (it can move).
    a_moves: [bool; LANES],
    b_moves: [bool; LANES],
    ra0: [[Real; LANES]; 2],
    rb0: [[Real; LANES]; 2],
    normal: [[Real; LANES]; 2],
    separation: [Real; LANES],
    /// `(cB0 + rB0) − cA0 − rA0`, as [`correct_point`] groups it.
    offset: [[Real; LANES]; 2],
    ta0: [Real; LANES],
    tb0: [Real; LANES],
    ma: [Real; LANES],
    ia: [Real; LANES],
    mb: [Real; LANES],
    ib: [Real; LANES],
}

impl Batch {
    /// The batch of the four `rows`.
    fn of(rows: [&PosRow; LANES]) -> Self {
        let mut b = Batch::default();
        for (l, row) in rows.into_iter().enumerate() {
            let [(a, a_moves), (bb, b_moves)] = row.ends();
            (b.a[l], b.b[l], b.a_moves[l], b.b_moves[l]) = (a, bb, a_moves, b_moves);
            (b.ra0[0][l], b.ra0[1][l]) = (row.ra0.x, row.ra0.y);
            (b.rb0[0][l], b.rb0[1][l]) = (row.rb0.x, row.rb0.y);
            (b.normal[0][l], b.normal[1][l]) = (row.normal.x, row.normal.y);
            b.separation[l] = row.separation;
            let offset = row.cb0 + row.rb0 - row.ca0 - row.ra0;
            (b.offset[0][l], b.offset[1][l]) = (offset.x, offset.y);
            (b.ta0[l], b.tb0[l]) = (row.ta0, row.tb0);
            (b.ma[l], b.ia[l], b.mb[l], b.ib[l]) = (row.ma, row.ia, row.mb, row.ib);
        }
        b
    }
}

/// One wave: its batches, then its points corrected one at a time.
#[derive(Debug, Clone, Copy, Default)]
struct Wave {
    /// Its range in [`Waves::batches`].
    batches: (u32, u32),
    /// Its range in [`Waves::singles`].
    singles: (u32, u32),
}

/// The points of an island in waves ([module docs](self)).
#[derive(Debug, Clone, Default)]
pub(crate) struct Waves {
    batches: Vec<Batch>,
    /// Indices of the rows corrected one at a time, wave by wave.
    singles: Vec<u32>,
    waves: Vec<Wave>,
    /// The instruction set the batches are compiled for, detected once a build.
    arch: pulp::Arch,
    /// Scratch of the build: each body's latest wave and each point's wave ([`levels`]),
    /// and the points sorted by wave.
    latest: Vec<u32>,
    wave_of: Vec<u32>,
    by_wave: Vec<u32>,
    starts: Vec<u32>,
}

/// Each point's wave (from 1) into `wave_of`, for `rows` in problem order on `poses`
/// (`latest`: scratch); whether no immovable body's pose holds a negative zero (else the
/// waves must not be used: [module docs](self)).
pub(crate) fn levels(
    rows: &[PosRow],
    poses: &[Pose],
    latest: &mut Vec<u32>,
    wave_of: &mut Vec<u32>,
) -> bool {
    latest.clear();
    latest.resize(poses.len(), 0);
    wave_of.clear();
    let mut plain = true;
    for row in rows {
        let mut wave = 1;
        for (body, moves) in row.ends() {
            if moves {
                wave = wave.max(latest[body as usize] + 1);
            } else {
                let p = &poses[body as usize];
                plain &= ![p.position.x, p.position.y, p.angle]
                    .iter()
                    .any(|v| *v == 0.0 && v.is_sign_negative());
            }
        }
        for (body, moves) in row.ends() {
            if moves {
                latest[body as usize] = wave;
            }
        }
        wave_of.push(wave);
    }
    plain
}

impl Waves {
    /// Plans all of `rows` (an island's points in problem order) on `poses`, the circles
    /// re-measured one at a time; `false` (nothing planned) where an immovable body's pose
    /// holds a negative zero.
    pub(crate) fn build(&mut self, rows: &[PosRow], poses: &[Pose]) -> bool {
        let (mut latest, mut wave_of) = (
            std::mem::take(&mut self.latest),
            std::mem::take(&mut self.wave_of),
        );
        let planned = levels(rows, poses, &mut latest, &mut wave_of);
        if planned {
            self.group(rows, &wave_of, 0..rows.len() as u32, |k| {
                rows[k as usize].remeasure
            });
        }
        (self.latest, self.wave_of) = (latest, wave_of);
        planned
    }

    /// Plans `points` (indices into `rows`, in problem order) by their waves `wave_of`
    /// ([`levels`] over all of `rows`): each wave's points four to a batch, those `single`
    /// picks and the rest of a wave one at a time.
    pub(crate) fn group(
        &mut self,
        rows: &[PosRow],
        wave_of: &[u32],
        points: impl Iterator<Item = u32> + Clone,
        single: impl Fn(u32) -> bool,
    ) {
        self.arch = pulp::Arch::new();
        self.batches.clear();
        self.singles.clear();
        self.waves.clear();
        // The points by wave, in problem order within one (a counting sort); waves without
        // points of this plan are left out.
        let count = points
            .clone()
            .map(|k| wave_of[k as usize])
            .max()
            .unwrap_or(0) as usize;
        self.starts.clear();
        self.starts.resize(count + 2, 0);
        for k in points.clone() {
            self.starts[wave_of[k as usize] as usize + 1] += 1;
        }
        for w in 1..self.starts.len() {
            self.starts[w] += self.starts[w - 1];
        }
        self.by_wave.clear();
        self.by_wave.resize(self.starts[count + 1] as usize, 0);
        for k in points {
            let at = &mut self.starts[wave_of[k as usize] as usize];
            self.by_wave[*at as usize] = k;
            *at += 1;
        }
        // After the sort, `starts[w]` is the end of wave `w`, so wave `w` spans
        // `starts[w - 1] .. starts[w]`.
        for w in 1..=count {
            let (from, to) = (self.starts[w - 1] as usize, self.starts[w] as usize);
            if from == to {
                continue;
            }
            let batches = self.batches.len() as u32;
            let singles = self.singles.len() as u32;
            let (mut lanes, mut filled) = ([0_u32; LANES], 0);
            for &k in &self.by_wave[from..to] {
                if single(k) {
                    self.singles.push(k);
                } else {
                    lanes[filled] = k;
                    filled += 1;
                    if filled == LANES {
                        self.batches
                            .push(Batch::of(lanes.map(|k| &rows[k as usize])));
                        filled = 0;
                    }
                }
            }
            // The wave's last points, fewer than a batch, one at a time (the points of a wave
            // may go in any order).
            self.singles.extend_from_slice(&lanes[..filled]);
            self.waves.push(Wave {
                batches: (batches, self.batches.len() as u32),
                singles: (singles, self.singles.len() as u32),
            });
        }
    }

    /// The points planned in batches (tests read it to know the batches ran).
    #[cfg(test)]
    pub(crate) fn batched(&self) -> usize {
        LANES * self.batches.len()
    }

    /// One iteration of the pass over `rows` (those [`build`](Self::build) planned), on the
    /// instruction set detected at run time; its measures.
    pub(crate) fn iterate(
        &self,
        rows: &[PosRow],
        settings: &PositionSettings,
        poses: &mut CachedRotations<'_>,
    ) -> PassMeasures {
        let one = |k: u32, poses: &mut CachedRotations<'_>| {
            Some(correct_point(&rows[k as usize], settings, poses, true))
        };
        let m = self.iterate_with(settings, poses, one);
        m.unwrap_or_default()
    }

    /// One iteration of the planned points: the batches of a wave here, its other points by
    /// `single` (given the point's index into the rows; `None` ends the iteration early and
    /// this returns `None`).
    pub(crate) fn iterate_with<F>(
        &self,
        settings: &PositionSettings,
        poses: &mut CachedRotations<'_>,
        single: F,
    ) -> Option<PassMeasures>
    where
        F: FnMut(u32, &mut CachedRotations<'_>) -> Option<PassMeasures>,
    {
        self.arch.dispatch(Iterate {
            waves: self,
            settings,
            poses,
            single,
        })
    }
}

/// [`Waves::iterate_with`] as [`pulp::WithSimd`] wants it.
struct Iterate<'a, 'b, 'c, F> {
    waves: &'a Waves,
    settings: &'a PositionSettings,
    poses: &'b mut CachedRotations<'c>,
    single: F,
}

impl<F> pulp::WithSimd for Iterate<'_, '_, '_, F>
where
    F: FnMut(u32, &mut CachedRotations<'_>) -> Option<PassMeasures>,
{
    type Output = Option<PassMeasures>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Option<PassMeasures> {
        let Iterate {
            waves,
            settings,
            poses,
            mut single,
        } = self;
        let mut m = PassMeasures::default();
        for wave in &waves.waves {
            for batch in &waves.batches[wave.batches.0 as usize..wave.batches.1 as usize] {
                correct_batch(batch, settings, poses, &mut m);
            }
            for &k in &waves.singles[wave.singles.0 as usize..wave.singles.1 as usize] {
                m.merge(&single(k, poses)?);
            }
        }
        Some(m)
    }
}

/// [`correct_point`] (the fixed-normal case) on the four points of `batch`, lane by lane; the
/// points share no movable body.
#[inline(always)]
fn correct_batch(
    batch: &Batch,
    settings: &PositionSettings,
    poses: &mut CachedRotations<'_>,
    m: &mut PassMeasures,
) {
    let mut ca = [[0.0; LANES]; 2];
    let mut cb = [[0.0; LANES]; 2];
    let (mut ta, mut tb) = ([0.0; LANES], [0.0; LANES]);
    for l in 0..LANES {
        let (pa, pb) = (
            poses.poses[batch.a[l] as usize],
            poses.poses[batch.b[l] as usize],
        );
        (ca[0][l], ca[1][l], ta[l]) = (pa.position.x, pa.position.y, pa.angle);
        (cb[0][l], cb[1][l], tb[l]) = (pb.position.x, pb.position.y, pb.angle);
    }
    let (mut sa, mut ka, mut sb, mut kb) = ([0.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
    for l in 0..LANES {
        (sa[l], ka[l]) = poses.sin_cos(batch.a[l] as usize, ta[l] - batch.ta0[l]);
        (sb[l], kb[l]) = poses.sin_cos(batch.b[l] as usize, tb[l] - batch.tb0[l]);
    }
    let mut sep = [0.0; LANES];
    let mut c = [0.0; LANES];
    let mut impulse = [0.0; LANES];
    let mut new_a = [[0.0; LANES]; 3];
    let mut new_b = [[0.0; LANES]; 3];
    for l in 0..LANES {
        let (r0x, r0y) = (batch.ra0[0][l], batch.ra0[1][l]);
        let (rax, ray) = (ka[l] * r0x - sa[l] * r0y, sa[l] * r0x + ka[l] * r0y);
        let (r0x, r0y) = (batch.rb0[0][l], batch.rb0[1][l]);
        let (rbx, rby) = (kb[l] * r0x - sb[l] * r0y, sb[l] * r0x + kb[l] * r0y);
        let dx = cb[0][l] + rbx - ca[0][l] - rax - batch.offset[0][l];
        let dy = cb[1][l] + rby - ca[1][l] - ray - batch.offset[1][l];
        let (nx, ny) = (batch.normal[0][l], batch.normal[1][l]);
        sep[l] = batch.separation[l] + (nx * dx + ny * dy);
        c[l] = (settings.baumgarte * (sep[l] + settings.linear_slop))
            .clamp(-settings.max_linear_correction, 0.0);
        let (rna, rnb) = (rax * ny - ray * nx, rbx * ny - rby * nx);
        let k = batch.ma[l] + batch.mb[l] + batch.ia[l] * rna * rna + batch.ib[l] * rnb * rnb;
        impulse[l] = if k > 0.0 { -c[l] / k } else { 0.0 };
        let (px, py) = (impulse[l] * nx, impulse[l] * ny);
        new_a[0][l] = ca[0][l] - batch.ma[l] * px;
        new_a[1][l] = ca[1][l] - batch.ma[l] * py;
        new_a[2][l] = ta[l] - batch.ia[l] * (rax * py - ray * px);
        new_b[0][l] = cb[0][l] + batch.mb[l] * px;
        new_b[1][l] = cb[1][l] + batch.mb[l] * py;
        new_b[2][l] = tb[l] + batch.ib[l] * (rbx * py - rby * px);
    }
    for l in 0..LANES {
        if batch.a_moves[l] {
            let p = &mut poses.poses[batch.a[l] as usize];
            (p.position.x, p.position.y, p.angle) = (new_a[0][l], new_a[1][l], new_a[2][l]);
        }
        if batch.b_moves[l] {
            let p = &mut poses.poses[batch.b[l] as usize];
            (p.position.x, p.position.y, p.angle) = (new_b[0][l], new_b[1][l], new_b[2][l]);
        }
        m.merge(&PassMeasures {
            min_separation: sep[l],
            max_correction: c[l].abs(),
            max_impulse: impulse[l].abs(),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::position::Rotation;
    use crate::position::tests::island;
    use deepcontact_core::{CircleContact, ContactProblem, scene};

    fn bits(poses: &[Pose], m: &PassMeasures) -> Vec<u64> {
        poses
            .iter()
            .flat_map(|p| [p.position.x, p.position.y, p.angle])
            .chain([m.min_separation, m.max_correction, m.max_impulse])
            .map(f64::to_bits)
            .collect()
    }

    /// Iterations of the point-by-point loop and of the waves (on the detected instruction set
    /// and on the baseline) from the same poses, the bits of the poses and measures compared
    /// after each; the share of the points in batches.
    fn compare(problem: &ContactProblem, start: &[Pose], settings: &PositionSettings) -> f64 {
        let rows: Vec<PosRow> = (0..problem.points.len())
            .map(|k| PosRow::new(problem, k, settings))
            .collect();
        let mut waves = Waves::default();
        assert!(waves.build(&rows, start), "planned");
        let mut baseline_waves = waves.clone();
        baseline_waves.arch = pulp::Arch::Scalar;
        let (mut plain, mut planned, mut baseline) =
            (start.to_vec(), start.to_vec(), start.to_vec());
        let mut rotations = [
            vec![Rotation::default(); start.len()],
            vec![Rotation::default(); start.len()],
            vec![Rotation::default(); start.len()],
        ];
        let mut moved = false;
        for it in 0..40 {
            let mut one = CachedRotations {
                poses: &mut plain,
                rotations: &mut rotations[0],
            };
            let mut m = PassMeasures::default();
            for row in &rows {
                m.merge(&correct_point(row, settings, &mut one, false));
            }
            let mut four = CachedRotations {
                poses: &mut planned,
                rotations: &mut rotations[1],
            };
            let w = waves.iterate(&rows, settings, &mut four);
            assert_eq!(bits(&plain, &m), bits(&planned, &w), "iteration {it}");
            // The same waves compiled for the baseline instruction set (no AVX2).
            let mut scalar = CachedRotations {
                poses: &mut baseline,
                rotations: &mut rotations[2],
            };
            let one = |k: u32, poses: &mut CachedRotations<'_>| {
                Some(correct_point(&rows[k as usize], settings, poses, true))
            };
            let b = baseline_waves
                .iterate_with(settings, &mut scalar, one)
                .unwrap();
            assert_eq!(
                bits(&plain, &m),
                bits(&baseline, &b),
                "baseline, iteration {it}"
            );
            moved |= m.max_impulse > 0.0;
        }
        assert!(moved, "no correction ran");
        waves.batched() as f64 / rows.len() as f64
    }

    #[test]
    fn waves_give_the_bits_of_the_point_by_point_pass_on_circles_and_boxes() {
        let fixed = PositionSettings::default();
        let (pile, start) = island(scene::pile(12345, 100).unwrap(), 130);
        let batched = compare(&pile, &start, &fixed);
        assert!(batched > 0.5, "{batched} of the pile's points in batches");
        // Box faces: two points of a manifold on the same bodies (two waves), rotations.
        let (pyramid, start) = island(scene::pyramid(10), 60);
        let batched = compare(&pyramid, &start, &fixed);
        assert!(
            batched > 0.05,
            "{batched} of the pyramid's points in batches"
        );
        // Circles re-measured go one at a time, between the batches of their wave.
        let remeasured = PositionSettings {
            circle_contact: CircleContact::Remeasured,
            ..fixed
        };
        let (pile, start) = island(scene::pile(12345, 100).unwrap(), 130);
        compare(&pile, &start, &remeasured);
    }

    #[test]
    fn a_negative_zero_on_a_wall_is_not_planned_in_waves() {
        // Writing a wall would turn its -0.0 into +0.0 where the point-by-point loop does, at
        // another time; the pass keeps that loop there.
        let (pile, mut start) = island(scene::pile(12345, 100).unwrap(), 130);
        let rows: Vec<PosRow> = (0..pile.points.len())
            .map(|k| PosRow::new(&pile, k, &PositionSettings::default()))
            .collect();
        let wall = rows
            .iter()
            .flat_map(PosRow::ends)
            .find(|&(_, moves)| !moves)
            .expect("a point on a wall")
            .0 as usize;
        let mut waves = Waves::default();
        assert!(waves.build(&rows, &start));
        start[wall].angle = -0.0;
        assert!(!waves.build(&rows, &start));
    }
}
