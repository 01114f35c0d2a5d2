//! Narrow phase: parry2d contact manifolds for the broad phase's pairs.

use crate::body::Body;
use crate::contact::ContactId;
use crate::math::{Real, Vector, from_parry, parry_pose};
use parry2d::math::Pose;
use parry2d::query::{ContactManifold, DefaultQueryDispatcher, PersistentQueryDispatcher};

/// One contact point straight from the narrow phase, in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawContact {
    /// Identity (ordered body pair + features).
    pub id: ContactId,
    /// Contact point (midpoint of the two surface points).
    pub point: Vector,
    /// Unit normal from `id.body_a` to `id.body_b`.
    pub normal: Vector,
    /// Signed distance (negative = overlap).
    pub separation: Real,
}

/// Pairs a thread takes at least before [`NarrowPhase::collide_on`] hands some to another: a
/// pair costs a few hundred ns, waking or starting a thread tens of µs.
pub const MIN_PAIRS_PER_THREAD: usize = 1024;

/// Reusable narrow-phase state.
#[derive(Debug, Default, Clone)]
pub struct NarrowPhase {
    /// Points of all manifolds, grouped by manifold.
    pub contacts: Vec<RawContact>,
    /// `[start, end)` into `contacts`, one per non-empty manifold, in pair order.
    pub manifolds_ranges: Vec<(u32, u32)>,
    /// Each body's parry pose for this step (one `sin_cos` per body, not two per pair).
    poses: Vec<Pose>,
    /// One share of the pairs per thread: the first thread's manifold scratch, then each
    /// further thread's scratch and output.
    shares: Vec<Share>,
}

/// What one thread's contiguous share of the pairs produces, and its scratch.
#[derive(Debug, Default, Clone)]
struct Share {
    manifolds: Vec<ContactManifold<(), ()>>,
    contacts: Vec<RawContact>,
    ranges: Vec<(u32, u32)>,
}

impl NarrowPhase {
    /// An empty narrow phase.
    pub fn new() -> Self {
        Self::default()
    }

    /// Computes the manifolds of `pairs`, keeping points with separation ≤ `prediction`.
    pub fn collide(&mut self, bodies: &[Body], pairs: &[(u32, u32)], prediction: Real) {
        self.collide_on(bodies, pairs, prediction, 1);
    }

    /// [`Self::collide`] on up to `threads` threads (0 counts as 1), each taking a
    /// contiguous share of the pairs of at least [`MIN_PAIRS_PER_THREAD`]; the shares' contacts
    /// are joined in pair order, so the result is the same, bit for bit, for any count.
    pub fn collide_on(
        &mut self,
        bodies: &[Body],
        pairs: &[(u32, u32)],
        prediction: Real,
        threads: usize,
    ) {
        self.collide_shares(bodies, pairs, prediction, threads, MIN_PAIRS_PER_THREAD);
    }

    /// [`Self::collide_on`] with the least share `min_pairs` (≥ 1).
    fn collide_shares(
        &mut self,
        bodies: &[Body],
        pairs: &[(u32, u32)],
        prediction: Real,
        threads: usize,
        min_pairs: usize,
    ) {
        self.poses.clear();
        self.poses
            .extend(bodies.iter().map(|b| parry_pose(&b.origin(), b.angle)));
        let threads = threads.clamp(1, (pairs.len() / min_pairs.max(1)).max(1));
        if self.shares.len() < threads {
            self.shares.resize_with(threads, Share::default);
        }
        self.contacts.clear();
        self.manifolds_ranges.clear();
        let (poses, (first, rest)) = (
            &self.poses,
            self.shares.split_first_mut().expect("at least one share"),
        );
        if threads == 1 {
            collide_pairs(
                bodies,
                poses,
                pairs,
                prediction,
                &mut first.manifolds,
                &mut self.contacts,
                &mut self.manifolds_ranges,
            );
            return;
        }
        let per = pairs.len().div_ceil(threads);
        let mut chunks = pairs.chunks(per);
        let own = chunks.next().unwrap_or_default();
        let (contacts, ranges) = (&mut self.contacts, &mut self.manifolds_ranges);
        let rest = &mut rest[..threads - 1];
        let shares = rest.iter_mut().zip(chunks).map(|(share, chunk)| {
            let Share {
                manifolds,
                contacts,
                ranges,
            } = share;
            (chunk, manifolds, contacts, ranges)
        });
        crate::threads::on_threads(
            std::iter::once((own, &mut first.manifolds, contacts, ranges)).chain(shares),
            |(chunk, manifolds, contacts, ranges)| {
                contacts.clear();
                ranges.clear();
                collide_pairs(
                    bodies, poses, chunk, prediction, manifolds, contacts, ranges,
                );
            },
        );
        for share in rest.iter() {
            let offset = self.contacts.len() as u32;
            self.contacts.extend_from_slice(&share.contacts);
            self.manifolds_ranges
                .extend(share.ranges.iter().map(|&(s, e)| (s + offset, e + offset)));
        }
    }
}

