//! What one more pass costs: the slope of step time against passes, ours beside rapier2d
//! (shared by the `peer` group and by the scaling example through `#[path]`).
//!
//! Each engine steps its own settled pile, alternately at [`LOW`] and [`HIGH`] passes per
//! step, in turns: ours at [`LOW`], rapier2d at [`LOW`], ours at [`HIGH`], rapier2d at
//! [`HIGH`], a block of steps each, and again for every round (with several of our solvers,
//! each takes its turn where "ours" stands, one after the other, on the same world). Per
//! engine and round the slope is
//!
//! ```text
//! (t_HIGH / points_HIGH − t_LOW / points_LOW) / (HIGH − LOW)
//! ```
//!
//! in ns per contact point per pass, `t / points` the fastest of a block's steps in wall time
//! of the whole step (everything the step does) per solver contact point of that step (the
//! fastest: a step that another process interrupted is slower, never faster): what the passes
//! beyond the first [`LOW`] cost, with the step's fixed part (narrow phase, set-up,
//! integration) cancelled out. The rounds are short, so that both engines see the machine
//! alike; the figure is the median of the rounds, with their spread. Ours runs exactly `passes` velocity iterations (tolerance 0); rapier2d runs
//! one substep of `passes` internal PGS passes with friction in every pass
//! ([`RapierConfig::Passes`]), plus its one stabilisation pass at both counts.

use std::time::Instant;

use deepcontact_benches::{fixed_iterations, median};
use deepcontact_core::{CarriedWarmStart, PositionSolver, VelocitySolver, World, WorldSettings};

use super::rapier_pile::{RapierConfig, RapierPile};

/// The lower pass count of the slope.
pub const LOW: u32 = 100;

/// The higher pass count of the slope.
pub const HIGH: u32 = 1_000;

/// One engine's slope over the rounds.
#[derive(Debug, Clone, Default)]
pub struct Slope {
    /// Ns per contact point per pass, one per round.
    pub rounds: Vec<f64>,
    /// Mean solver contact points per step, all steps.
    pub points: f64,
}

impl Slope {
    /// The median round.
    pub fn median(&self) -> f64 {
        median(&self.rounds)
    }

    /// The smallest and largest rounds.
    pub fn spread(&self) -> (f64, f64) {
        let min = self.rounds.iter().copied().fold(f64::INFINITY, f64::min);
        let max = self
            .rounds
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        (min, max)
    }
}

/// One of our solvers: its slope and the ratio to rapier2d's of each round.
#[derive(Debug, Clone, Default)]
pub struct OurSlope {
    /// The solver's label.
    pub label: String,
    /// Its slope.
    pub slope: Slope,
    /// Ours / rapier2d, one per round.
    pub ratios: Vec<f64>,
}

impl OurSlope {
    /// The median ratio and the smallest and largest.
    pub fn ratio(&self) -> (f64, f64, f64) {
        let min = self.ratios.iter().copied().fold(f64::INFINITY, f64::min);
        let max = self
            .ratios
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        (median(&self.ratios), min, max)
    }
}

/// Our solvers' side and rapier2d's.
#[derive(Debug, Clone, Default)]
pub struct SlopeRow {
    /// Bodies.
    pub bodies: usize,
    /// Steps per engine, pass count and round.
    pub block: u64,
    /// Rounds.
    pub rounds: u32,
    /// Our solvers, in the order they took their turns.
    pub ours: Vec<OurSlope>,
    /// rapier2d.
    pub rapier: Slope,
}

/// Steps per engine, pass count and round for a pile of `n` bodies: about 10 000 body-steps,
/// 3 to 50.
pub fn block_steps(n: usize) -> u64 {
    (10_000 / n.max(1) as u64).clamp(3, 50)
}

/// The fastest step per contact point (wall seconds) and the mean points per step of a block.
#[derive(Clone, Copy)]
struct Block {
    per_point: f64,
    points: f64,
}

impl Block {
    fn new() -> Self {
        Self {
            per_point: f64::INFINITY,
            points: 0.0,
        }
    }

    /// One step of `wall` seconds on `points` contact points.
    fn add(&mut self, wall: f64, points: usize) {
        self.per_point = self.per_point.min(wall / points.max(1) as f64);
        self.points += points as f64;
    }

    /// Ends a block of `steps` steps.
    fn finish(mut self, steps: u64) -> Self {
        self.points /= steps.max(1) as f64;
        self
    }
}

