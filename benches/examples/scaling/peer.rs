//! The peer comparison: ns per solver contact point per pass of our PGS velocity solve beside
//! rapier2d's velocity resolution in each [`RapierConfig`], over a whole run from the initial
//! state and on the settled pile, measured in the same process one after the other.

use std::time::Instant;

use deepcontact_benches::fixed_iterations;
use deepcontact_core::scene::Scene;
use deepcontact_core::{World, WorldSettings};

use crate::ours;
use crate::rapier_pile::{RapierConfig, RapierPile};

/// The rapier2d configurations set beside ours, for `passes` passes.
pub fn configs(passes: u32) -> [RapierConfig; 3] {
    let n = passes as usize;
    [
        RapierConfig::Passes(n),
        RapierConfig::PassesNormalOnly(n),
        RapierConfig::Substeps(n),
    ]
}

/// One engine's velocity solve over some steps.
#[derive(Debug, Clone, Copy)]
pub struct PassCost {
    /// Ns per solver contact point per pass.
    pub ns: f64,
    /// Mean solver contact points per step.
    pub points: f64,
    /// Mean wall time of a whole step, ms.
    pub step_ms: f64,
}

/// One row of the comparison: ours and each rapier2d configuration on the same pile.
pub struct PeerRow {
    /// Bodies.
    pub bodies: usize,
    /// "whole run" or "settled".
    pub pile: &'static str,
    /// Steps measured.
    pub steps: u64,
    /// Our PGS.
    pub ours: PassCost,
    /// rapier2d, per configuration.
    pub rapier: Vec<(RapierConfig, PassCost)>,
}

/// Our settings with exactly `passes` velocity iterations (tolerance 0) and the default
/// position pass: `deepcontact simulate --tolerance 0 --max-iterations PASSES`.
fn ours_settings(passes: u32) -> WorldSettings {
    WorldSettings {
        solver: fixed_iterations(passes),
        ..WorldSettings::default()
    }
}

/// Our velocity solve over `steps` steps of `world` at `passes` iterations.
fn ours_cost(world: &mut World, passes: u32, steps: u64) -> Result<PassCost, String> {
    let t = ours::run(world, ours_settings(passes), steps, Some(passes))?;
    Ok(PassCost {
        ns: t.ns_per_point_iteration(),
        points: t.mean_contacts(),
        step_ms: t.ms(t.wall),
    })
}

/// rapier2d's velocity resolution over `steps` steps in its current configuration.
fn rapier_cost(peer: &mut RapierPile, steps: u64) -> PassCost {
    let (mut solve, mut point_passes, mut points, mut wall) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..steps {
        let t0 = Instant::now();
        peer.step();
        wall += t0.elapsed().as_secs_f64();
        solve += peer.solver_seconds();
        points += peer.contacts() as f64;
        point_passes += (peer.contacts() * peer.passes()) as f64;
    }
    PassCost {
        ns: solve / point_passes.max(1.0) * 1e9,
        points: points / steps.max(1) as f64,
        step_ms: wall / steps.max(1) as f64 * 1e3,
    }
}

/// Every engine from the initial state of `scene` (`n` bodies)'s initial state for `steps` steps at `passes` passes.
pub fn whole_run(n: usize, scene: &Scene, passes: u32, steps: u64) -> Result<PeerRow, String> {
    let mut world = scene
        .build(ours_settings(passes))
        .map_err(|e| e.to_string())?;
    let ours = ours_cost(&mut world, passes, steps)?;
    let rapier = configs(passes)
        .into_iter()
        .map(|config| {
            (
                config,
                rapier_cost(&mut RapierPile::new(scene, config), steps),
            )
        })
        .collect();
    Ok(PeerRow {
        bodies: n,
        pile: "whole run",
        steps,
        ours,
        rapier,
    })
}

/// Ours continuing from the settled `world`, then rapier2d settled for `settle` steps (in its
/// substep configuration at `settle_iterations`) and measured in each configuration in turn,
/// `steps` steps each.
pub fn settled(
    n: usize,
    scene: &Scene,
    world: &mut World,
    settle: u64,
    settle_iterations: u32,
    passes: u32,
    steps: u64,
) -> Result<PeerRow, String> {
    let ours = ours_cost(world, passes, steps)?;
    let mut peer = RapierPile::new(scene, RapierConfig::Substeps(settle_iterations as usize));
    for _ in 0..settle {
        peer.step();
    }
    eprintln!(
        "n={n}: kinetic energy of the settled piles: deepcontact {:.3} J, rapier2d {:.3} J",
        world.kinetic_energy(),
        peer.kinetic_energy()
    );
    let rapier = configs(passes)
        .into_iter()
        .map(|config| {
            peer.set_config(config);
            (config, rapier_cost(&mut peer, steps))
        })
        .collect();
    Ok(PeerRow {
        bodies: n,
        pile: "settled",
        steps,
        ours,
        rapier,
    })
}
