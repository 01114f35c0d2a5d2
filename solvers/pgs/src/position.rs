//! The position pass: Box2D v2.4's non-linear Gauss-Seidel on the contact separations.

mod chunked;
mod domains;
mod ordered;
mod waves;

use deepcontact_core::math::{Pose, Real, Vector, cross, rotate, rotate_sin_cos, sin_cos};
use deepcontact_core::{
    CircleContact, ContactProblem, CoreError, PositionReport, PositionSettings, PositionSolver,
    ProblemBody,
};

/// Options of the position pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PgsPositionSettings {
    /// Threads that share the pass of one island (default 1; 0 counts as 1; no more than the
    /// cores the process may use are started): in the domain or coloured plan from
    /// [`parallel_min_points`](Self::parallel_min_points), in problem order from 256 points
    /// below it (the ordered plan: each thread corrects the points of a slab of bodies,
    /// and a body two threads move waits for the corrections before it in problem order). The
    /// result is bit-identical for every thread count.
    pub threads: usize,
    /// Islands with at least this many contact points run the domain plan or the coloured
    /// plan ([`domains`](Self::domains); default 2048), bodies renumbered in Z-order. Smaller
    /// islands visit their points in problem order, as Box2D does. The orders give different
    /// (equally valid) Gauss-Seidel results.
    pub parallel_min_points: usize,
    /// The most domains of the domain plan (default 16; more than 63 count as 63): the island's
    /// movable bodies cut into bands of a breadth-first walk of their contacts (as many as
    /// [`domain_points`](Self::domain_points) says, up to this), holding about as many points each,
    /// as the velocity sweep's ([`PgsSettings::domains`](crate::PgsSettings::domains)). Each
    /// domain's points are visited in problem order by one thread on poses of its own; the even
    /// domains side by side, then the odd ones. Up to half the domains, rounded up, work on an
    /// island. `0`: the coloured plan instead — points coloured greedily so that no two of a colour
    /// move the same body, visited colour by colour, each colour's points in fixed chunks that
    /// threads share through atomics (which scales worse).
    pub domains: usize,
    /// Contact points a domain holds at least (default 1 100; 0: always
    /// [`domains`](Self::domains)), as the velocity sweep's
    /// ([`PgsSettings::domain_points`](crate::PgsSettings::domain_points)): `n / domain_points`
    /// domains for an island of `n` points, at least 4 and at most `domains`.
    pub domain_points: usize,
}

impl Default for PgsPositionSettings {
    fn default() -> Self {
        Self {
            threads: 1,
            parallel_min_points: 2048,
            domains: 16,
            domain_points: crate::DOMAIN_POINTS,
        }
    }
}

impl PgsPositionSettings {
    /// The threads a pass with these settings shares one island of `points` contact points
    /// over: from [`parallel_min_points`](Self::parallel_min_points) those of the domain plan
    /// (at most half the domains, rounded up) or of the shared colours, from 256 points those of
    /// the ordered plan, capped at this process's cores; else 1.
    pub fn threads_for(&self, points: usize) -> usize {
        let threads = crate::threads::sync::effective_threads(self.threads);
        if points >= self.parallel_min_points {
            if self.domains > 0 {
                crate::threads::domain_sweep::useful_threads(threads, self.domains_for(points))
            } else {
                threads
            }
        } else if points >= ordered::ORDERED_MIN_POINTS {
            threads
        } else {
            1
        }
    }

    /// The domains of an island of `points` contact points in the domain plan
    /// ([`domain_points`](Self::domain_points)).
    pub(crate) fn domains_for(&self, points: usize) -> usize {
        crate::threads::partition::domains_for(points, self.domains, self.domain_points)
    }
}

