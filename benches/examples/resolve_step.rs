//! One step of a pile re-solved from several starts: the pile of `--seed` is stepped
//! `--step` times with the `--drive` provider, then step `--step` is run on a copy of that
//! world once per listed provider (solved by `--solver`, default `pgs`; the world before it is
//! driven by `--drive-solver`, default `pgs`), and each run's velocity iterations, natural residual and
//! capped islands are printed, with the provider's diagnostics. It tells whether a hard step is hard from every start (the
//! solver's problem) or only from one (the start's).
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example resolve_step -- \
//!     --seed 228 --step 133 --drive sor builtin sor none copy
//! ```

use deepcontact_core::{WorldSettings, scene};
use deepcontact_pgs::PgsPositionSolver;

fn main() {
    if let Err(e) = run() {
        eprintln!("resolve_step: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let (mut seed, mut step, mut drive, mut bodies) =
        (12345u64, 150u64, "builtin".to_string(), 100);
    let mut solver_spec = "pgs".to_string();
    let mut drive_solver = "pgs".to_string();
    let mut providers = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--seed" => seed = value()?.parse()?,
            "--step" => step = value()?.parse()?,
            "--bodies" => bodies = value()?.parse()?,
            "--drive" => drive = value()?,
            "--solver" => solver_spec = value()?,
            "--drive-solver" => drive_solver = value()?,
            "-h" | "--help" => {
                println!(
                    "usage: resolve_step [--seed 12345] [--step 150] [--bodies 100] [--drive builtin] [--drive-solver pgs] [--solver pgs] PROVIDER..."
                );
                return Ok(());
            }
            _ => providers.push(a),
        }
    }
    if providers.is_empty() {
        return Err("name at least one provider to re-solve the step with".into());
    }
    let registry = deepcontact_experiments::full_registry();
    let mut driver = registry.build_provider(&drive)?;
    let mut solver = registry.build_solver(&drive_solver)?;
    let mut position = PgsPositionSolver::new();
    let mut world = scene::by_name("pile", seed, bodies)?.build(WorldSettings::default())?;
    for _ in 0..step {
        world.step(driver.as_mut(), solver.as_mut(), &mut position)?;
    }
    println!(
        "pile {bodies}, seed {seed}, step {step} of `{drive}`'s world (driven by `{drive_solver}`), solved by `{solver_spec}`:"
    );
    for spec in &providers {
        let mut copy = world.clone();
        let mut provider = registry.build_provider(spec)?;
        let mut resolver = registry.build_solver(&solver_spec)?;
        let r = copy.step(provider.as_mut(), resolver.as_mut(), &mut position)?;
        println!(
            "  {spec:<28} {:>5} iterations, natural residual {:.3e} N·s, {} of {} islands capped",
            r.velocity_iterations, r.natural_residual, r.capped_islands, r.islands
        );
        for (key, value) in provider.diagnostics() {
            println!("      {key} = {value}");
        }
    }
    Ok(())
}
