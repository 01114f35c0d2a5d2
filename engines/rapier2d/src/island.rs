//! Island-sized problems for [`Grouping::Island`](crate::Grouping::Island): a pre-pass over
//! last step's manifolds, moved to this step's poses, before rapier's narrow phase runs.
//!
//! rapier's hook sees one manifold at a time and must write during that call, so the whole
//! contact graph has to be known before the step. Between two steps the bodies do not move:
//! the narrow phase of the coming step sees the poses the bodies have now. For every point of
//! last step's manifolds the pre-pass recomputes what parry2d's coherent update
//! (`ContactManifold::try_update_contacts`) computes: the world points `pose1 · local_p1` and
//! `pose2 · local_p2`, the normal `rot1 · local_n1`, the distance `(p2 − p1) · n`, and keeps the
//! points rapier would keep as solver contacts (distance below the prediction distance, or
//! closing below it within the step). Islands are the connected groups of dynamic bodies over
//! those manifolds (static bodies do not connect); each becomes one [`ContactProblem`] whose
//! `carried` values are the points' carried impulses. Points the narrow phase then creates or
//! renames (a new pair, a changed feature id) are missing from the plan: their manifold takes
//! the per-manifold path.

use std::collections::{BTreeMap, HashMap};

use deepcontact_core::{ContactProblem, Impulse, PointDesc, ProblemBody, Real, Vector};
use rapier2d::prelude::*;

use crate::hooks::PointKey;

/// One island's problem, with the key of each point.
#[derive(Debug)]
pub(crate) struct IslandProblem {
    pub problem: ContactProblem,
    pub carried: Vec<Option<Impulse>>,
    pub keys: Vec<PointKey>,
}

/// Union-find over body slots.
fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// A kept point of the pre-pass.
struct Point {
    key: PointKey,
    point: Vector,
    dist: Real,
    carried: Option<Impulse>,
}

/// A kept manifold of the pre-pass: its bodies, normal, friction, restitution and points.
struct Manifold {
    bodies: [Option<RigidBodyHandle>; 2],
    colliders: [ColliderHandle; 2],
    normal: Vector,
    friction: Real,
    restitution: Real,
    points: Vec<Point>,
}

/// The island problems of the coming step (see the [module docs](self)); `body` builds a
/// problem body from a rapier body (or a body-less collider), `to_step` converts rapier's
/// carried per-substep values.
pub(crate) fn plan(
    bodies: &RigidBodySet,
    colliders: &ColliderSet,
    narrow_phase: &NarrowPhase,
    prediction: Real,
    dt: Real,
    body: &dyn Fn(Option<RigidBodyHandle>, ColliderHandle) -> ProblemBody,
    to_step: &dyn Fn(f32, f32) -> Impulse,
) -> Vec<IslandProblem> {
    let manifolds = collect_manifolds(bodies, colliders, narrow_phase, prediction, dt, to_step);
    islands_of(bodies, &manifolds)
        .values()
        .filter_map(|members| island_problem(&manifolds, members, body))
        .collect()
}

/// Whether `h` is a dynamic body of `bodies`.
fn is_dynamic(bodies: &RigidBodySet, h: Option<RigidBodyHandle>) -> bool {
    h.and_then(|h| bodies.get(h))
        .is_some_and(|rb| rb.is_dynamic())
}

