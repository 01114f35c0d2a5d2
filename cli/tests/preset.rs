//! `--preset thesis` reaches the settings of every command that runs worlds, and the default
//! preset leaves them alone.

use clap::Parser;
use deepcontact_cli::{Cli, Command};
use deepcontact_core::{ResidualNorm, WorldSettings};

fn parse(args: &[&str]) -> Command {
    Cli::try_parse_from(std::iter::once("deepcontact").chain(args.iter().copied()))
        .expect("the arguments parse")
        .command
}

/// The original code's stop rules (`Preset::world`).
fn assert_thesis_rules(w: &WorldSettings) {
    assert_eq!(w.solver.norm, ResidualNorm::Contact);
    assert_eq!(w.solver.tolerance, 1e-4);
    assert_eq!(w.solver.max_iterations, 1000);
    assert!(w.position.stop_on_impulse);
    assert_eq!(w.position.max_iterations, 250);
}

#[test]
fn simulate_takes_the_thesis_preset() {
    let Command::Simulate(args) = parse(&[
        "simulate",
        "--preset",
        "thesis",
        "--warm-start",
        "copy2",
        "--seed",
        "12350",
    ]) else {
        panic!("not simulate");
    };
    let c = args.config().unwrap();
    assert_eq!(c.scene, "thesis");
    assert_eq!(c.seed, 12350);
    assert_eq!(c.solver, "pgs:start=raw");
    assert_eq!(
        c.warm_start,
        "copy2:max_iterations=1000,norm=contact,tolerance=0.0001"
    );
    assert_thesis_rules(&c.world);

    // A scene of one's own is kept; the rules still apply.
    let Command::Simulate(args) = parse(&["simulate", "--preset", "thesis", "--scene", "stack"])
    else {
        panic!("not simulate");
    };
    let c = args.config().unwrap();
    assert_eq!(c.scene, "stack");
    assert_thesis_rules(&c.world);

    let Command::Simulate(args) = parse(&["simulate", "--warm-start", "copy2"]) else {
        panic!("not simulate");
    };
    let c = args.config().unwrap();
    assert_eq!((c.scene.as_str(), c.solver.as_str()), ("pile", "pgs"));
    assert_eq!(c.warm_start, "copy2");
    assert_eq!(c.world.solver.norm, ResidualNorm::Infinity);
    assert!(!c.world.position.stop_on_impulse);
}

#[test]
fn generate_takes_the_thesis_preset() {
    let Command::Generate(args) = parse(&["generate", "--preset", "thesis", "--seeds", "3..5"])
    else {
        panic!("not generate");
    };
    let c = args.config().unwrap();
    assert_eq!(c.seeds, vec![3, 4]);
    assert_eq!(c.solver, "pgs:start=raw");
    assert_thesis_rules(&c.world);

    let Command::Generate(args) = parse(&["generate"]) else {
        panic!("not generate");
    };
    let c = args.config().unwrap();
    assert_eq!(c.solver, "pgs");
    assert_eq!(c.world.solver.norm, ResidualNorm::Infinity);
}

#[test]
fn compare_takes_the_thesis_preset() {
    let Command::Compare(args) = parse(&[
        "compare",
        "--preset",
        "thesis",
        "--warm-starts",
        "none,copy0,copy:tolerance=1e-3",
    ]) else {
        panic!("not compare");
    };
    let c = args.config().unwrap();
    assert_eq!(c.scene, "thesis");
    assert_eq!(c.seeds, (12345..12355).collect::<Vec<u64>>());
    let specs: Vec<String> = c.warm_starts.iter().map(ToString::to_string).collect();
    assert_eq!(
        specs,
        [
            "none",
            "copy0:max_iterations=1000,norm=contact,tolerance=0.0001",
            // an oracle with settings of its own keeps them
            "copy:tolerance=1e-3",
        ]
    );
    assert_eq!(c.solvers[0].to_string(), "pgs:start=raw");
    assert_thesis_rules(&c.world);

    // Other worlds under the original's rules (e.g. the perturbed worlds of docs/THESIS.md).
    let Command::Compare(args) = parse(&["compare", "--preset", "thesis", "--scene", "file:w.csv"])
    else {
        panic!("not compare");
    };
    let c = args.config().unwrap();
    assert_eq!(c.scene, "file:w.csv");
    assert_thesis_rules(&c.world);
}