/// Non-linear Gauss-Seidel position correction (`b2ContactSolver::SolvePositionConstraints`).
///
/// The separation of a point at the current poses is estimated from its separation when
/// the contacts were computed plus the relative displacement of its two anchors along the
/// (fixed) normal, the anchors rotating with their bodies (as Box2D v3's relax step does);
/// circle contacts are re-measured from the centres instead under
/// [`CircleContact::Remeasured`] (Box2D v2.3).
///
/// Points that share no movable body are corrected four at a time where the instruction set
/// allows (waves of independent points, `position/waves.rs`), with the bits of visiting them
/// one by one in the plan's order.
#[derive(Debug, Clone, Default)]
pub struct PgsPositionSolver {
    /// Options.
    pub settings: PgsPositionSettings,
    /// The points laid out for the pass, in the order it visits them.
    rows: Vec<PosRow>,
    /// The coloured plan: point indices colour by colour, and each colour's range in it.
    plan: crate::position::chunked::Plan,
    /// For the coloured plan: the bodies renumbered in Z-order of their positions, and the
    /// poses in that order.
    bodies: crate::threads::z_order::Renumbering,
    renumbered: Vec<Pose>,
    /// The domain plan's parts ([`PgsPositionSettings::domains`]).
    domains: crate::position::domains::PositionDomains,
    /// The plain plan's rotation of each body, kept across the pass's iterations.
    rotations: Vec<Rotation>,
    /// The plain plan's points in waves, four at a time ([`waves`]).
    waves: crate::position::waves::Waves,
    /// The most threads one island's pass has run on ([`Self::threads_used`]).
    threads_used: usize,
}

impl PgsPositionSolver {
    /// A new position solver.
    pub fn new() -> Self {
        Self::default()
    }

    /// A position solver with the given options.
    pub fn with_settings(settings: PgsPositionSettings) -> Self {
        Self {
            settings,
            ..Self::default()
        }
    }

    /// The most threads that one island's pass has run on with this solver since it was made
    /// (0 before its first pass; 1 when every pass ran on the calling thread): no more than
    /// [`PgsPositionSettings::threads`], the cores the process may use, and what the plan
    /// offers side by side. Tests read it to know that the plan they ask for is the one that
    /// ran; it never changes a result.
    pub fn threads_used(&self) -> usize {
        self.threads_used
    }

    /// A position solver whose large islands run on `threads` threads.
    pub fn with_threads(threads: usize) -> Self {
        Self::with_settings(PgsPositionSettings {
            threads,
            ..PgsPositionSettings::default()
        })
    }
}

/// Body poses as the pass reads and writes them: a plain slice on one thread, shared atomic
/// cells when threads split a colour ([`crate::position::chunked`]).
pub(crate) trait Poses {
    /// Pose of body `i`.
    fn get(&self, i: usize) -> Pose;
    /// Sets the pose of body `i`.
    fn set(&mut self, i: usize, pose: Pose);
    /// `v` rotated by `angle`, an angle of body `i`'s ([`rotate`]; a pose store may keep the
    /// last sine and cosine of each body, [`CachedRotations`]).
    #[inline(always)]
    fn rotate(&mut self, _i: usize, v: &Vector, angle: Real) -> Vector {
        rotate(v, angle)
    }
}

/// Per body, the angle (as bits) of the last rotation the pass computed for it, and its sine
/// and cosine. A body's angle only changes when a correction moves it, and most points of a
/// resting pile sit inside the slop (no correction), so a row often finds its bodies'
/// rotations here instead of calling `sin_cos` again. Keyed by the exact bits of the angle,
/// so the result is the same bits.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Rotation {
    angle: u64,
    sin: Real,
    cos: Real,
}

impl Default for Rotation {
    /// The rotation by `+0.0`: `sin_cos(0) = (0, 1)` exactly.
    fn default() -> Self {
        Self {
            angle: 0.0_f64.to_bits(),
            sin: 0.0,
            cos: 1.0,
        }
    }
}

/// Poses with a [`Rotation`] cache per body.
pub(crate) struct CachedRotations<'a> {
    pub(crate) poses: &'a mut [Pose],
    pub(crate) rotations: &'a mut [Rotation],
}