/// The manifolds of `pairs` (bodies posed by `poses`), their points appended to `contacts`
/// and their ranges (into `contacts`) to `ranges`; `manifolds` is parry's scratch.
pub(crate) fn collide_pairs(
    bodies: &[Body],
    poses: &[Pose],
    pairs: &[(u32, u32)],
    prediction: Real,
    manifolds: &mut Vec<ContactManifold<(), ()>>,
    contacts: &mut Vec<RawContact>,
    ranges: &mut Vec<(u32, u32)>,
) {
    let dispatcher = DefaultQueryDispatcher;
    for &(a, b) in pairs {
        let (ba, bb) = (&bodies[a as usize], &bodies[b as usize]);
        let (pose_a, pose_b) = (&poses[a as usize], &poses[b as usize]);
        let pos12 = pose_a.inv_mul(pose_b);
        manifolds.clear();
        let mut workspace = None;
        if dispatcher
            .contact_manifolds(
                &pos12,
                ba.shape.as_ref(),
                bb.shape.as_ref(),
                prediction as f32,
                manifolds,
                &mut workspace,
            )
            .is_err()
        {
            continue;
        }
        for m in manifolds.iter() {
            let start = contacts.len() as u32;
            let normal = from_parry(pose_a.rotation * m.local_n1);
            let nn = normal.norm();
            if nn.is_nan() || nn <= 0.0 {
                continue;
            }
            let normal = normal / nn;
            for p in &m.points {
                if p.dist as Real > prediction {
                    continue;
                }
                let p1 = from_parry(pose_a.transform_point(p.local_p1));
                let p2 = from_parry(pose_b.transform_point(p.local_p2));
                contacts.push(RawContact {
                    id: ContactId {
                        body_a: a,
                        body_b: b,
                        feature_a: ((m.subshape1 as u64) << 32) | p.fid1.0 as u64,
                        feature_b: ((m.subshape2 as u64) << 32) | p.fid2.0 as u64,
                    },
                    point: 0.5 * (p1 + p2),
                    normal,
                    separation: p.dist as Real,
                });
            }
            let end = contacts.len() as u32;
            if end > start {
                ranges.push((start, end));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::broad_phase::BroadPhase;
    use crate::world::WorldSettings;

    #[test]
    fn contacts_are_the_same_bits_in_the_same_order_for_any_thread_count() {
        // A pile (walls, balls) with boxes and balls strewn over it, some overlapping, at
        // random angles: every share boundary falls between pairs of some manifolds.
        let world =
            crate::shared_collide::tests::strewn_world(300, 300, 30.0, 5, WorldSettings::default());
        let mut bp = BroadPhase::new();
        let pairs = bp.find_pairs(world.bodies(), 0.02).to_vec();
        assert!(pairs.len() > 300, "{} pairs", pairs.len());
        let bits = |n: &NarrowPhase| {
            let c: Vec<_> = n
                .contacts
                .iter()
                .map(|c| {
                    (
                        c.id,
                        [c.point.x, c.point.y, c.normal.x, c.normal.y, c.separation]
                            .map(f64::to_bits),
                    )
                })
                .collect();
            (c, n.manifolds_ranges.clone())
        };
        let mut one = NarrowPhase::new();
        one.collide(world.bodies(), &pairs, 0.02);
        assert!(one.contacts.len() > 200 && one.manifolds_ranges.len() > 100);
        let expected = bits(&one);
        // The same narrow phase reused, shares of 1, 7 and 100 pairs, 2 to 5 threads.
        let mut many = NarrowPhase::new();
        for (threads, least) in [(2, 1), (3, 7), (5, 100), (4, 1), (1, 1), (2, 100_000)] {
            many.collide_shares(world.bodies(), &pairs, 0.02, threads, least);
            assert!(
                bits(&many) == expected,
                "{threads} threads, shares of at least {least}"
            );
        }
    }
}
