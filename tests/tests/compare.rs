//! The comparison of deepcontact-experiments (what `deepcontact compare` runs): outputs, columns, and independence from the thread count.

use std::path::PathBuf;

use deepcontact_core::registry::{SpecError, split_spec_list};
use deepcontact_experiments::ExperimentError;
use deepcontact_experiments::compare::{
    self, CURVES_COLUMNS, Config, Results, STEPS_COLUMNS, SUMMARY_COLUMNS, StepRecord,
};
use deepcontact_experiments::seeds::parse_seeds;
use deepcontact_pgs::{PgsPositionSolver, PgsSettings, PgsSolver};

/// Two seeds and enough steps to get past the free fall (the first contacts come near step 33).
fn small(threads: usize) -> Config {
    Config {
        seeds: vec![12345, 12346],
        steps: 45,
        threads,
        progress: false,
        ..Config::default()
    }
}

/// The step records without their wall times.
fn deterministic(r: &StepRecord) -> StepRecord {
    StepRecord {
        warm_start_seconds: 0.0,
        solve_seconds: 0.0,
        step_seconds: 0.0,
        ..r.clone()
    }
}

fn assert_same_numbers(a: &Results, b: &Results) {
    assert_eq!(a.runs.len(), b.runs.len());
    for (ra, rb) in a.runs.iter().zip(&b.runs) {
        assert_eq!(
            (ra.solver, ra.warm_start, ra.seed),
            (rb.solver, rb.warm_start, rb.seed)
        );
        let (sa, sb): (Vec<_>, Vec<_>) = (
            ra.steps.iter().map(deterministic).collect(),
            rb.steps.iter().map(deterministic).collect(),
        );
        assert_eq!(sa, sb, "{} seed {}", a.warm_starts[ra.warm_start], ra.seed);
        assert_eq!(ra.curves, rb.curves);
    }
    assert_eq!(compare::curves(a), compare::curves(b));
    assert_eq!(
        compare::curves_csv(&compare::curves(a)).unwrap(),
        compare::curves_csv(&compare::curves(b)).unwrap()
    );
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("deepcontact-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Steps of the thread tests: by step 80 the pile is one island that outweighs the rest, so
/// the world hands it to the solver itself (not to a fork on one thread) and its sweep is
/// shared; at 45 steps every island is still small.
const THREAD_STEPS: u64 = 80;

/// The most threads that a PGS solver of `settings` ran one island's sweep on over the first
/// run of the thread tests (seed 12345, `builtin`, [`THREAD_STEPS`]), islands on
/// `island_threads` threads: whether the comparison's runs of that solver reach the thread
/// count they ask for.
fn threads_used_on_small(settings: PgsSettings, island_threads: usize) -> usize {
    let mut world = deepcontact_tests::build(&deepcontact_core::scene::pile(12345, 100).unwrap());
    world
        .set_settings(deepcontact_core::WorldSettings {
            island_threads,
            ..deepcontact_core::WorldSettings::default()
        })
        .unwrap();
    let mut warm = deepcontact_experiments::full_registry()
        .build_provider("builtin")
        .unwrap();
    let mut solvers = (PgsSolver::with_settings(settings), PgsPositionSolver::new());
    deepcontact_tests::run_with(
        &mut world,
        warm.as_mut(),
        &mut solvers,
        THREAD_STEPS,
        |_, _| {},
    )
    .unwrap();
    solvers.0.threads_used()
}

#[test]
fn compare_outputs_are_the_same_on_one_two_and_more_threads_than_cores() {
    // Islands side by side and every island through the chunked sweep (`parallel_from=0`,
    // `domains=0`, one batch a chunk so that the pile's colours have chunks for several
    // threads) on 1, 2 and one more thread than the cores (capped at the cores), for a
    // provider of each kind (zeros, carried, random, an oracle, a grid filter, a CNN) on seed
    // 12345: the same step records and curves, and the same as the plain sweep one island
    // after another (∞-norm stop rule). Shared sweeps meet at every colour of every
    // iteration, which on a loaded 2-core machine costs more than the arithmetic: a provider
    // of each kind keeps the test to seconds.
    let cores = deepcontact_tests::cores();
    let config = |solver: &str, island_threads: usize| Config {
        warm_starts: split_spec_list("none,builtin,random,copy,grid,pressure").unwrap(),
        solvers: split_spec_list(solver).unwrap(),
        world: deepcontact_core::WorldSettings {
            island_threads,
            collide_threads: island_threads,
            ..deepcontact_core::WorldSettings::default()
        },
        seeds: vec![12345],
        steps: THREAD_STEPS,
        ..small(2)
    };
    let plain = compare::run_experiment(&config("pgs", 1)).unwrap();
    for threads in [1, 2, cores + 1] {
        let spec = format!("pgs:chunk=1,domains=0,parallel_from=0,threads={threads}");
        let mut chunked = compare::run_experiment(&config(&spec, threads)).unwrap();
        assert_eq!(chunked.solvers, [spec]);
        // The solver's name is the only difference.
        chunked.solvers.clone_from(&plain.solvers);
        assert_same_numbers(&plain, &chunked);
        let settings = PgsSettings {
            threads,
            parallel_min_points: 0,
            domains: 0,
            chunk: 1,
            ..PgsSettings::default()
        };
        assert_eq!(
            threads_used_on_small(settings, threads),
            threads.min(cores),
            "chunked sweep, {threads} threads asked for"
        );
    }
    // Every island in the domain plan (3 domains: 2 side by side): its own Gauss-Seidel
    // order, the same numbers on 1, 2 and more threads than the cores.
    let domains = |threads: usize| {
        let spec = format!("pgs:domains=3,parallel_from=0,threads={threads}");
        let mut run = compare::run_experiment(&config(&spec, threads)).unwrap();
        run.solvers.clone_from(&plain.solvers);
        let settings = PgsSettings {
            threads,
            parallel_min_points: 0,
            domains: 3,
            ..PgsSettings::default()
        };
        assert_eq!(
            threads_used_on_small(settings, threads),
            threads.min(cores).min(2),
            "domain plan, {threads} threads asked for"
        );
        run
    };
    let one = domains(1);
    for threads in [2, cores + 1] {
        assert_same_numbers(&one, &domains(threads));
    }
}

#[test]
fn compare_writes_every_file_and_ignores_the_thread_count() {
    let one = compare::run_experiment(&small(1)).unwrap();
    let two = compare::run_experiment(&small(2)).unwrap();
    // The two seeds are two jobs: with two workers both take one, so the equality below
    // compares a one-worker run with a run that really was shared.
    assert_eq!(one.workers_used, 1);
    assert_eq!(
        two.workers_used,
        2.min(deepcontact_tests::cores()),
        "workers that ran a job out of 2"
    );
    assert_eq!(
        one.warm_starts,
        [
            "none",
            "builtin",
            "random",
            "bad",
            "copy",
            "copy2",
            "copy0",
            "grid",
            "pressure",
            "peak",
            "extrapolate",
            "shock",
            "tail",
            "krylov",
            "best",
            "presolve",
            "sor",
            "graph",
            "learned-sor"
        ]
    );
    assert_same_numbers(&one, &two);

    let providers = one.warm_starts.len();
    let rows = compare::summarize(&one);
    assert_eq!(rows.len(), providers);
    let row = |name: &str| rows.iter().find(|r| r.warm_start == name).unwrap();
    assert!(
        row("none").contact_steps > 5,
        "the pile touches within 45 steps"
    );
    assert!(
        row("copy").mean_iterations <= 3.0,
        "copy: {}",
        row("copy").mean_iterations
    );
    assert!(row("copy").mean_iterations < row("none").mean_iterations);
    assert!(row("bad").mse_normal > row("none").mse_normal);
    assert_eq!(
        row("none").speedup_vs_none.map(|s| (s * 1e9).round()),
        Some(1e9)
    );
    assert!(rows.iter().all(|r| r.fallbacks == 0 && r.steps == 90));

    let dir = scratch_dir("compare");
    let outputs = compare::write_outputs(&one, &dir, true).unwrap();
    // 5 tables, 5 figures and one per provider group (FIGURE_GROUPS), each as PNG and SVG.
    assert_eq!(outputs.files.len(), 5 + 2 * (5 + 8));
    for f in &outputs.files {
        assert!(
            f.is_file() && std::fs::metadata(f).unwrap().len() > 0,
            "{}",
            f.display()
        );
    }
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap();
    let steps = read("steps.csv");
    let mut lines = steps.lines();
    assert_eq!(lines.next(), Some(STEPS_COLUMNS));
    assert_eq!(lines.count(), providers * 2 * 45);
    for col in [
        "contacts",
        "iterations",
        "residual_inf",
        "mse_normal",
        "mse_tangent",
        "fallbacks",
        "warm_start_ms",
        "solve_ms",
        "step_ms",
    ] {
        assert!(
            STEPS_COLUMNS.split(',').any(|c| c == col),
            "steps.csv has {col}"
        );
    }
    let curves = read("curves.csv");
    assert_eq!(curves.lines().next(), Some(CURVES_COLUMNS));
    assert!(
        curves.lines().count() > 10,
        "one row per iteration at least for each warm start"
    );
    let summary = read("summary.csv");
    assert_eq!(summary.lines().next(), Some(SUMMARY_COLUMNS));
    assert_eq!(summary.lines().count(), 1 + providers);
    let md = read("summary.md");
    assert_eq!(md, outputs.summary_md);
    for col in [
        "warm_start",
        "mean_iterations",
        "median_iterations",
        "capped_steps",
        "mean_contacts",
        "warm_start_ms",
        "solve_ms",
        "step_ms",
        "mse_normal",
        "mse_tangent",
        "fallbacks",
        "speedup_vs_none",
        "speedup_vs_builtin",
    ] {
        assert!(
            SUMMARY_COLUMNS.split(',').any(|c| c == col),
            "summary.csv has {col}"
        );
        assert!(md.contains(col), "summary.md has {col}");
    }
    let json = read("summary.json");
    let parsed: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        parsed["summary"].as_array().map(Vec::len),
        Some(providers),
        "{json}"
    );
    // Providers with state report it: tail its measured rate, best its candidates' shares.
    let diagnostics = parsed["diagnostics"].as_array().unwrap();
    assert!(diagnostics.iter().any(|d| d["warm_start"] == "tail"));
    assert!(json.contains("\"seeds\": [") && json.contains("\"copy0\""));
    let png = std::fs::read(dir.join("figures/residual.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(read("figures/mse.svg").starts_with("<svg"));
    // The thesis's groups, each with none and builtin as references.
    for group in [
        "none_builtin",
        "random_bad_copy",
        "copy2_copy0",
        "grid",
        "cnn",
    ] {
        assert!(
            dir.join(format!("figures/iterations_{group}.png"))
                .is_file(),
            "{group}"
        );
    }
    // Nothing half-written is left behind.
    for d in [dir.clone(), dir.join("figures")] {
        for entry in std::fs::read_dir(d).unwrap() {
            let name = entry.unwrap().file_name().to_string_lossy().into_owned();
            assert!(
                !name.starts_with('.') && !name.contains(".tmp"),
                "leftover {name}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn several_solvers_get_a_solver_column_and_their_own_figures() {
    let config = Config {
        warm_starts: split_spec_list("none,builtin").unwrap(),
        solvers: split_spec_list("pgs,pgs:block=false").unwrap(),
        seeds: vec![12345],
        steps: 36,
        threads: 2,
        progress: false,
        ..Config::default()
    };
    let results = compare::run_experiment(&config).unwrap();
    let rows = compare::summarize(&results);
    assert_eq!(rows.len(), 4);
    assert_eq!(rows[2].solver, "pgs:block=false");
    let dir = scratch_dir("compare-solvers");
    let outputs = compare::write_outputs(&results, &dir, true).unwrap();
    assert!(outputs.summary_md.contains("| solver | warm_start |"));
    assert!(dir.join("figures/iterations_pgs_block_false.png").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_third_party_provider_is_compared_through_its_registry() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use deepcontact_core::{Impulse, Observation, WarmStart, WarmStartContext, WarmStartError};
    /// `bad:value=25` under its own name, counting the islands it starts.
    struct HalfBad(Box<dyn WarmStart>, Arc<AtomicUsize>);
    impl WarmStart for HalfBad {
        fn name(&self) -> &str {
            "half_bad"
        }
        fn warm_start(
            &mut self,
            ctx: &WarmStartContext<'_>,
            out: &mut [Impulse],
        ) -> Result<(), WarmStartError> {
            self.1.fetch_add(1, Ordering::Relaxed);
            self.0.warm_start(ctx, out)
        }
        fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
            self.0.observe(ctx, seen);
        }
    }
    let calls = Arc::new(AtomicUsize::new(0));
    let mut registry = deepcontact_experiments::full_registry();
    let counter = Arc::clone(&calls);
    registry.register_provider("half_bad", "bad halved", move |_, r| {
        Ok(Box::new(HalfBad(
            r.build_provider("bad:value=25")?,
            Arc::clone(&counter),
        )))
    });
    // Seed 7's first contact comes at step 34: 40 steps give the provider six steps.
    let config = Config {
        warm_starts: split_spec_list("none,half_bad").unwrap(),
        seeds: vec![7],
        steps: 40,
        progress: false,
        ..Config::default()
    };
    let results = compare::run_experiment_with(&config, &registry).unwrap();
    assert_eq!(results.warm_starts, ["none", "half_bad"]);
    let calls = calls.load(Ordering::Relaxed);
    assert!(calls >= 6, "half_bad started {calls} islands");
    // Its starts of 25 N·s, far from the solved impulses, show in the records: every step
    // with contacts has a warm-start error of hundreds, where zeros have a small one.
    for run in &results.runs {
        let name = &results.warm_starts[run.warm_start];
        let touching: Vec<_> = run.steps.iter().filter(|r| r.contacts > 0).collect();
        assert!(
            touching.len() >= 6,
            "{name}: {} steps with contacts",
            touching.len()
        );
        for r in touching {
            let far = r.mse_normal > 100.0;
            assert_eq!(
                far,
                name == "half_bad",
                "{name}, step {}: {}",
                r.step,
                r.mse_normal
            );
        }
    }
}

#[test]
fn a_learned_providers_state_is_read_back_through_the_comparison() {
    use deepcontact_core::{Impulse, Observation, WarmStart, WarmStartContext, WarmStartError};
    /// Counts the islands it observed: its "learned state".
    struct Counting(f64);
    impl WarmStart for Counting {
        fn name(&self) -> &str {
            "counting"
        }
        fn warm_start(
            &mut self,
            _: &WarmStartContext<'_>,
            _: &mut [Impulse],
        ) -> Result<(), WarmStartError> {
            Ok(())
        }
        fn observe(&mut self, _: &WarmStartContext<'_>, _: &Observation<'_>) {
            self.0 += 1.0;
        }
        fn diagnostics(&self) -> Vec<(String, f64)> {
            vec![("islands_seen".into(), self.0)]
        }
    }
    let mut registry = deepcontact_experiments::full_registry();
    registry.register_provider("counting", "counts islands", |_, _| {
        Ok(Box::new(Counting(0.0)))
    });
    let config = Config {
        warm_starts: split_spec_list("none,counting").unwrap(),
        seeds: vec![12345],
        steps: 45,
        progress: false,
        ..Config::default()
    };
    let results = compare::run_experiment_with(&config, &registry).unwrap();
    assert!(results.runs[0].diagnostics.is_empty());
    let islands: usize = results.runs[1].steps.iter().map(|s| s.islands).sum();
    assert_eq!(
        results.runs[1].diagnostics,
        [("islands_seen".to_string(), islands as f64)]
    );
    let dir = scratch_dir("diagnostics");
    compare::write_outputs(&results, &dir, false).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(
        json["diagnostics"][0]["values"]["islands_seen"],
        islands as f64
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_a_typed_error() {
    let err = |config: Config| {
        compare::run_experiment(&Config {
            progress: false,
            ..config
        })
        .unwrap_err()
    };
    let base = || Config {
        seeds: vec![1],
        steps: 1,
        ..Config::default()
    };
    assert!(matches!(
        err(Config {
            warm_starts: split_spec_list("nope").unwrap(),
            ..base()
        }),
        ExperimentError::Spec(SpecError::UnknownProvider { .. })
    ));
    assert!(matches!(
        err(Config {
            solvers: split_spec_list("nope").unwrap(),
            ..base()
        }),
        ExperimentError::Spec(SpecError::UnknownSolver { .. })
    ));
    assert!(matches!(
        err(Config {
            warm_starts: split_spec_list("none,none").unwrap(),
            ..base()
        }),
        ExperimentError::Invalid(_)
    ));
    assert!(matches!(
        err(Config { steps: 0, ..base() }),
        ExperimentError::Invalid(_)
    ));
    assert!(matches!(
        err(Config {
            seeds: vec![],
            ..base()
        }),
        ExperimentError::Invalid(_)
    ));
    let mut bad_world = base();
    bad_world.world.solver.max_iterations = 0;
    assert!(matches!(err(bad_world), ExperimentError::Core(_)));

    assert_eq!(parse_seeds("12345..12355").unwrap().len(), 10);
    assert_eq!(parse_seeds("3..=5").unwrap(), [3, 4, 5]);
    assert_eq!(parse_seeds("4, 2,9").unwrap(), [4, 2, 9]);
    assert_eq!(parse_seeds("8").unwrap(), [8]);
    for bad in ["", "5..5", "a..b", "1..x", "-1", "1,,x", "1,1"] {
        assert!(
            matches!(parse_seeds(bad), Err(ExperimentError::Invalid(_))),
            "{bad}"
        );
    }
}

/// `same_problems`: every provider solves the driver's problem of each step (the same
/// contacts), the driver's own numbers are those of the ordinary comparison, and the other
/// providers' differ from theirs (they no longer follow their own trajectories).
#[test]
fn same_problems_solves_every_start_on_the_drivers_world() {
    let base = Config {
        warm_starts: split_spec_list("none,builtin,sor").unwrap(),
        seeds: vec![12345],
        steps: 60,
        threads: 1,
        progress: false,
        ..Config::default()
    };
    let own = compare::run_experiment(&base).unwrap();
    let same = compare::run_experiment(&Config {
        same_problems: Some("builtin".into()),
        ..base.clone()
    })
    .unwrap();
    let records = |r: &Results, w: usize| -> Vec<StepRecord> {
        r.group(0, w)[0].steps.iter().map(deterministic).collect()
    };
    assert_eq!(
        records(&own, 1),
        records(&same, 1),
        "the driver's run changed"
    );
    let contacts = |r: &Results, w: usize| -> Vec<usize> {
        r.group(0, w)[0].steps.iter().map(|s| s.contacts).collect()
    };
    for w in [0, 2] {
        assert_eq!(contacts(&same, w), contacts(&same, 1), "warm start {w}");
        assert_ne!(records(&own, w), records(&same, w), "warm start {w}");
    }
    assert!(contacts(&same, 1).iter().any(|&c| c > 0));
    let md = compare::summary_md(&same, &compare::summarize(&same));
    assert!(md.contains("Same problems"), "{md}");

    let err = compare::run_experiment(&Config {
        same_problems: Some("graph".into()),
        ..base
    })
    .unwrap_err();
    assert!(
        matches!(&err, ExperimentError::Invalid(m) if m.contains("`graph`")),
        "{err}"
    );
}

#[test]
fn a_world_built_in_code_runs_through_compare_as_a_registered_scene_and_is_named() {
    use deepcontact_core::scene::Scene;
    use deepcontact_core::{BodyDesc, ShapeDesc, Vector};
    let mut registry = deepcontact_experiments::full_registry();
    registry.register_scene(
        "tiny-stack",
        "count unit boxes on the ground",
        |p, _seed| {
            let unit = ShapeDesc::Cuboid {
                half_width: 0.5,
                half_height: 0.5,
            };
            let ground = ShapeDesc::Cuboid {
                half_width: 3.0,
                half_height: 0.5,
            };
            let mut bodies = vec![BodyDesc::fixed(ground, Vector::new(0.0, -0.5))];
            for i in 0..p.u64("count", 2)? {
                bodies.push(BodyDesc::dynamic(
                    unit.clone(),
                    Vector::new(0.0, 0.5 + i as f64),
                ));
            }
            Ok(Scene {
                name: "tiny-stack".into(),
                bodies,
                min: Vector::new(-3.0, -1.0),
                max: Vector::new(3.0, 4.0),
            })
        },
    );
    let config = Config {
        warm_starts: Config::with_warm_starts("none,builtin")
            .unwrap()
            .warm_starts,
        scene_spec: Some("tiny-stack:count=3".parse().unwrap()),
        seeds: vec![1],
        steps: 30,
        progress: false,
        ..Config::default()
    };
    let results = compare::run_experiment_with(&config, &registry).unwrap();
    let rows = compare::summarize(&results);
    // The boxes stand on the ground from the first step: two points per manifold or so.
    assert!(
        rows.iter()
            .all(|r| r.contact_steps > 20 && r.mean_contacts >= 4.0)
    );
    let md = compare::summary_md(&results, &rows);
    assert!(
        md.contains("Scene `tiny-stack:count=3`, seed 1, 30 steps each"),
        "summary.md names the scene: {md}"
    );
}
