//! What the velocity solver's tests share: islands of the suite's scenes, and a solve's bits.

use deepcontact_core::{CarriedWarmStart, ContactProblem, Impulse, Velocity, WorldSettings, scene};

use super::PgsSolver;

/// Every island of `scene`'s last step after `steps` steps of carried impulses and PGS,
/// largest first.
pub(crate) fn islands(scene: scene::Scene, steps: usize) -> Vec<ContactProblem> {
    let mut world = scene.build(WorldSettings::default()).unwrap();
    let (mut s, mut p) = (PgsSolver::new(), crate::PgsPositionSolver::new());
    for _ in 0..steps {
        world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
    }
    let mut problems = world.last_problems().to_vec();
    problems.sort_by_key(|p| std::cmp::Reverse(p.len()));
    problems
}

/// The bits of a solve's result: every impulse, then every velocity.
pub(crate) fn solution_bits(impulses: &[Impulse], velocities: &[Velocity]) -> Vec<u64> {
    impulses
        .iter()
        .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
        .chain(velocities.iter().flat_map(|v| {
            [
                v.linear.x.to_bits(),
                v.linear.y.to_bits(),
                v.angular.to_bits(),
            ]
        }))
        .collect()
}
