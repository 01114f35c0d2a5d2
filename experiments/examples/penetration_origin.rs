//! Where a scene's deepest penetration comes from: points on the step they first touch (no
//! impulse carried to them, so no solve has acted on them yet) or points the solver already
//! held the step before. The suite reports the deepest penetration at the start of a step over
//! every point; a warm start can only change the second kind.
//!
//! Each scene runs under a pass budget as `deepcontact compare --budgets K` runs it
//! ([`SuiteConfig::cell_config`]: the solver's tolerance 0 and cap K, the provider's passes
//! counted, 3 position passes), with
//! each warm start on its own trajectory, and prints per warm start the deepest penetration
//! (m) over all steps and seeds of the new points and of the held ones, and the overall step
//! and seed where the deepest one was.
//!
//! ```sh
//! cargo run --release -p deepcontact-experiments --example penetration_origin -- \
//!     --scenes pile,box-pile,polygon-pile --budgets 8,16 --seeds 12345..12355 \
//!     --warm-starts builtin,learned-sor [--prediction 0.002]
//! ```
//!
//! `--prediction` keeps points up to that separation (m) as contacts, so that a point is
//! solved before it touches (the suite's worlds keep touching points only).

use deepcontact_core::{
    Impulse, Observation, Real, WarmStart, WarmStartContext, WarmStartError, WorldSettings,
};
use deepcontact_experiments::full_registry;
use deepcontact_experiments::suite::{Budget, SuiteConfig};
use deepcontact_pgs::PgsPositionSolver;

/// A warm start that measures the depth of its island's points before it hands them to the
/// provider it wraps (whose impulses and passes it passes on unchanged).
struct Origin {
    inner: Box<dyn WarmStart>,
    /// Deepest penetration (m) of a new point, and of a held one, so far.
    new_max: Real,
    held_max: Real,
    /// The deepest of either (m), and its step.
    deepest: (Real, u64),
}

impl WarmStart for Origin {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        for (p, carried) in ctx.problem.points.iter().zip(ctx.carried) {
            let depth = (-p.separation).max(0.0);
            let slot = if carried.is_some() {
                &mut self.held_max
            } else {
                &mut self.new_max
            };
            *slot = slot.max(depth);
            if depth > self.deepest.0 {
                self.deepest = (depth, ctx.step);
            }
        }
        self.inner.warm_start(ctx, out)
    }

    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.inner.observe(ctx, seen);
    }

    fn reset(&mut self) {
        self.inner.reset();
    }

    fn passes_spent(&self) -> u32 {
        self.inner.passes_spent()
    }
    fn diagnostics(&self) -> Vec<(String, deepcontact_core::Real)> {
        self.inner.diagnostics()
    }
}

/// The value after `flag` on the command line, or `default`.
fn arg(flag: &str, default: &str) -> String {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == flag)
        .and_then(|i| args.get(i + 1).cloned())
        .unwrap_or_else(|| default.to_string())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let registry = full_registry();
    let suite = SuiteConfig::default();
    let scenes = deepcontact_core::registry::split_spec_list(&arg(
        "--scenes",
        "pile,box-pile,polygon-pile",
    ))?;
    let budgets: Vec<u32> = arg("--budgets", "8,16")
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let seeds = deepcontact_experiments::seeds::parse_seeds(&arg("--seeds", "12345..12355"))?;
    let warm_starts = arg("--warm-starts", "builtin,learned-sor");
    let steps: u64 = arg("--steps", "250").parse()?;
    // Contacts kept up to this separation (m; the suite's worlds: 0).
    let prediction: Real = arg("--prediction", "0").parse()?;
    println!(
        "scene | K | warm start | deepest, new points (m) | deepest, held points (m) | deepest: seed, step"
    );
    for scene in &scenes {
        for &k in &budgets {
            for spec in warm_starts.split(',') {
                let (mut new_max, mut held_max, mut deepest) =
                    (0.0 as Real, 0.0 as Real, (0.0, 0, 0));
                for &seed in &seeds {
                    // The suite's world under a budget of `k` passes, contacts kept up to `prediction`.
                    let settings = WorldSettings {
                        prediction,
                        ..suite.cell_config(scene, Budget::Passes(k)).world
                    };
                    let mut world = registry.scene_from_spec(scene, seed)?.build(settings)?;
                    let mut origin = Origin {
                        inner: registry.build_provider(spec)?,
                        new_max: 0.0,
                        held_max: 0.0,
                        deepest: (0.0, 0),
                    };
                    let mut solver = registry.build_solver("pgs")?;
                    let mut position = PgsPositionSolver::new();
                    for _ in 0..steps {
                        world.step(&mut origin, solver.as_mut(), &mut position)?;
                    }
                    new_max = new_max.max(origin.new_max);
                    held_max = held_max.max(origin.held_max);
                    if origin.deepest.0 > deepest.0 {
                        deepest = (origin.deepest.0, seed, origin.deepest.1);
                    }
                }
                println!(
                    "{scene} | {k} | {spec} | {new_max:.3e} | {held_max:.3e} | {}, {}",
                    deepest.1, deepest.2
                );
            }
        }
    }
    Ok(())
}
