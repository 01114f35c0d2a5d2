//! Building providers from specs, and the errors of bad specs.

use deepcontact_core::registry::{SpecError, split_spec_list};
use deepcontact_core::{Impulse, WarmStart, WarmStartContext, WarmStartError};

fn registry() -> deepcontact_core::Registry {
    let mut r = deepcontact_core::Registry::empty();
    deepcontact_pgs::register(&mut r);
    deepcontact_warmstart::register(&mut r);
    r
}

#[test]
fn defaults_build_with_their_names_and_help() {
    let r = registry();
    for (spec, name) in [
        ("none", "none"),
        ("builtin", "builtin"),
        ("random", "random"),
        ("random:seed=3,normal_max=5,tangent_max=2", "random"),
        ("bad", "bad"),
        ("bad:value=10", "bad"),
        ("copy", "copy"),
        ("copy:solver=pgs,tolerance=1e-6,max_iterations=500", "copy"),
        ("copy:solver=pgs:block=false", "copy"),
        ("copy:decimals=2", "copy2"),
        ("copy2", "copy2"),
        ("copy0", "copy0"),
        ("copy0:tolerance=1e-5", "copy0"),
    ] {
        let p = r
            .build_provider(spec)
            .unwrap_or_else(|e| panic!("{spec}: {e}"));
        assert_eq!(p.name(), name, "{spec}");
    }
    let names: Vec<_> = r.providers().map(|(n, _)| n).collect();
    for n in ["none", "builtin", "random", "bad", "copy", "copy2", "copy0"] {
        assert!(names.contains(&n), "{n} registered");
    }
    assert!(r.providers().all(|(_, help)| !help.is_empty()));
}

#[test]
fn the_default_list_parses() {
    let r = registry();
    let specs =
        split_spec_list("none,builtin,random:seed=2,normal_max=4,bad,copy,copy2,copy0").unwrap();
    assert_eq!(specs.len(), 7);
    for s in &specs {
        r.provider_from_spec(s).unwrap();
    }
}

#[test]
fn unknown_names_and_parameters_are_typed_errors() {
    let r = registry();
    match r.build_provider("nope") {
        Err(SpecError::UnknownProvider { name, known }) => {
            assert_eq!(name, "nope");
            assert!(
                known.contains("copy0") && known.contains("random"),
                "{known}"
            );
        }
        other => panic!("{:?}", other.map(|p| p.name().to_string())),
    }
    match r.build_provider("random:sed=3") {
        Err(SpecError::UnknownParameter {
            spec,
            param,
            accepted,
        }) => {
            assert_eq!((spec.as_str(), param.as_str()), ("random", "sed"));
            assert!(
                accepted.contains("seed") && accepted.contains("tangent_max"),
                "{accepted}"
            );
        }
        other => panic!("{:?}", other.map(|p| p.name().to_string())),
    }
    assert!(matches!(
        r.build_provider("copy2:decimals=3"),
        Err(SpecError::UnknownParameter { .. })
    ));
    assert!(matches!(
        r.build_provider("none:x=1"),
        Err(SpecError::UnknownParameter { .. })
    ));
    assert!(matches!(
        r.build_provider("copy:solver=nope"),
        Err(SpecError::UnknownSolver { .. })
    ));
    assert!(matches!(
        r.build_provider("sor:start=nope"),
        Err(SpecError::UnknownProvider { .. })
    ));
    assert!(matches!(
        r.build_provider("random:"),
        Err(SpecError::MalformedSpec { .. })
    ));
}

#[test]
fn bad_values_are_typed_errors() {
    let r = registry();
    for (spec, param) in [
        ("random:seed=abc", "seed"),
        ("random:seed=-1", "seed"),
        ("random:normal_max=-1", "normal_max"),
        ("random:normal_min=-1", "normal_min"),
        ("random:tangent_max=inf", "tangent_max"),
        ("bad:value=nan", "value"),
        ("bad:normal=-5", "normal"),
        ("copy:tolerance=-1", "tolerance"),
        ("copy:tolerance=x", "tolerance"),
        ("copy:max_iterations=0", "max_iterations"),
        ("copy:max_iterations=99999999999", "max_iterations"),
        ("copy:decimals=16", "decimals"),
        ("copy:decimals=-1", "decimals"),
        ("copy:solver=pgs:block=maybe", "block"),
    ] {
        match r.build_provider(spec) {
            Err(SpecError::InvalidParameter { param: p, .. }) => {
                assert_eq!(p, param, "{spec}")
            }
            Err(e) => panic!("{spec}: unexpected error {e}"),
            Ok(p) => panic!("{spec}: built {}", p.name()),
        }
    }
}

/// A third-party provider: registered from outside the crate, built by name.
struct Half;

impl WarmStart for Half {
    fn name(&self) -> &str {
        "half"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        for (o, c) in out.iter_mut().zip(ctx.carried_impulses()) {
            *o = Impulse::new(0.5 * c.normal, 0.5 * c.tangent);
        }
        Ok(())
    }
}

#[test]
fn third_party_providers_register_and_build() {
    let mut r = registry();
    r.register_provider("half", "builtin halved", |_, _| Ok(Box::new(Half)));
    // A wrapper around a registered provider, built through the registry it is given.
    r.register_provider("rounded_random", "random rounded", |p, reg| {
        let decimals = p.u64("decimals", 1)? as u32;
        let inner = reg.build_provider("random")?;
        Ok(Box::new(deepcontact_warmstart::Rounded::new(
            inner, decimals,
        )?))
    });
    assert_eq!(r.build_provider("half").unwrap().name(), "half");
    assert_eq!(
        r.build_provider("rounded_random:decimals=3")
            .unwrap()
            .name(),
        "random3"
    );
    assert!(
        r.providers()
            .any(|(n, h)| n == "half" && h == "builtin halved")
    );
}