impl Poses for CachedRotations<'_> {
    #[inline(always)]
    fn get(&self, i: usize) -> Pose {
        self.poses[i]
    }

    #[inline(always)]
    fn set(&mut self, i: usize, pose: Pose) {
        self.poses[i] = pose;
    }

    #[inline(always)]
    fn rotate(&mut self, i: usize, v: &Vector, angle: Real) -> Vector {
        let (s, c) = self.sin_cos(i, angle);
        rotate_sin_cos(v, s, c)
    }
}

impl CachedRotations<'_> {
    /// `sin_cos(angle)` for a rotation of body `i`, from its cache when the angle's bits are
    /// those of its last rotation.
    #[inline(always)]
    pub(crate) fn sin_cos(&mut self, i: usize, angle: Real) -> (Real, Real) {
        let r = &mut self.rotations[i];
        if r.angle != angle.to_bits() {
            (r.sin, r.cos) = sin_cos(angle);
            r.angle = angle.to_bits();
        }
        (r.sin, r.cos)
    }
}

impl Poses for [Pose] {
    #[inline(always)]
    fn get(&self, i: usize) -> Pose {
        self[i]
    }

    #[inline(always)]
    fn set(&mut self, i: usize, pose: Pose) {
        self[i] = pose;
    }
}

/// One contact point laid out for the pass: its bodies' inverse masses and poses at the time
/// the contacts were computed copied in, so that a sweep reads one row per point in order.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PosRow {
    a: u32,
    b: u32,
    ra0: Vector,
    rb0: Vector,
    normal: Vector,
    separation: Real,
    ma: Real,
    ia: Real,
    mb: Real,
    ib: Real,
    ca0: Vector,
    ta0: Real,
    cb0: Vector,
    tb0: Real,
    /// Re-measured as Box2D v2.3 does ([`CircleContact::Remeasured`] on a circle contact).
    remeasure: bool,
}

impl PosRow {
    /// Point `k` of `problem` under `settings`.
    pub(crate) fn new(problem: &ContactProblem, k: usize, settings: &PositionSettings) -> Self {
        let p = &problem.points[k];
        let (a0, b0) = (
            &problem.bodies[p.body_a as usize],
            &problem.bodies[p.body_b as usize],
        );
        Self {
            a: p.body_a,
            b: p.body_b,
            ra0: p.r_a,
            rb0: p.r_b,
            normal: p.normal,
            separation: p.separation,
            ma: a0.inv_mass,
            ia: a0.inv_inertia,
            mb: b0.inv_mass,
            ib: b0.inv_inertia,
            ca0: a0.position,
            ta0: a0.angle,
            cb0: b0.position,
            tb0: b0.angle,
            remeasure: settings.circle_contact == CircleContact::Remeasured
                && on_centre_line(&p.r_a, &p.normal, a0)
                && on_centre_line(&p.r_b, &p.normal, b0),
        }
    }
}

impl PosRow {
    /// The row's two bodies and whether each can move.
    pub(crate) fn ends(&self) -> crate::threads::partition::Ends {
        [
            (self.a, !(self.ma == 0.0 && self.ia == 0.0)),
            (self.b, !(self.mb == 0.0 && self.ib == 0.0)),
        ]
    }

    /// The row with its bodies renumbered by `slot` (new index of each old one).
    pub(crate) fn renumbered(&self, slot: &[u32]) -> Self {
        Self {
            a: slot[self.a as usize],
            b: slot[self.b as usize],
            ..*self
        }
    }
}

