//! Shared helpers of the cross-crate integration tests: run a scene with a provider and
//! collect what the tests check.
#![warn(missing_docs)]

use deepcontact_core::{CoreError, StepReport, WarmStart, World, WorldSettings, scene::Scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Steps `world` `steps` times with PGS and `warm`, calling `check` after every step.
pub fn run(
    world: &mut World,
    warm: &mut dyn WarmStart,
    steps: u64,
    check: impl FnMut(&World, &StepReport),
) -> Result<Vec<StepReport>, CoreError> {
    let mut solvers = (PgsSolver::new(), PgsPositionSolver::new());
    run_with(world, warm, &mut solvers, steps, check)
}

/// [`run`] with the given velocity and position solvers.
pub fn run_with(
    world: &mut World,
    warm: &mut dyn WarmStart,
    (solver, position): &mut (PgsSolver, PgsPositionSolver),
    steps: u64,
    mut check: impl FnMut(&World, &StepReport),
) -> Result<Vec<StepReport>, CoreError> {
    let mut reports = Vec::with_capacity(steps as usize);
    for _ in 0..steps {
        let r = world.step(warm, solver, position)?;
        check(world, &r);
        reports.push(r);
    }
    Ok(reports)
}

/// Builds `scene` with the default (thesis) settings.
pub fn build(scene: &Scene) -> World {
    scene.build(WorldSettings::default()).expect("scene builds")
}

/// Bit patterns of every body's position and angle (for determinism checks).
pub fn state_bits(world: &World) -> Vec<[u64; 3]> {
    world
        .bodies()
        .iter()
        .map(|b| {
            [
                b.position.x.to_bits(),
                b.position.y.to_bits(),
                b.angle.to_bits(),
            ]
        })
        .collect()
}

/// The cores this process may use, which caps the threads any solver starts. A machine with
/// one core cannot show that thread counts agree, so under `CI=true` (whose machines have two
/// or more) one core is a failure rather than a test that proves nothing.
pub fn cores() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    assert!(
        cores >= 2 || std::env::var("CI").as_deref() != Ok("true"),
        "CI=true on a machine with {cores} core: no second thread can run"
    );
    cores
}

/// The README: its Rust snippets compile (and run, unless marked `no_run`) as this crate's
/// doctests, so `cargo test --release --workspace --exclude deepcontact-benches` checks them.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
pub struct Readme;

/// `docs/guide/provider.md`: its Rust code runs as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../../docs/guide/provider.md")]
pub struct GuideProvider;

/// `docs/guide/embed.md`: its Rust code runs as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../docs/guide/embed.md")]
pub struct GuideEmbed;

/// `docs/guide/depend.md` (TOML and shell only: nothing to run, kept here so a Rust block
/// added later is checked too).
#[cfg(doctest)]
#[doc = include_str!("../../docs/guide/depend.md")]
pub struct GuideDepend;

/// `docs/guide/reproduce.md` (shell only; see [`GuideDepend`]).
#[cfg(doctest)]
#[doc = include_str!("../../docs/guide/reproduce.md")]
pub struct GuideReproduce;
