//! `deepcontact grid-roundtrip`: the thesis's Table 1 (section 5.5).
//!
//! For every grid spacing `res` and support radius `h` in {0.125, 0.25, 0.5}: the mean
//! absolute difference, after particles → grid → particles (SPH both ways, poly6), of
//! the body masses and of the contact normal impulses, over piles of seeds
//! `first_seed..first_seed + worlds` settled for `steps` steps with the builtin warm start.
//! Means are pooled over all bodies (contacts) of all worlds. Worlds run in parallel
//! (rayon), but each world's sums are kept apart and added in seed order, so the result
//! does not depend on the number of threads.
//!
//! Outputs (in `--out`, each written to a temporary file and renamed into place):
//! `grid_roundtrip.csv` and `grid_roundtrip.md`.

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::Args;
use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};
use deepcontact_grid::{Kernel, RoundTrip, RoundTripSums, TABLE1_VALUES, THESIS_TABLE1};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};
use rayon::prelude::*;

use crate::common::CliError;

/// Options of `grid-roundtrip`.
#[derive(Debug, Clone, Args)]
pub struct GridRoundtripArgs {
    /// Number of piles (seeds `first_seed..first_seed + worlds`).
    #[arg(long, default_value_t = 25)]
    pub worlds: u64,
    /// Steps each pile is simulated before the round trip.
    #[arg(long, default_value_t = 200)]
    pub steps: u64,
    /// First seed.
    #[arg(long, default_value_t = 0)]
    pub first_seed: u64,
    /// Circles per pile (the box is scaled to keep the density).
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Output directory.
    #[arg(long, default_value = "results")]
    pub out: PathBuf,
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

fn grid_err(seed: u64, e: deepcontact_grid::GridError) -> CliError {
    CliError::Usage(format!("seed {seed}: grid transfer: {e}"))
}

/// Settles one pile and measures every pair on it.
pub fn world_sums(seed: u64, args: &GridRoundtripArgs) -> Result<Vec<RoundTripSums>, CliError> {
    let scene = scene::pile(seed, args.bodies)?;
    let mut world = scene.build(WorldSettings::default())?;
    let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..args.steps {
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
pub fn table(args: &GridRoundtripArgs) -> Result<Vec<Row>, CliError> {
    if args.worlds == 0 {
        return Err(CliError::Usage("--worlds must be at least 1".into()));
    }
    let seeds: Vec<u64> = (0..args.worlds)
        .map(|i| args.first_seed.wrapping_add(i))
        .collect();
    let per_world: Vec<Result<Vec<RoundTripSums>, CliError>> = seeds
        .par_iter()
        .map(|&seed| world_sums(seed, args))
        .collect();
    let mut rows: Vec<Row> = pairs()
        .into_iter()
        .map(|(res, h)| Row {
            res,
            h,
            sums: RoundTripSums::default(),
            thesis: THESIS_TABLE1
                .iter()
                .find(|t| t.0 == res && t.1 == h)
                .map(|t| (t.2, t.3)),
        })
        .collect();
    for world in per_world {
        for (row, sums) in rows.iter_mut().zip(world?) {
            row.sums.add(&sums);
        }
    }
    Ok(rows)
}

/// The table as CSV (one row per pair, thesis values alongside).
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "res,h,body_mean_abs_diff,contact_mean_abs_diff,bodies,contacts,lost_bodies,lost_contacts,thesis_body,thesis_contact\n",
    );
    for r in rows {
        let (tb, tc) = r.thesis.map_or((String::new(), String::new()), |(b, c)| {
            (b.to_string(), c.to_string())
        });
        s.push_str(&format!(
            "{},{},{:.6e},{:.6e},{},{},{},{},{tb},{tc}\n",
            r.res,
            r.h,
            r.sums.body_mean(),
            r.sums.contact_mean(),
            r.sums.bodies,
            r.sums.contacts,
            r.sums.lost_bodies,
            r.sums.lost_contacts
        ));
    }
    s
}

/// The table as markdown, with the setup.
pub fn markdown(rows: &[Row], args: &GridRoundtripArgs) -> String {
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
        args.worlds,
        args.first_seed,
        args.first_seed.wrapping_add(args.worlds),
        args.bodies,
        args.steps
    );
    for r in rows {
        let (tb, tc) = r.thesis.map_or(("–".into(), "–".into()), |(b, c)| {
            (format!("{b:.4}"), format!("{c:.4}"))
        });
        s.push_str(&format!(
            "| {} | {} | {:.4} | {tb} | {:.4} | {tc} | {} | {} |\n",
            r.res,
            r.h,
            r.sums.body_mean(),
            r.sums.contact_mean(),
            r.sums.lost_bodies,
            r.sums.lost_contacts
        ));
    }
    s
}

fn write_atomic(path: &Path, text: &str) -> Result<(), CliError> {
    let io = |source| CliError::Io {
        path: path.display().to_string(),
        source,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let written = std::fs::File::create(&tmp).and_then(|mut f| {
        f.write_all(text.as_bytes())?;
        f.sync_all()
    });
    if let Err(e) = written.and_then(|_| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    Ok(())
}

/// Runs `grid-roundtrip`: prints the table and writes CSV + markdown into `--out`.
pub fn run(args: GridRoundtripArgs) -> Result<(), CliError> {
    let rows = table(&args)?;
    let md = markdown(&rows, &args);
    print!("{md}");
    std::fs::create_dir_all(&args.out).map_err(|source| CliError::Io {
        path: args.out.display().to_string(),
        source,
    })?;
    let csv_path = args.out.join("grid_roundtrip.csv");
    let md_path = args.out.join("grid_roundtrip.md");
    write_atomic(&csv_path, &csv(&rows))?;
    write_atomic(&md_path, &md)?;
    println!("\nwrote {} and {}", csv_path.display(), md_path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_table_has_the_thesis_pattern() {
        let args = GridRoundtripArgs {
            worlds: 2,
            steps: 30,
            first_seed: 0,
            bodies: 100,
            out: std::env::temp_dir(),
        };
        let rows = table(&args).unwrap();
        assert_eq!(rows.len(), 9);
        let get = |res: f64, h: f64| rows.iter().find(|r| r.res == res && r.h == h).unwrap();
        assert_eq!(get(0.25, 0.25).sums.bodies, 200);
        assert!(get(0.25, 0.25).sums.body_mean() < 1e-4);
        assert!(get(0.5, 0.125).sums.body_mean() > get(0.25, 0.125).sums.body_mean());
        assert!(rows.iter().all(|r| r.thesis.is_some()));
        let csv = csv(&rows);
        assert_eq!(csv.lines().count(), 10);
        assert!(markdown(&rows, &args).contains("| 0.25 | 0.5 |"));
        let bad = GridRoundtripArgs { worlds: 0, ..args };
        assert!(table(&bad).is_err());
    }
}
