//! How a researcher starts: write a `WarmStart`, register it next to the baselines, and
//! compare mean velocity iterations on the thesis pile.
//!
//! ```text
//! cargo run --release -p deepcontact-warmstart --example custom_warm_start
//! ```
//!
//! The provider here is "builtin scaled by 0.9": last step's impulses, damped a little.

use deepcontact_core::scene;
use deepcontact_core::{Impulse, WarmStart, WarmStartContext, WarmStartError, WorldSettings};
use deepcontact_core::{Registry, SpecError};
use deepcontact_pgs::PgsPositionSolver;

/// Last step's impulses (matched by contact id), multiplied by a factor.
struct ScaledBuiltin {
    factor: f64,
}

impl WarmStart for ScaledBuiltin {
    fn name(&self) -> &str {
        "scaled"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        if ctx.carried.len() != out.len() {
            return Err(WarmStartError::WrongLength {
                expected: out.len(),
                got: ctx.carried.len(),
            });
        }
        for (o, c) in out.iter_mut().zip(ctx.carried_impulses()) {
            *o = Impulse::new(self.factor * c.normal, self.factor * c.tangent);
        }
        Ok(())
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Register the new provider beside the baselines, with a parameter: `scaled:factor=0.8`.
    let mut registry = Registry::empty();
    deepcontact_pgs::register(&mut registry);
    deepcontact_warmstart::register(&mut registry);
    registry.register_provider("scaled", "builtin times factor (default 0.9)", |p, _| {
        let factor = p.f64("factor", 0.9)?;
        if !(0.0..=10.0).contains(&factor) {
            return Err(SpecError::InvalidParameter {
                spec: "scaled".into(),
                param: "factor".into(),
                value: factor.to_string(),
                reason: "must be in [0, 10]".into(),
            });
        }
        Ok(Box::new(ScaledBuiltin { factor }))
    });

    let seeds = 12345..12348;
    let steps = 150;
    println!("pile of 100 circles, seeds {seeds:?}, {steps} steps, PGS to 1e-4");
    println!(
        "{:<10} {:>16} {:>14}",
        "provider", "mean iterations", "contact steps"
    );
    for spec in ["none", "builtin", "scaled"] {
        let (mut iterations, mut contact_steps) = (0u64, 0u64);
        for seed in seeds.clone() {
            let mut world = scene::pile(seed, 100)?.build(WorldSettings::default())?;
            let mut provider = registry.build_provider(spec)?;
            let mut solver = registry.build_solver("pgs")?;
            let mut position = PgsPositionSolver::new();
            for _ in 0..steps {
                let report = world.step(&mut provider, &mut solver, &mut position)?;
                // Steps without contacts (free fall at the start) do no iterations: skip them.
                if report.contacts > 0 {
                    iterations += u64::from(report.velocity_iterations);
                    contact_steps += 1;
                }
            }
        }
        let mean = iterations as f64 / contact_steps.max(1) as f64;
        println!("{spec:<10} {mean:>16.1} {contact_steps:>14}");
    }
    Ok(())
}
