//! The thesis's Table 1 (section 5.5; what `deepcontact grid-roundtrip` runs).
//!
//! For every grid spacing `res` and support radius `h` in {0.125, 0.25, 0.5}: the mean
//! absolute difference, after particles → grid → particles (SPH both ways, poly6), of
//! the body masses and of the contact normal impulses, over piles of seeds
//! `first_seed..first_seed + worlds` settled for `steps` steps with the builtin warm start.
//! Means are pooled over all bodies (contacts) of all worlds. Worlds run in parallel
//! (rayon), but each world's sums are kept apart and added in seed order, so the result
//! does not depend on the number of threads.
//!
//! Outputs ([`write_roundtrip`], each written to a temporary file and renamed into place):
//! `grid_roundtrip.csv` and `grid_roundtrip.md`.

use std::path::{Path, PathBuf};

use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};
use deepcontact_grid::{Kernel, RoundTrip, RoundTripSums, TABLE1_VALUES, THESIS_TABLE1};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};
use rayon::prelude::*;

use crate::ExperimentError;
use crate::atomic::write_atomic;

/// What to measure. [`RoundtripConfig::default`] is the table of `docs/`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoundtripConfig {
    /// Number of piles, seeds `first_seed..first_seed + worlds` (default 25, at most
    /// [`crate::seeds::MAX_SEEDS`]).
    pub worlds: u64,
    /// Steps each pile is simulated before the round trip (default 200).
    pub steps: u64,
    /// First seed (default 0).
    pub first_seed: u64,
    /// Circles per pile, the box scaled to keep the density (default 100).
    pub bodies: usize,
    /// Settings the piles settle under (default: the thesis defaults; the thesis preset uses
    /// the original's `Step(0.01, 10, 10)`, see [`crate::preset::Preset::roundtrip`]).
    pub world: WorldSettings,
    /// Average the per-world means (the original's Table 1) instead of pooling all bodies and
    /// contacts of all worlds (default false).
    pub per_world_average: bool,
}

impl Default for RoundtripConfig {
    fn default() -> Self {
        Self {
            worlds: 25,
            steps: 200,
            first_seed: 0,
            bodies: 100,
            world: WorldSettings::default(),
            per_world_average: false,
        }
    }
}

/// One row of the table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Grid spacing (m).
    pub res: f64,
    /// Kernel support radius (m).
    pub h: f64,
    /// Sums over all worlds.
    pub sums: RoundTripSums,
    /// Mean absolute body-mass difference: pooled, or the mean of the per-world means with
    /// [`RoundtripConfig::per_world_average`].
    pub body_mean: f64,
    /// Mean absolute contact normal-impulse difference, likewise.
    pub contact_mean: f64,
    /// The thesis's (body, contact) means for this pair, if it has one.
    pub thesis: Option<(f64, f64)>,
}

/// The `(res, h)` pairs of Table 1, in the thesis's order.
pub fn pairs() -> Vec<(f64, f64)> {
    TABLE1_VALUES
        .iter()
        .flat_map(|&res| TABLE1_VALUES.iter().map(move |&h| (res, h)))
        .collect()
}

fn grid_err(seed: u64, e: deepcontact_grid::GridError) -> ExperimentError {
    ExperimentError::Grid {
        seed,
        reason: e.to_string(),
    }
}

/// Settles one pile and measures every pair on it.
pub fn world_sums(
    seed: u64,
    config: &RoundtripConfig,
) -> Result<Vec<RoundTripSums>, ExperimentError> {
    let scene = scene::pile(seed, config.bodies)?;
    let mut world = scene.build(config.world)?;
    let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..config.steps {
        world.step(&mut CarriedWarmStart, &mut solver, &mut position)?;
    }
    pairs()
        .into_iter()
        .map(|(res, h)| {
            let mut rt = RoundTrip::new(scene.min, scene.max, res, h, Kernel::Poly6)
                .map_err(|e| grid_err(seed, e))?;
            rt.world(&world).map_err(|e| grid_err(seed, e))
        })
        .collect()
}

/// Runs every world (in parallel) and adds their sums in seed order.
pub fn table(config: &RoundtripConfig) -> Result<Vec<Row>, ExperimentError> {
    if config.worlds == 0 {
        return Err(ExperimentError::Invalid("worlds must be at least 1".into()));
    }
    if config.worlds > crate::seeds::MAX_SEEDS as u64 {
        return Err(ExperimentError::Invalid(format!(
            "--worlds {} is above the ceiling of {} worlds (seeds::MAX_SEEDS)",
            config.worlds,
            crate::seeds::MAX_SEEDS
        )));
    }
    let seeds: Vec<u64> = (0..config.worlds)
        .map(|i| config.first_seed.wrapping_add(i))
        .collect();
    let per_world: Vec<Result<Vec<RoundTripSums>, ExperimentError>> = seeds
        .par_iter()
        .map(|&seed| world_sums(seed, config))
        .collect();
    let mut rows: Vec<Row> = pairs()
        .into_iter()
        .map(|(res, h)| Row {
            res,
            h,
            sums: RoundTripSums::default(),
            body_mean: 0.0,
            contact_mean: 0.0,
            thesis: THESIS_TABLE1
                .iter()
                .find(|t| t.0 == res && t.1 == h)
                .map(|t| (t.2, t.3)),
        })
        .collect();
    let n = per_world.len() as f64;
    for world in per_world {
        for (row, sums) in rows.iter_mut().zip(world?) {
            row.sums.add(&sums);
            if config.per_world_average {
                row.body_mean += sums.body_mean() / n;
                row.contact_mean += sums.contact_mean() / n;
            }
        }
    }
    if !config.per_world_average {
        for row in &mut rows {
            (row.body_mean, row.contact_mean) = (row.sums.body_mean(), row.sums.contact_mean());
        }
    }
    Ok(rows)
}

