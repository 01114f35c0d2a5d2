//! Scaling study: piles of 100, 1 000 and 10 000 circles (box scaled to keep the density),
//! deepcontact beside rapier2d, printed as markdown tables.
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example scaling
//! cargo run --release -p deepcontact-benches --example scaling -- --sizes 100,1000 --passes 1000
//! ```
//!
//! Per size: the pile is settled (builtin warm start, PGS, thesis stop rule with the velocity
//! cap lowered to `--settle-cap`, position cap 20) for `--settle` steps (default: 250 × (N /
//! 100)^¼, the thesis's 250 steps stretched by the longer fall of a taller pile), then
//! measured for a number of steps under these settings, continuing from the settled state:
//!
//! * `fixed`: `--iterations` velocity iterations always (tolerance 0), position cap the same;
//!   time per step, its split, ns per contact point per iteration of the velocity solve, and
//!   the phases of a step timed one by one;
//! * `thesis`: the thesis stop rule (∞-norm < 1e-4, cap 1000; position cap 250);
//! * the slope (`slope.rs`): what one more pass costs, ns per contact point per pass, from whole
//!   steps at 100 and at 1 000 passes of each engine on its settled pile, the engines in turns,
//!   `--slope-rounds` rounds (median and spread), our PGS in `f64` and in `f32`
//!   (`pgs:precision=f32`) in turns with rapier2d, with the ratios ours / rapier2d;
//! * the peer comparison at `--passes` passes per step, on the settled pile and over a whole
//!   `--run-steps` run from the initial state: our PGS velocity solve (`--passes`
//!   iterations, tolerance 0, default position pass) beside rapier2d's velocity resolution in
//!   three configurations (`rapier_pile.rs`, `RapierConfig`): one substep of N PGS passes with
//!   friction in every pass (like with like), the same with rapier's default friction rule
//!   (friction only in the final unbiased pass), and N substeps. Both sides in ns per solver
//!   contact point per pass, and their ratio.
//!
//! Timings are wall-clock on whatever machine runs it; compare rows of one run only.

#[path = "../../benches/groups/rapier_pile.rs"]
mod rapier_pile;
#[path = "../../benches/groups/slope.rs"]
mod slope;

mod options;
mod ours;
mod peer;
mod phases;
mod tables;

use deepcontact_benches::{SEED, fixed_world};
use deepcontact_core::{WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSettings, PgsSolver, Precision};

use options::Options;
use peer::PeerRow;
use tables::SizeRow;

fn main() -> Result<(), String> {
    let Some(o) = options::parse()? else {
        return Ok(());
    };
    let (mut rows, mut peers, mut slopes) = (Vec::new(), Vec::new(), Vec::new());
    for &n in &o.sizes {
        rows.push(measure_size(&o, n, &mut peers, &mut slopes)?);
    }
    tables::steps(&rows, o.iterations);
    tables::phases(&rows, o.iterations);
    tables::peer(&peers, o.passes);
    if !slopes.is_empty() {
        slope::print(&slopes);
    }
    Ok(())
}

/// Settles the pile of `n` bodies and measures it; the peer rows go to `peers`, the slope rows
/// to `slopes`.
fn measure_size(
    o: &Options,
    n: usize,
    peers: &mut Vec<PeerRow>,
    slopes: &mut Vec<slope::SlopeRow>,
) -> Result<SizeRow, String> {
    let scene = scene::pile(SEED, n).map_err(|e| e.to_string())?;
    let settle = o.settle.unwrap_or_else(|| options::settle_steps(n));
    let t0 = std::time::Instant::now();
    let mut world = ours::settle(&scene, settle, o.settle_cap, o.trace)?;
    let m = o.measure.unwrap_or_else(|| options::measure_steps(n));
    eprintln!(
        "n={n}: settled {settle} steps in {:.1} s, measuring {m} steps per setting",
        t0.elapsed().as_secs_f64()
    );
    let fixed = ours::run(&mut world, fixed_world(o.iterations), m, Some(o.iterations))?;
    let phases = phases::phases(&world, o.iterations, m.min(20) as u32)?;
    let thesis = if o.thesis {
        Some(ours::run(
            &mut world,
            WorldSettings::default(),
            m.min(20),
            None,
        )?)
    } else {
        None
    };
    if o.rapier {
        let mut pile = peer::settle(&scene, settle, o.iterations);
        peers.push(peer::settled(n, &mut world, &mut pile, o.passes, m)?);
        if o.slope_rounds > 0 {
            let mut position = PgsPositionSolver::default();
            let (mut f64_solver, mut f32_solver) = (
                PgsSolver::default(),
                PgsSolver::with_settings(PgsSettings {
                    precision: Precision::F32,
                    ..PgsSettings::default()
                }),
            );
            let block = o.slope_block.unwrap_or_else(|| slope::block_steps(n));
            slopes.push(slope::measure(
                n,
                &mut world,
                &mut [
                    ("pgs (f64)", &mut f64_solver),
                    ("pgs:precision=f32", &mut f32_solver),
                ],
                &mut position,
                &mut pile,
                o.slope_rounds,
                block,
            )?);
        }
        if o.whole_run {
            peers.push(peer::whole_run(n, &scene, o.passes, o.run_steps)?);
        }
    }
    Ok(SizeRow {
        bodies: n,
        fixed,
        thesis,
        phases,
    })
}
