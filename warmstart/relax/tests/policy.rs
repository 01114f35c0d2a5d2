//! The learned relaxation policy: its features, its ω, its files, and `learned-sor` in a
//! world.

use std::path::Path;

use deepcontact_core::{
    Impulse, Real, Registry, SpecError, WarmStart, WarmStartContext, WarmStartError, World,
    WorldSettings, scene,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};
use deepcontact_relax::{FEATURES, FORMAT, RelaxError, RelaxationPolicy, learned_sor};
use deepcontact_warmstart::{Relaxation, RelaxedConfig, RelaxedWarmStart};

/// A settled-enough 40-body pile: 80 steps with builtin (contacts from step ~35 on).
fn pile() -> World {
    let mut world = scene::by_name("pile", 12345, 40)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..80 {
        world
            .step(
                &mut deepcontact_core::CarriedWarmStart,
                &mut solver,
                &mut position,
            )
            .unwrap();
    }
    world
}

/// Positions and angles of every body after `steps` more steps with `provider`, as bits.
fn run(mut world: World, provider: &mut dyn WarmStart, steps: usize) -> Vec<u64> {
    let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..steps {
        world.step(provider, &mut solver, &mut position).unwrap();
    }
    world
        .bodies()
        .iter()
        .flat_map(|b| [b.position.x, b.position.y, b.angle].map(Real::to_bits))
        .collect()
}

fn policy_json(weights: &[Real], span: Real, format: &str, features: &[&str]) -> String {
    serde_json::json!({
        "format": format, "features": features, "weights": weights, "omega_span": span,
    })
    .to_string()
}

#[test]
fn an_intercept_only_policy_is_sor_with_that_omega_bit_for_bit() {
    let policy = RelaxationPolicy::new([0.8, 0.0, 0.0, 0.0, 0.0, 0.0], 0.95).unwrap();
    let omega = policy.omega(&[1.0, 0.5, 1.0, 0.0, 1.0, 0.2]);
    assert!((omega - (1.0 + 0.95 / (1.0 + (-0.8f64).exp()))).abs() < 1e-15);
    let world = pile();
    let config = RelaxedConfig {
        omega,
        ..RelaxedConfig::default()
    };
    let mut sor = RelaxedWarmStart::new(config).unwrap();
    let mut learned = learned_sor("learned-sor", policy, config).unwrap();
    let (a, b) = (
        run(world.clone(), &mut sor, 40),
        run(world.clone(), &mut learned, 40),
    );
    assert_eq!(a, b);
    // And a policy that does look at the features takes another path.
    let varied = RelaxationPolicy::new([0.8, 0.0, 0.0, 0.0, -2.0, 1.0], 0.95).unwrap();
    let mut other = learned_sor("x", varied, config).unwrap();
    assert_ne!(run(world, &mut other, 40), a);
}

#[test]
fn features_follow_their_definitions_and_every_omega_is_in_range() {
    let world = pile();
    let problem = world
        .last_problems()
        .iter()
        .max_by_key(|p| p.len())
        .unwrap();
    let n = problem.len();
    assert!(n > 5, "{n} points");
    let mut carried: Vec<Option<Impulse>> = vec![None; n];
    carried[0] = Some(Impulse::new(0.3, 0.1));
    carried[1] = Some(Impulse::new(-1.0, 0.0));
    let ctx = WarmStartContext::new(problem, &carried, 81, 0.01);
    for i in 0..n {
        let g = RelaxationPolicy::features(&ctx, i);
        let p = &problem.points[i];
        assert_eq!(g[0], 1.0);
        assert_eq!(g[1], p.normal.y.abs());
        let load = match i {
            0 => (1.0 + 3.0 as Real).ln(),
            _ => 0.0, // new, or a negative carried normal impulse
        };
        assert_eq!(g[2], load, "point {i}");
        assert_eq!(g[3], if i < 2 { 0.0 } else { 1.0 });
        let fixed = |k: u32| problem.bodies[k as usize].inv_mass == 0.0;
        assert_eq!(
            g[4],
            if fixed(p.body_a) || fixed(p.body_b) {
                1.0
            } else {
                0.0
            }
        );
        assert_eq!(g[5], (n as Real).ln() - 4.0);
    }
    assert!(
        (0..n).any(|i| RelaxationPolicy::features(&ctx, i)[4] == 1.0),
        "the pile rests on the ground"
    );
    let mut shipped = RelaxationPolicy::shipped().unwrap();
    let mut omegas = Vec::new();
    shipped.omegas(&ctx, &mut omegas).unwrap();
    assert_eq!(omegas.len(), n);
    assert!(omegas.iter().all(|w| (1.0..1.95).contains(w)), "{omegas:?}");
}