/// Corrects one point at the current `poses` and returns its measures; with
/// `skip_immovable`, bodies that cannot move are not written (so threads never write a
/// shared wall).
#[inline(always)]
pub(crate) fn correct_point<P: Poses + ?Sized>(
    row: &PosRow,
    settings: &PositionSettings,
    poses: &mut P,
    skip_immovable: bool,
) -> PassMeasures {
    let (ia, ib) = (row.a as usize, row.b as usize);
    let (
        Pose {
            position: ca,
            angle: ta,
        },
        Pose {
            position: cb,
            angle: tb,
        },
    ) = (poses.get(ia), poses.get(ib));
    let (a_fixed, b_fixed) = (
        row.ma == 0.0 && row.ia == 0.0,
        row.mb == 0.0 && row.ib == 0.0,
    );
    let (ra, rb, normal, sep) = if !row.remeasure {
        let ra = poses.rotate(ia, &row.ra0, ta - row.ta0);
        let rb = poses.rotate(ib, &row.rb0, tb - row.tb0);
        // s = s0 + n · [(cB + rB) − (cA + rA) − ((cB0 + rB0) − (cA0 + rA0))]
        let d = (cb + rb - ca - ra) - (row.cb0 + row.rb0 - row.ca0 - row.ra0);
        (ra, rb, row.normal, row.separation + row.normal.dot(&d))
    } else if !a_fixed && !b_fixed {
        // Box2D v2.3, two circles: rA + rB = n0 · (cB0 − cA0) − s0; n = d / |d|.
        let radii = row.normal.dot(&(row.cb0 - row.ca0)) - row.separation;
        let d = cb - ca;
        let len = d.norm();
        let n = if len > 1e-12 { d / len } else { row.normal };
        (0.5 * d, -0.5 * d, n, len - radii)
    } else {
        // A circle on an immovable body: the fixed normal, translation only.
        let d = (cb - ca) - (row.cb0 - row.ca0);
        (
            row.ra0,
            row.rb0,
            row.normal,
            row.separation + row.normal.dot(&d),
        )
    };
    // Prevent large corrections and allow slop.
    let c = (settings.baumgarte * (sep + settings.linear_slop))
        .clamp(-settings.max_linear_correction, 0.0);
    let (rna, rnb) = (cross(&ra, &normal), cross(&rb, &normal));
    let k = row.ma + row.mb + row.ia * rna * rna + row.ib * rnb * rnb;
    let impulse = if k > 0.0 { -c / k } else { 0.0 };
    let pv = impulse * normal;
    if !(skip_immovable && a_fixed) {
        poses.set(
            ia,
            Pose::new(ca - row.ma * pv, ta - row.ia * cross(&ra, &pv)),
        );
    }
    if !(skip_immovable && b_fixed) {
        poses.set(
            ib,
            Pose::new(cb + row.mb * pv, tb + row.ib * cross(&rb, &pv)),
        );
    }
    PassMeasures {
        min_separation: sep,
        max_correction: c.abs(),
        max_impulse: impulse.abs(),
    }
}

/// Whether a contact's anchor `r` on body `b` lies on the line of its normal `n` (a circle's
/// anchor), or the body does not rotate. The narrow phase (parry2d) computes in `f32`, so a
/// circle's anchor and normal agree to about 1e-7 of the radius: the test allows 1e-5.
#[inline(always)]
fn on_centre_line(r: &Vector, n: &Vector, b: &ProblemBody) -> bool {
    b.inv_inertia == 0.0 || cross(r, n).abs() <= ON_LINE * r.norm()
}

/// Relative tolerance of [`on_centre_line`].
const ON_LINE: Real = 1e-5;

/// Whether a body cannot be moved by a correction.
#[inline(always)]
pub(crate) fn immovable(b: &ProblemBody) -> bool {
    b.inv_mass == 0.0 && b.inv_inertia == 0.0
}

/// The measures of a pass iteration, or of one point's correction: its separation before
/// the correction, `|C|` and `|impulse|`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PassMeasures {
    pub(crate) min_separation: Real,
    pub(crate) max_correction: Real,
    pub(crate) max_impulse: Real,
}

impl Default for PassMeasures {
    fn default() -> Self {
        Self {
            min_separation: Real::INFINITY,
            max_correction: 0.0,
            max_impulse: 0.0,
        }
    }
}