#[derive(serde::Serialize)]
struct CsvRow {
    res: f64,
    h: f64,
    body_mean_abs_diff: f64,
    contact_mean_abs_diff: f64,
    bodies: usize,
    contacts: usize,
    lost_bodies: usize,
    lost_contacts: usize,
    thesis_body: Option<f64>,
    thesis_contact: Option<f64>,
}

/// The table as CSV (one row per pair, thesis values alongside; empty where the thesis has
/// none), written with the `csv` crate.
pub fn csv(rows: &[Row]) -> Result<String, ExperimentError> {
    let bytes = crate::csv_bytes(rows.iter().map(|r| CsvRow {
        res: r.res,
        h: r.h,
        body_mean_abs_diff: r.body_mean,
        contact_mean_abs_diff: r.contact_mean,
        bodies: r.sums.bodies,
        contacts: r.sums.contacts,
        lost_bodies: r.sums.lost_bodies,
        lost_contacts: r.sums.lost_contacts,
        thesis_body: r.thesis.map(|t| t.0),
        thesis_contact: r.thesis.map(|t| t.1),
    }))?;
    String::from_utf8(bytes).map_err(|e| ExperimentError::Invalid(format!("csv: {e}")))
}

/// The table as markdown, with the setup.
pub fn markdown(rows: &[Row], config: &RoundtripConfig) -> String {
    let (bodies, contacts) = rows
        .first()
        .map_or((0, 0), |r| (r.sums.bodies, r.sums.contacts));
    let mut s = format!(
        "# Grid round trip (thesis Table 1)\n\n\
         Mean absolute difference after particles → grid → particles (SPH both ways, poly6 kernel, \
         weights normalised per particle and per node), pooled over {} piles (seeds {}..{}) of {} circles \
         settled for {} steps with the builtin warm start: {bodies} bodies and {contacts} contact points \
         in all. A body's mass is π/4 ≈ 0.7854.\n\n\
         | res | h | body mass diff | thesis | contact normal impulse diff | thesis | lost bodies | lost contacts |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|\n",
        config.worlds,
        config.first_seed,
        config.first_seed.wrapping_add(config.worlds),
        config.bodies,
        config.steps
    );
    for r in rows {
        let (tb, tc) = r.thesis.map_or(("–".into(), "–".into()), |(b, c)| {
            (format!("{b:.4}"), format!("{c:.4}"))
        });
        s.push_str(&format!(
            "| {} | {} | {:.4} | {tb} | {:.4} | {tc} | {} | {} |\n",
            r.res, r.h, r.body_mean, r.contact_mean, r.sums.lost_bodies, r.sums.lost_contacts
        ));
    }
    s
}

/// Writes `grid_roundtrip.csv` and `grid_roundtrip.md` into `dir` (created if missing);
/// returns their paths.
pub fn write_roundtrip(
    rows: &[Row],
    config: &RoundtripConfig,
    dir: &Path,
) -> Result<[PathBuf; 2], ExperimentError> {
    std::fs::create_dir_all(dir).map_err(|e| ExperimentError::io(dir, e))?;
    let csv_path = dir.join("grid_roundtrip.csv");
    let md_path = dir.join("grid_roundtrip.md");
    write_atomic(&csv_path, csv(rows)?.as_bytes())?;
    write_atomic(&md_path, markdown(rows, config).as_bytes())?;
    Ok([csv_path, md_path])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_table_has_the_thesis_pattern() {
        let config = RoundtripConfig {
            worlds: 2,
            steps: 30,
            first_seed: 0,
            bodies: 100,
            ..RoundtripConfig::default()
        };
        let rows = table(&config).unwrap();
        assert_eq!(rows.len(), 9);
        let get = |res: f64, h: f64| rows.iter().find(|r| r.res == res && r.h == h).unwrap();
        assert_eq!(get(0.25, 0.25).sums.bodies, 200);
        assert!(get(0.25, 0.25).sums.body_mean() < 1e-4);
        assert!(get(0.5, 0.125).sums.body_mean() > get(0.25, 0.125).sums.body_mean());
        assert!(rows.iter().all(|r| r.thesis.is_some()));
        assert!(rows.iter().all(|r| r.body_mean == r.sums.body_mean()));
        // The original's settling and per-world averages: every world has 100 bodies, so the
        // body means agree with the pooled ones; the run differs (10 iterations per step).
        let thesis = crate::preset::Preset::Thesis.roundtrip(config);
        let t = table(&thesis).unwrap();
        let tget = |res: f64, h: f64| t.iter().find(|r| r.res == res && r.h == h).unwrap();
        assert!((tget(0.5, 0.125).body_mean - tget(0.5, 0.125).sums.body_mean()).abs() < 1e-12);
        assert!(tget(0.25, 0.25).contact_mean < 1e-3);
        let csv = csv(&rows).unwrap();
        assert_eq!(csv.lines().count(), 10);
        assert!(markdown(&rows, &config).contains("| 0.25 | 0.5 |"));
        let bad = RoundtripConfig {
            worlds: 0,
            ..config
        };
        assert!(table(&bad).is_err());
    }

    #[test]
    fn regression_a_hundred_million_worlds_hung_before_any_output() {
        let huge = RoundtripConfig {
            worlds: 100_000_000,
            ..RoundtripConfig::default()
        };
        let e = table(&huge).unwrap_err().to_string();
        assert!(e.contains("ceiling of 1000000 worlds"), "{e}");
    }
}