#[test]
fn a_factor_outside_one_to_two_is_a_typed_error_not_a_blow_up() {
    #[derive(Debug)]
    struct TooLarge;
    impl Relaxation for TooLarge {
        fn omegas(
            &mut self,
            ctx: &WarmStartContext<'_>,
            out: &mut Vec<Real>,
        ) -> Result<(), WarmStartError> {
            out.clear();
            out.resize(ctx.problem.len(), 2.5);
            Ok(())
        }
    }
    let world = pile();
    let problem = &world.last_problems()[0];
    let carried = vec![None; problem.len()];
    let ctx = WarmStartContext::new(problem, &carried, 81, 0.01);
    let mut provider = RelaxedWarmStart::new(RelaxedConfig::default())
        .unwrap()
        .with_relaxation("bad", Box::new(TooLarge));
    let mut out = vec![Impulse::ZERO; problem.len()];
    let err = provider.warm_start(&ctx, &mut out).unwrap_err();
    assert!(err.to_string().contains("outside [1, 2)"), "{err}");
}

#[test]
fn bad_policy_files_are_typed_errors() {
    let here = Path::new("x.json");
    let ok = policy_json(&[0.0; 6], 0.95, FORMAT, &FEATURES);
    assert!(RelaxationPolicy::from_json(&ok, here).is_ok());
    let cases = [
        (policy_json(&[0.0; 6], 0.95, "other/1", &FEATURES), "format"),
        (policy_json(&[0.0; 5], 0.95, FORMAT, &FEATURES), "5 weights"),
        (policy_json(&[0.0; 6], 1.0, FORMAT, &FEATURES), "omega_span"),
        (
            policy_json(&[0.0; 6], 0.95, FORMAT, &FEATURES[..5]),
            "features",
        ),
        ("{".to_string(), "EOF"),
        (ok.replace("0.0]", "1e999]"), "number"),
    ];
    for (text, needle) in cases {
        let err = RelaxationPolicy::from_json(&text, here).unwrap_err();
        assert!(
            matches!(err, RelaxError::Format { .. } | RelaxError::Policy { .. }),
            "{err:?}"
        );
        assert!(err.to_string().contains(needle), "{err} lacks {needle}");
    }
    assert!(RelaxationPolicy::new([Real::NAN, 0.0, 0.0, 0.0, 0.0, 0.0], 0.5).is_err());
    let missing = RelaxationPolicy::from_file(Path::new("/nonexistent/policy.json")).unwrap_err();
    assert!(matches!(missing, RelaxError::Io { .. }), "{missing:?}");

    let mut registry = Registry::empty();
    deepcontact_relax::register(&mut registry);
    assert_eq!(
        registry
            .build_provider("learned-sor:name=mine")
            .unwrap()
            .name(),
        "mine"
    );
    assert!(matches!(
        registry.build_provider("learned-sor:path=/nonexistent/policy.json"),
        Err(SpecError::Build { .. })
    ));
    assert!(matches!(
        registry.build_provider("learned-sor:sweeps=0"),
        Err(SpecError::InvalidParameter { .. })
    ));
}