impl PassMeasures {
    /// Folds another set of measures in (minima and maxima: the order does not matter).
    #[inline(always)]
    pub(crate) fn merge(&mut self, o: &PassMeasures) {
        self.min_separation = self.min_separation.min(o.min_separation);
        self.max_correction = self.max_correction.max(o.max_correction);
        self.max_impulse = self.max_impulse.max(o.max_impulse);
    }

    /// Records iteration `it` (0-based) in `report`; whether the pass may stop.
    pub(crate) fn judge(
        &self,
        it: u32,
        settings: &PositionSettings,
        report: &mut PositionReport,
    ) -> bool {
        report.iterations = it + 1;
        report.min_separation = self.min_separation;
        report.max_correction = self.max_correction;
        let small = if settings.stop_on_impulse {
            self.max_impulse <= settings.tolerance
        } else {
            self.max_correction < settings.tolerance
        };
        small && self.min_separation >= -settings.penetration_factor * settings.linear_slop
    }
}

impl PositionSolver for PgsPositionSolver {
    fn name(&self) -> &str {
        "ngs"
    }

    /// The same settings on one thread: every plan gives the same bits for any thread
    /// count, so a fork corrects an island as this pass would.
    fn fork(&self) -> Option<Box<dyn PositionSolver>> {
        Some(Box::new(Self::with_settings(PgsPositionSettings {
            threads: 1,
            ..self.settings
        })))
    }

    fn threads_for(&self, points: usize) -> usize {
        self.settings.threads_for(points)
    }

    fn solve_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &PositionSettings,
        poses: &mut [Pose],
    ) -> Result<PositionReport, CoreError> {
        settings.validate()?;
        if poses.len() != problem.bodies.len() {
            return Err(CoreError::LengthMismatch {
                what: "poses",
                expected: problem.bodies.len(),
                got: poses.len(),
            });
        }
        let mut report = PositionReport::default();
        if problem.points.is_empty() {
            return Ok(report);
        }
        if problem.points.len() >= self.settings.parallel_min_points {
            self.solve_large(problem, settings, poses, &mut report);
        } else {
            self.solve_in_order(problem, settings, poses, &mut report);
        }
        finite(poses, report)
    }
}

impl PgsPositionSolver {
    /// The pass of an island of [`PgsPositionSettings::parallel_min_points`] points or more:
    /// the domain plan or the coloured plan, on the bodies renumbered in Z-order.
    fn solve_large(
        &mut self,
        problem: &ContactProblem,
        settings: &PositionSettings,
        poses: &mut [Pose],
        report: &mut PositionReport,
    ) {
        // Bodies in Z-order (so that a domain, or a chunk of a colour, is a patch of
        // space whose bodies share cache lines).
        let z = crate::threads::z_order::ZOrder::of(&problem.points);
        self.bodies.build(&z, &problem.bodies);
        let new = &self.bodies.new_index;
        let row = |k: usize| {
            let mut row = PosRow::new(problem, k, settings);
            (row.a, row.b) = (new[row.a as usize], new[row.b as usize]);
            row
        };
        self.rows.clear();
        if self.settings.domains > 0 {
            self.rows.extend((0..problem.points.len()).map(row));
        } else {
            // Points coloured, each colour in Z-order.
            self.plan.build(problem, &z);
            self.rows
                .extend(self.plan.order().iter().map(|&k| row(k as usize)));
        }
        self.renumbered.clear();
        self.renumbered
            .extend(self.bodies.body_of.iter().map(|&b| poses[b as usize]));
        let threads = crate::threads::sync::effective_threads(self.settings.threads);
        if self.settings.domains > 0 {
            self.domains.build(
                self.settings.domains_for(self.rows.len()),
                threads,
                &self.rows,
                &self.renumbered,
            );
            let ran_on = self
                .domains
                .solve(threads, settings, &mut self.renumbered, report);
            self.threads_used = self.threads_used.max(ran_on);
        } else {
            let ran_on = crate::position::chunked::solve(
                &self.rows,
                &self.plan,
                threads,
                settings,
                &mut self.renumbered,
                report,
            );
            self.threads_used = self.threads_used.max(ran_on);
        }
        for (&b, pose) in self.bodies.body_of.iter().zip(&self.renumbered) {
            poses[b as usize] = *pose;
        }
    }

