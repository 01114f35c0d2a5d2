//! Narrow phase: parry2d contact manifolds for the broad phase's pairs.

use crate::body::Body;
use crate::contact::ContactId;
use crate::math::{Real, Vector, from_parry, parry_pose};
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

/// Reusable narrow-phase state.
#[derive(Debug, Default, Clone)]
pub struct NarrowPhase {
    manifolds: Vec<ContactManifold<(), ()>>,
    /// Points of all manifolds, grouped by manifold.
    pub contacts: Vec<RawContact>,
    /// `[start, end)` into `contacts`, one per non-empty manifold, in pair order.
    pub manifolds_ranges: Vec<(u32, u32)>,
}

impl NarrowPhase {
    /// An empty narrow phase.
    pub fn new() -> Self {
        Self::default()
    }

    /// Computes the manifolds of `pairs`, keeping points with separation ≤ `prediction`.
    pub fn collide(&mut self, bodies: &[Body], pairs: &[(u32, u32)], prediction: Real) {
        self.contacts.clear();
        self.manifolds_ranges.clear();
        let dispatcher = DefaultQueryDispatcher;
        for &(a, b) in pairs {
            let (ba, bb) = (&bodies[a as usize], &bodies[b as usize]);
            let pose_a = parry_pose(&ba.origin(), ba.angle);
            let pose_b = parry_pose(&bb.origin(), bb.angle);
            let pos12 = pose_a.inv_mul(&pose_b);
            self.manifolds.clear();
            let mut workspace = None;
            if dispatcher
                .contact_manifolds(
                    &pos12,
                    ba.shape.as_ref(),
                    bb.shape.as_ref(),
                    prediction as f32,
                    &mut self.manifolds,
                    &mut workspace,
                )
                .is_err()
            {
                continue;
            }
            for m in &self.manifolds {
                let start = self.contacts.len() as u32;
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
                    self.contacts.push(RawContact {
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
                let end = self.contacts.len() as u32;
                if end > start {
                    self.manifolds_ranges.push((start, end));
                }
            }
        }
    }
}
