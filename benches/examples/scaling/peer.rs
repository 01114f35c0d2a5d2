//! The peer comparison: ns per solver contact point per pass of our PGS velocity solve beside
//! rapier2d's velocity resolution in each [`RapierConfig`], over a whole run from the initial
//! state and on the settled pile, measured in the same process. The engines take their steps
//! in turn, [`BLOCK`] steps at a time (ours, then each rapier2d configuration; on the settled
//! pile ours with the like-with-like configuration, the other two after), so that the machine
//! changing speed during a run touches both sides of a ratio alike, while each engine still
//! finds its own data in the caches for all but the first step of a block.

/// Steps an engine takes before the next one takes its turn.
pub const BLOCK: u64 = 25;

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

/// Our velocity solve from the totals of the steps taken.
fn ours_cost(t: &ours::Totals) -> PassCost {
    PassCost {
        ns: t.ns_per_point_iteration(),
        points: t.mean_contacts(),
        step_ms: t.ms(t.wall),
    }
}

/// rapier2d's velocity resolution, summed step by step.
#[derive(Default)]
struct RapierTotals {
    steps: u64,
    solve: f64,
    point_passes: f64,
    points: f64,
    wall: f64,
}

impl RapierTotals {
    /// One step of `peer`, timed.
    fn step(&mut self, peer: &mut RapierPile) {
        let t0 = Instant::now();
        peer.step();
        self.wall += t0.elapsed().as_secs_f64();
        self.steps += 1;
        self.solve += peer.solver_seconds();
        self.points += peer.contacts() as f64;
        self.point_passes += (peer.contacts() * peer.passes()) as f64;
    }

    fn cost(&self) -> PassCost {
        PassCost {
            ns: self.solve / self.point_passes.max(1.0) * 1e9,
            points: self.points / self.steps.max(1) as f64,
            step_ms: self.wall / self.steps.max(1) as f64 * 1e3,
        }
    }
}

/// Ours stepping `world` at `passes` passes.
fn our_stepper(world: &mut World, passes: u32) -> Result<ours::Stepper, String> {
    world
        .set_settings(ours_settings(passes))
        .map_err(|e| e.to_string())?;
    Ok(ours::Stepper::new(Some(passes)))
}

/// Every engine from the initial state of `scene` (`n` bodies) for `steps` steps at `passes`
/// passes, in turns of [`BLOCK`] steps: ours, then each rapier2d configuration.
pub fn whole_run(n: usize, scene: &Scene, passes: u32, steps: u64) -> Result<PeerRow, String> {
    let mut world = scene
        .build(ours_settings(passes))
        .map_err(|e| e.to_string())?;
    let mut ours = our_stepper(&mut world, passes)?;
    let mut peers: Vec<(RapierConfig, RapierPile, RapierTotals)> = configs(passes)
        .into_iter()
        .map(|config| {
            (
                config,
                RapierPile::new(scene, config),
                RapierTotals::default(),
            )
        })
        .collect();
    for first in (0..steps).step_by(BLOCK as usize) {
        let block = BLOCK.min(steps - first);
        for _ in 0..block {
            ours.step(&mut world)?;
        }
        for (_, pile, totals) in &mut peers {
            for _ in 0..block {
                totals.step(pile);
            }
        }
    }
    Ok(PeerRow {
        bodies: n,
        pile: "whole run",
        steps,
        ours: ours_cost(&ours.totals),
        rapier: peers.iter().map(|(c, _, t)| (*c, t.cost())).collect(),
    })
}

/// rapier2d's pile of `scene` settled for `settle` steps in its substep configuration at
/// `settle_iterations`.
pub fn settle(scene: &Scene, settle: u64, settle_iterations: u32) -> RapierPile {
    let mut peer = RapierPile::new(scene, RapierConfig::Substeps(settle_iterations as usize));
    for _ in 0..settle {
        peer.step();
    }
    peer
}

/// Ours continuing from the settled `world` beside rapier2d's settled `peer` ([`settle`]):
/// `steps` steps of ours and of rapier2d in the like-with-like configuration in turns of
/// [`BLOCK`] steps, then `steps` steps of each other configuration.
pub fn settled(
    n: usize,
    world: &mut World,
    peer: &mut RapierPile,
    passes: u32,
    steps: u64,
) -> Result<PeerRow, String> {
    eprintln!(
        "n={n}: kinetic energy of the settled piles: deepcontact {:.3} J, rapier2d {:.3} J",
        world.kinetic_energy(),
        peer.kinetic_energy()
    );
    // Ours beside the like-with-like configuration, step after step; the others after.
    let mut ours = our_stepper(world, passes)?;
    let mut rapier = Vec::new();
    for (k, config) in configs(passes).into_iter().enumerate() {
        peer.set_config(config);
        let mut totals = RapierTotals::default();
        for first in (0..steps).step_by(BLOCK as usize) {
            let block = BLOCK.min(steps - first);
            for _ in 0..block {
                if k == 0 {
                    ours.step(world)?;
                }
            }
            for _ in 0..block {
                totals.step(peer);
            }
        }
        rapier.push((config, totals.cost()));
    }
    let ours = ours_cost(&ours.totals);
    Ok(PeerRow {
        bodies: n,
        pile: "settled",
        steps,
        ours,
        rapier,
    })
}