    /// The pass of a smaller island in problem order: the ordered plan on several threads,
    /// else on this thread in waves (or point by point where the waves decline).
    fn solve_in_order(
        &mut self,
        problem: &ContactProblem,
        settings: &PositionSettings,
        poses: &mut [Pose],
        report: &mut PositionReport,
    ) {
        self.rows.clear();
        self.rows
            .extend((0..problem.points.len()).map(|k| PosRow::new(problem, k, settings)));
        let threads = crate::threads::sync::effective_threads(self.settings.threads);
        if threads > 1 && problem.points.len() >= ordered::ORDERED_MIN_POINTS {
            let ran_on = ordered::solve(&self.rows, threads, settings, poses, report);
            self.threads_used = self.threads_used.max(ran_on);
            return;
        }
        self.threads_used = self.threads_used.max(1);
        self.rotations.clear();
        self.rotations.resize(poses.len(), Rotation::default());
        let mut cached = CachedRotations {
            poses: &mut *poses,
            rotations: &mut self.rotations,
        };
        let in_waves = self.waves.build(&self.rows, cached.poses);
        for it in 0..settings.max_iterations {
            let m = if in_waves {
                self.waves.iterate(&self.rows, settings, &mut cached)
            } else {
                let mut m = PassMeasures::default();
                for row in &self.rows {
                    m.merge(&correct_point(row, settings, &mut cached, false));
                }
                m
            };
            if m.judge(it, settings, report) {
                break;
            }
        }
    }
}