/// The manifolds touching a dynamic body, with the points rapier will keep as solver
/// contacts at this step's poses.
fn collect_manifolds(
    bodies: &RigidBodySet,
    colliders: &ColliderSet,
    narrow_phase: &NarrowPhase,
    prediction: Real,
    dt: Real,
    to_step: &dyn Fn(f32, f32) -> Impulse,
) -> Vec<Manifold> {
    let v = |p: rapier2d::math::Vector| Vector::new(Real::from(p.x), Real::from(p.y));
    let dynamic = |h: Option<RigidBodyHandle>| is_dynamic(bodies, h);
    let mut manifolds = Vec::new();
    for pair in narrow_phase.contact_pairs() {
        let (Some(co1), Some(co2)) = (colliders.get(pair.collider1), colliders.get(pair.collider2))
        else {
            continue;
        };
        let (rb1, rb2) = (co1.parent(), co2.parent());
        if !dynamic(rb1) && !dynamic(rb2) {
            continue;
        }
        let vel = |h: Option<RigidBodyHandle>, p| {
            h.and_then(|h| bodies.get(h))
                .map_or(rapier2d::math::Vector::ZERO, |rb| rb.velocity_at_point(p))
        };
        let skins = co1.contact_skin() + co2.contact_skin();
        for m in &pair.manifolds {
            let pose1 = m
                .subshape_pos1
                .map_or(*co1.position(), |s| *co1.position() * s);
            let pose2 = m
                .subshape_pos2
                .map_or(*co2.position(), |s| *co2.position() * s);
            let n = pose1.rotation * m.local_n1;
            let mut points = Vec::new();
            for pt in &m.points {
                let (p1, p2) = (pose1 * pt.local_p1, pose2 * pt.local_p2);
                let dist = (p2 - p1).dot(n) - skins;
                let closing = (vel(rb2, p2) - vel(rb1, p1)).dot(n);
                let kept = Real::from(dist) < prediction
                    || Real::from(dist) + Real::from(closing) * dt < prediction;
                if !kept {
                    continue;
                }
                let key = PointKey {
                    collider1: pair.collider1.into_raw_parts(),
                    collider2: pair.collider2.into_raw_parts(),
                    subshape1: m.subshape1,
                    subshape2: m.subshape2,
                    fid1: pt.fid1.0,
                    fid2: pt.fid2.0,
                };
                let (wn, wt) = (
                    pt.data.warmstart_impulse,
                    pt.data.warmstart_tangent_impulse.x,
                );
                let carried =
                    (pt.data.impulse != 0.0 || wn != 0.0 || wt != 0.0).then(|| to_step(wn, wt));
                points.push(Point {
                    key,
                    point: v(p1.midpoint(p2)),
                    dist: Real::from(dist),
                    carried,
                });
            }
            if points.is_empty() {
                continue;
            }
            // Last step's solver contacts hold the mixed coefficients; a manifold without any
            // takes rapier's default rules (average friction, largest restitution).
            let (friction, restitution) = m.data.solver_contacts.first().map_or(
                (
                    0.5 * (co1.friction() + co2.friction()),
                    co1.restitution().max(co2.restitution()),
                ),
                |sc| (sc.friction, sc.restitution),
            );
            manifolds.push(Manifold {
                bodies: [rb1, rb2],
                colliders: [pair.collider1, pair.collider2],
                normal: v(n),
                friction: Real::from(friction),
                restitution: Real::from(restitution),
                points,
            });
        }
    }
    manifolds
}

/// The manifolds of each island, by its root: union-find over the dynamic bodies' slots in
/// the body set (static and kinematic bodies do not join islands).
fn islands_of(bodies: &RigidBodySet, manifolds: &[Manifold]) -> BTreeMap<usize, Vec<usize>> {
    let dynamic = |h: Option<RigidBodyHandle>| is_dynamic(bodies, h);
    let slot = |h: RigidBodyHandle| h.into_raw_parts().0 as usize;
    let slots = bodies.iter().map(|(h, _)| slot(h) + 1).max().unwrap_or(0);
    let mut parent: Vec<usize> = (0..slots).collect();
    for m in manifolds {
        if let [Some(a), Some(b)] = m.bodies
            && dynamic(Some(a))
            && dynamic(Some(b))
        {
            let (ra, rb) = (find(&mut parent, slot(a)), find(&mut parent, slot(b)));
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    let mut by_root: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, m) in manifolds.iter().enumerate() {
        let d = if dynamic(m.bodies[0]) {
            m.bodies[0]
        } else {
            m.bodies[1]
        };
        let Some(d) = d else { continue };
        by_root
            .entry(find(&mut parent, slot(d)))
            .or_default()
            .push(i);
    }
    by_root
}

/// One island's problem from its `members` (indices into `manifolds`), `None` when no point
/// was admitted.
fn island_problem(
    manifolds: &[Manifold],
    members: &[usize],
    body: &dyn Fn(Option<RigidBodyHandle>, ColliderHandle) -> ProblemBody,
) -> Option<IslandProblem> {
    let mut problem = ContactProblem::new();
    let mut index: HashMap<(Option<RigidBodyHandle>, ColliderHandle), u32> = HashMap::new();
    let mut carried = Vec::new();
    let mut keys = Vec::new();
    for &i in members {
        let m = &manifolds[i];
        // Bodies are shared by their manifolds (a body-less collider by its handle).
        let ids = [0, 1].map(|k| {
            let tag = (
                m.bodies[k],
                if m.bodies[k].is_some() {
                    ColliderHandle::invalid()
                } else {
                    m.colliders[k]
                },
            );
            *index
                .entry(tag)
                .or_insert_with(|| problem.add_body(body(m.bodies[k], m.colliders[k])))
        });
        for (j, p) in m.points.iter().enumerate() {
            if j % 2 == 0 {
                problem.begin_manifold();
            }
            let desc = PointDesc::new(ids[0], ids[1], p.point, m.normal)
                .id(p.key.contact_id())
                .separation(p.dist)
                .friction(m.friction)
                .restitution(m.restitution, 1.0);
            if problem.add_point(&desc).is_err() {
                continue;
            }
            carried.push(p.carried);
            keys.push(p.key);
        }
    }
    (!problem.is_empty()).then_some(IslandProblem {
        problem,
        carried,
        keys,
    })
}
