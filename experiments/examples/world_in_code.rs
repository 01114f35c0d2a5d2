//! A world built in code, run through the experiment library: a tower of boxes registered as
//! a scene (a closure, like a provider), compared over three warm starts with the tables and
//! figures written, then stepped once more by hand.
//!
//! ```sh
//! cargo run --release -p deepcontact-experiments --example world_in_code -- [OUT]
//! ```
//!
//! `OUT` (default: `world-in-code/` in the system's temporary directory) receives what
//! `deepcontact compare` writes: `summary.md`, `summary.csv`, `steps.csv`, the figures.

use deepcontact_core::scene::Scene;
use deepcontact_core::{BodyDesc, CarriedWarmStart, ShapeDesc, Vector, WorldSettings};
use deepcontact_experiments::{compare, full_registry};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// A tower of `count` unit boxes (1 kg) on a 10 m ground box.
fn tower(count: u64) -> Scene {
    let ground = ShapeDesc::Cuboid {
        half_width: 5.0,
        half_height: 0.5,
    };
    let unit = ShapeDesc::Cuboid {
        half_width: 0.5,
        half_height: 0.5,
    };
    let mut bodies = vec![BodyDesc::fixed(ground, Vector::new(0.0, -0.5))];
    for i in 0..count {
        bodies.push(BodyDesc::dynamic(
            unit.clone(),
            Vector::new(0.0, 0.5 + i as f64),
        ));
    }
    Scene {
        name: "tower".into(),
        bodies,
        min: Vector::new(-5.0, -1.0),
        max: Vector::new(5.0, count as f64 + 1.0),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| std::env::temp_dir().join("world-in-code"), Into::into);

    // The scene, registered by name with a parameter: `tower:count=12`.
    let mut registry = full_registry();
    registry.register_scene("tower", "unit boxes on the ground; count=10", |p, _seed| {
        Ok(tower(p.u64("count", 10)?))
    });

    // The comparison: one summary row per warm start, the files of `deepcontact compare`.
    let mut config = compare::Config::with_warm_starts("none,builtin,sor")?;
    config.scene_spec = Some("tower:count=12".parse()?);
    config.seeds = vec![1];
    config.steps = 200;
    let results = compare::run_experiment_with(&config, &registry)?;
    let outputs = compare::write_outputs(&results, &out, true)?;
    println!("{}", outputs.summary_md);
    println!("wrote {} files to {}", outputs.files.len(), out.display());

    // The same world stepped by hand: the position solver to pass is PGS's position pass,
    // whatever the velocity solver (the soft step moves its islands itself and it skips them).
    let mut world = tower(12).build(WorldSettings::default())?;
    let (mut warm, mut solver, mut position) =
        (CarriedWarmStart, PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..200 {
        world.step(&mut warm, &mut solver, &mut position)?;
    }
    let top = world.bodies().last().map_or(0.0, |b| b.position.y);
    println!("after 200 steps the top box is at {top:.3} m (11.5 m when built)");
    Ok(())
}