/// `report`, or an error if the pass left a non-finite pose.
fn finite(poses: &[Pose], report: PositionReport) -> Result<PositionReport, CoreError> {
    if poses
        .iter()
        .any(|p| !(p.position.x.is_finite() && p.position.y.is_finite() && p.angle.is_finite()))
    {
        return Err(CoreError::Solver {
            solver: "ngs".into(),
            reason: "position pass produced a non-finite pose".into(),
        });
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};

    /// The pile's largest island, and the bodies' poses pushed 2 cm down (deeper contacts).
    pub(crate) fn pile_problem() -> (ContactProblem, Vec<Pose>) {
        island(scene::pile(12345, 100).unwrap(), 130)
    }

    /// The largest island of `scene` after `steps` steps, and its movable bodies' poses pushed
    /// 2 cm down (deeper contacts, so that every pass corrects).
    pub(crate) fn island(scene: scene::Scene, steps: usize) -> (ContactProblem, Vec<Pose>) {
        let mut world = scene.build(WorldSettings::default()).unwrap();
        let (mut s, mut p) = (crate::PgsSolver::new(), PgsPositionSolver::new());
        for _ in 0..steps {
            world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
        }
        let problem = world
            .last_problems()
            .iter()
            .max_by_key(|p| p.len())
            .unwrap()
            .clone();
        let poses = problem
            .bodies
            .iter()
            .map(|b| {
                let drop = if b.inv_mass > 0.0 { 0.02 } else { 0.0 };
                Pose::new(b.position - Vector::new(0.0, drop), b.angle)
            })
            .collect();
        (problem, poses)
    }

    fn pass_bits(
        problem: &ContactProblem,
        start: &[Pose],
        settings: PgsPositionSettings,
    ) -> (Vec<u64>, u32, u64) {
        // One point a chunk, so that a 100-body island has chunks for every thread.
        let mut solver = PgsPositionSolver::with_settings(settings);
        solver.plan.chunk = 1;
        let mut poses = start.to_vec();
        let cap = PositionSettings {
            max_iterations: 60,
            ..PositionSettings::default()
        };
        let report = solver.solve_positions(problem, &cap, &mut poses).unwrap();
        let bits = poses
            .iter()
            .flat_map(|p| [p.position.x, p.position.y, p.angle].map(f64::to_bits))
            .collect();
        (bits, report.iterations, report.min_separation.to_bits())
    }

    #[test]
    fn cached_rotations_give_the_bits_of_a_fresh_sin_cos() {
        // Repeated angles (hits), changed ones, both zeros (different bits: a miss) and a
        // NaN, on two bodies.
        let angles = [0.0, 0.0, -0.0, 0.3, 0.3, 1e-9, -2.5, -2.5, Real::NAN, 0.0];
        let v = Vector::new(0.7, -0.2);
        let mut poses = vec![Pose::new(Vector::zeros(), 0.0); 2];
        let mut rotations = vec![Rotation::default(); 2];
        let mut cached = CachedRotations {
            poses: &mut poses,
            rotations: &mut rotations,
        };
        for (k, &angle) in angles.iter().enumerate() {
            let body = k % 2;
            let got = cached.rotate(body, &v, angle);
            let want = rotate(&v, angle);
            assert_eq!(
                (got.x.to_bits(), got.y.to_bits()),
                (want.x.to_bits(), want.y.to_bits()),
                "angle {angle} on body {body}"
            );
        }
    }

    #[test]
    fn coloured_pass_is_bit_identical_for_one_two_and_four_threads() {
        let (problem, start) = pile_problem();
        let runs: Vec<_> = [1, 2, 4]
            .map(|threads| {
                let settings = PgsPositionSettings {
                    threads,
                    parallel_min_points: 0,
                    domains: 0,
                    domain_points: 0,
                };
                pass_bits(&problem, &start, settings)
            })
            .into();
        assert!(runs[0].1 > 1, "ran {} iterations", runs[0].1);
        assert_eq!(runs[0], runs[1]);
        assert_eq!(runs[0], runs[2]);
        // Both orders are valid Gauss-Seidel passes: from 2 cm of floor overlap they end at
        // the same depth (to 0.1 mm), most of the overlap resolved.
        let in_order = pass_bits(&problem, &start, PgsPositionSettings::default());
        let deepest = problem
            .points
            .iter()
            .map(|p| p.separation)
            .fold(f64::INFINITY, f64::min)
            - 0.02;
        let (coloured, plain) = (f64::from_bits(runs[0].2), f64::from_bits(in_order.2));
        assert!((coloured - plain).abs() < 1e-4, "{coloured} vs {plain}");
        assert!(coloured > deepest + 0.015, "{coloured} from {deepest}");
    }

    #[test]
    fn mid_sized_islands_on_two_threads_step_the_world_as_one_thread() {
        // The 400-body pile until its largest island passes 256 points (the ordered plan) and
        // stays under the domain plan's 2 048; every pose the same bits on 1 and 2 threads.
        let run = |threads: usize| {
            let mut world = scene::pile(12345, 400)
                .unwrap()
                .build(WorldSettings::default())
                .unwrap();
            let mut s = crate::PgsSolver::new();
            let mut p = PgsPositionSolver::with_threads(threads);
            let mut largest = 0;
            for _ in 0..160 {
                world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
                let most = world.last_problems().iter().map(ContactProblem::len).max();
                largest = largest.max(most.unwrap_or(0));
            }
            let bits: Vec<u64> = world
                .bodies()
                .iter()
                .flat_map(|b| [b.position.x, b.position.y, b.angle].map(f64::to_bits))
                .collect();
            (bits, largest, p.threads_used())
        };
        let (one, largest, used_one) = run(1);
        let (two, _, used_two) = run(2);
        assert!(
            (ordered::ORDERED_MIN_POINTS..2048).contains(&largest),
            "largest island {largest} points"
        );
        assert_eq!(used_one, 1);
        assert_eq!(used_two, crate::threads::sync::effective_threads(2));
        assert_eq!(one, two);
    }

    #[test]
    fn domain_pass_is_bit_identical_for_one_to_four_threads_and_as_deep() {
        // 1 to 8 domains of the 100-body pile (8 give all four threads a domain of each
        // phase), 1 to 4 threads; the pass ends where the problem-order pass does (to 0.1 mm),
        // most of the overlap resolved.
        let (problem, start) = pile_problem();
        let in_order = pass_bits(&problem, &start, PgsPositionSettings::default());
        let plain = f64::from_bits(in_order.2);
        for domains in [1, 2, 3, 5, 8] {
            let runs: Vec<_> = (1..=4)
                .map(|threads| {
                    let settings = PgsPositionSettings {
                        threads,
                        parallel_min_points: 0,
                        domains,
                        domain_points: 0,
                    };
                    pass_bits(&problem, &start, settings)
                })
                .collect();
            assert!(runs[0].1 > 1, "ran {} iterations", runs[0].1);
            for (k, r) in runs.iter().enumerate().skip(1) {
                assert!(r == &runs[0], "{domains} domains: {} threads", k + 1);
            }
            let split = f64::from_bits(runs[0].2);
            assert!(
                (split - plain).abs() < 1e-4,
                "{domains}: {split} vs {plain}"
            );
        }
        // One domain is the problem-order pass on Z-renumbered bodies: the same corrections.
        let one = pass_bits(
            &problem,
            &start,
            PgsPositionSettings {
                parallel_min_points: 0,
                domains: 1,
                ..PgsPositionSettings::default()
            },
        );
        assert_eq!(one, in_order);
    }

    #[test]
    fn regression_remeasured_circle_contacts_were_never_recognised_in_f32_geometry() {
        // The circle test allowed 1e-9 of the radius; parry2d's f32 anchors and normals agree
        // to ~1e-7, so almost no pile contact was re-measured. A circle-circle point of the
        // pile, body B slid 0.1 m along the tangent: the fixed
        // normal sees no change of separation, the re-measured one the true gap between the
        // circles (|cB − cA| − (rA + rB)).
        let (problem, _) = pile_problem();
        let k = problem
            .points
            .iter()
            .position(|p| {
                let (a, b) = (
                    &problem.bodies[p.body_a as usize],
                    &problem.bodies[p.body_b as usize],
                );
                a.inv_mass > 0.0 && b.inv_mass > 0.0
            })
            .expect("a circle-circle contact");
        let p = &problem.points[k];
        let (ia, ib) = (p.body_a as usize, p.body_b as usize);
        let mut poses: Vec<Pose> = problem
            .bodies
            .iter()
            .map(|b| Pose::new(b.position, b.angle))
            .collect();
        poses[ib].position += 0.1 * Vector::new(-p.normal.y, p.normal.x);
        let radii = p
            .normal
            .dot(&(problem.bodies[ib].position - problem.bodies[ia].position))
            - p.separation;
        let gap = (poses[ib].position - poses[ia].position).norm() - radii;
        let measured = |circle_contact| {
            let settings = PositionSettings {
                circle_contact,
                ..PositionSettings::default()
            };
            let row = PosRow::new(&problem, k, &settings);
            correct_point(&row, &settings, poses.clone().as_mut_slice(), false).min_separation
        };
        assert!((measured(CircleContact::Fixed) - p.separation).abs() < 1e-12);
        assert!((measured(CircleContact::Remeasured) - gap).abs() < 1e-12);
        assert!(
            gap - p.separation > 1e-3,
            "the slide opens the gap: {gap} vs {}",
            p.separation
        );
    }

    #[test]
    fn coloured_plan_never_puts_two_points_on_one_movable_body_in_a_colour() {
        let (problem, _) = pile_problem();
        let mut plan = crate::position::chunked::Plan::default();
        plan.build(
            &problem,
            &crate::threads::z_order::ZOrder::of(&problem.points),
        );
        assert!(plan.check(&problem), "a colour moves one body twice");
    }
}
