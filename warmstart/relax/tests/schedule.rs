//! The learned schedules: their file, and `learned-sor` sweeping by them under a pass budget.

use std::path::Path;

use deepcontact_core::{Real, Registry, WarmStart, WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};
use deepcontact_relax::{RelaxError, SCHEDULE_FORMAT, schedules_from_json, shipped_schedules};

/// The natural residual of every step of a 100-circle pile (seed 100) under `budget`, as bits,
/// and the provider's passes on the steps with contacts.
fn run(provider: &mut dyn WarmStart, budget: Option<u32>) -> (Vec<u64>, Vec<u32>) {
    let settings = WorldSettings {
        budget,
        ..WorldSettings::default()
    };
    let mut world = scene::by_name("pile", 100, 100)
        .unwrap()
        .build(settings)
        .unwrap();
    let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
    let (mut bits, mut passes) = (Vec::new(), Vec::new());
    for _ in 0..80 {
        let r = world.step(provider, &mut solver, &mut position).unwrap();
        bits.push(r.natural_residual.to_bits());
        if r.contacts > 0 {
            passes.push(provider.passes_spent());
        }
    }
    assert!(passes.len() > 30, "{} steps with contacts", passes.len());
    (bits, passes)
}

fn registry() -> Registry {
    let mut registry = Registry::empty();
    deepcontact_warmstart::register(&mut registry);
    deepcontact_relax::register(&mut registry);
    registry
}

#[test]
fn shipped_schedules_cover_the_budgets_they_were_fitted_for() {
    let table = shipped_schedules().unwrap();
    let budgets: Vec<u32> = table.entries().iter().map(|&(k, _)| k).collect();
    assert_eq!(budgets, [4, 8, 16, 32]);
    for (k, s) in table.entries() {
        assert!(!s.is_empty(), "K = {k}");
        assert!(s.factors().iter().all(|f| (1.0..2.0).contains(f)), "{s:?}");
    }
}

#[test]
fn learned_sor_sweeps_by_the_schedule_of_its_budget() {
    let registry = registry();
    let factors = |k: u32| -> String {
        let table = shipped_schedules().unwrap();
        let (_, s) = table.entries().iter().find(|&&(b, _)| b == k).unwrap();
        s.factors()
            .iter()
            .map(Real::to_string)
            .collect::<Vec<_>>()
            .join("/")
    };
    let build = |spec: &str| registry.build_provider(spec).unwrap();
    let learned = run(build("learned-sor").as_mut(), Some(8));
    let twin = run(
        build(&format!("sor:schedule={}", factors(8))).as_mut(),
        Some(8),
    );
    assert_eq!(
        learned, twin,
        "learned-sor at K = 8 is sor with the K = 8 schedule"
    );
    assert!(learned.1.iter().any(|&p| p > 1), "the sweeps ran");
    // Without the schedules: the policy's factors, capped, another trajectory.
    let capped = run(build("learned-sor:schedules=none").as_mut(), Some(8));
    assert_ne!(capped.0, learned.0);
    // Without a budget the schedules are not used: the tolerance mode's bits.
    assert_eq!(
        run(build("learned-sor").as_mut(), None),
        run(build("learned-sor:schedules=none").as_mut(), None)
    );
}

#[test]
fn a_bad_schedule_file_is_a_typed_error() {
    let path = Path::new("bad.json");
    let file = |format: &str, schedules: serde_json::Value| {
        serde_json::json!({"format": format, "schedules": schedules}).to_string()
    };
    let cases = [
        (file("other/1", serde_json::json!({"8": [1.5]})), "format"),
        ("not json".to_string(), "format"),
        (file(SCHEDULE_FORMAT, serde_json::json!({})), "schedule"),
        (
            file(SCHEDULE_FORMAT, serde_json::json!({"1": [1.5]})),
            "schedule",
        ),
        (
            file(SCHEDULE_FORMAT, serde_json::json!({"x": [1.5]})),
            "schedule",
        ),
        (
            file(SCHEDULE_FORMAT, serde_json::json!({"8": [2.5]})),
            "schedule",
        ),
        (
            file(SCHEDULE_FORMAT, serde_json::json!({"8": []})),
            "schedule",
        ),
    ];
    for (text, kind) in cases {
        match (schedules_from_json(&text, path), kind) {
            (Err(RelaxError::Format { .. }), "format") => {}
            (Err(RelaxError::Schedule { reason, .. }), "schedule") => assert!(!reason.is_empty()),
            (other, _) => panic!("{text}: {other:?}"),
        }
    }
    let good = file(
        SCHEDULE_FORMAT,
        serde_json::json!({"16": [1.8, 1.1], "8": [1.6]}),
    );
    let table = schedules_from_json(&good, path).unwrap();
    assert_eq!(table.for_pass_budget(7).unwrap().factors(), &[1.6]);
    assert_eq!(table.for_pass_budget(15).unwrap().factors(), &[1.8, 1.1]);
    let registry = registry();
    match registry.build_provider("learned-sor:schedules=/no/such/file.json") {
        Err(e) => assert!(e.to_string().contains("no/such/file"), "{e}"),
        Ok(_) => panic!("a missing schedule file was accepted"),
    }
}