/// Our world stepped `steps` times at `passes` passes (tolerance 0).
fn ours_block(
    world: &mut World,
    solver: &mut dyn VelocitySolver,
    position: &mut dyn PositionSolver,
    passes: u32,
    steps: u64,
) -> Result<Block, String> {
    world
        .set_settings(WorldSettings {
            solver: fixed_iterations(passes),
            ..WorldSettings::default()
        })
        .map_err(|e| e.to_string())?;
    let mut b = Block::new();
    for _ in 0..steps {
        let t0 = Instant::now();
        let r = world
            .step(&mut CarriedWarmStart, solver, position)
            .map_err(|e| e.to_string())?;
        b.add(t0.elapsed().as_secs_f64(), r.contacts);
    }
    Ok(b.finish(steps))
}

/// rapier2d stepped `steps` times at `passes` passes.
fn rapier_block(peer: &mut RapierPile, passes: u32, steps: u64) -> Block {
    peer.set_config(RapierConfig::Passes(passes as usize));
    let mut b = Block::new();
    for _ in 0..steps {
        let t0 = Instant::now();
        peer.step();
        b.add(t0.elapsed().as_secs_f64(), peer.contacts());
    }
    b.finish(steps)
}

/// The slope of both engines on their settled piles of `n` bodies, `rounds` rounds of
/// `block` steps per engine and pass count, the engines in turns (see the module docs); each
/// of our `solvers` (label, solver) takes its turn on the same world, one after the other.
pub fn measure(
    n: usize,
    world: &mut World,
    solvers: &mut [(&str, &mut dyn VelocitySolver)],
    position: &mut dyn PositionSolver,
    peer: &mut RapierPile,
    rounds: u32,
    block: u64,
) -> Result<SlopeRow, String> {
    let mut row = SlopeRow {
        bodies: n,
        block,
        rounds,
        ours: solvers
            .iter()
            .map(|(label, _)| OurSlope {
                label: (*label).to_string(),
                ..OurSlope::default()
            })
            .collect(),
        ..SlopeRow::default()
    };
    let per_pass = 1e9 / f64::from(HIGH - LOW);
    let blocks = 2.0 * f64::from(rounds.max(1));
    let mut low = vec![Block::new(); solvers.len()];
    let mut high = low.clone();
    for _ in 0..rounds {
        for ((_, solver), b) in solvers.iter_mut().zip(&mut low) {
            *b = ours_block(world, &mut **solver, position, LOW, block)?;
        }
        let rapier_low = rapier_block(peer, LOW, block);
        for ((_, solver), b) in solvers.iter_mut().zip(&mut high) {
            *b = ours_block(world, &mut **solver, position, HIGH, block)?;
        }
        let rapier_high = rapier_block(peer, HIGH, block);
        let rapier = (rapier_high.per_point - rapier_low.per_point) * per_pass;
        row.rapier.rounds.push(rapier);
        row.rapier.points += (rapier_low.points + rapier_high.points) / blocks;
        for ((ours, l), h) in row.ours.iter_mut().zip(&low).zip(&high) {
            let slope = (h.per_point - l.per_point) * per_pass;
            ours.slope.rounds.push(slope);
            ours.slope.points += (l.points + h.points) / blocks;
            ours.ratios.push(slope / rapier);
        }
    }
    Ok(row)
}

/// The markdown table of the slope rows.
pub fn print(rows: &[SlopeRow]) {
    println!(
        "\nSlope: what one more pass costs, (t{HIGH}/points − t{LOW}/points) / {} in ns per \
         contact point per pass, t/points = the fastest whole step of a block per contact point, \
         both engines on their settled piles in turns (ours: PGS, tolerance 0; rapier2d: one \
         substep of N PGS passes, friction in every pass); median of the rounds (min–max):\n",
        HIGH - LOW
    );
    println!(
        "| bodies | steps/block | rounds | solver | points | ns | rapier2d points | rapier2d ns | \
         ratio to rapier2d |"
    );
    println!("|---:|---:|---:|---|---:|---:|---:|---:|---:|");
    for r in rows {
        let (rm, (r0, r1)) = (r.rapier.median(), r.rapier.spread());
        for o in &r.ours {
            let (om, (o0, o1)) = (o.slope.median(), o.slope.spread());
            let (q, q0, q1) = o.ratio();
            println!(
                "| {} | {} | {} | {} | {:.0} | {om:.2} ({o0:.2}–{o1:.2}) | {:.0} | \
                 {rm:.2} ({r0:.2}–{r1:.2}) | {q:.2} ({q0:.2}–{q1:.2}) |",
                r.bodies, r.block, r.rounds, o.label, o.slope.points, r.rapier.points,
            );
        }
    }
}
