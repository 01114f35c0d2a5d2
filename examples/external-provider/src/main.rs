//! A warm-start provider written outside the deepcontact workspace:
//! 1. it implements `WarmStart` (carried impulses, damped, plus a hydrostatic guess for new
//!    contacts from gravity);
//! 2. registers it next to the built-in providers and runs the full comparison (tables and
//!    figures) through `deepcontact-experiments`;
//! 3. embeds the PGS solver on a hand-built problem, a stack of three boxes, with no world.
//!
//! `cargo run --release` here (CI runs it with `-- --quick`).

use deepcontact_core::Velocity;

use deepcontact_core::{
    ContactProblem, Impulse, Observation, PointDesc, ProblemBody, ProviderInfo, Real, SolveReport,
    SolverSettings, Vector, VelocitySolver, WarmStart, WarmStartContext, WarmStartError,
};
use deepcontact_experiments::{compare, full_registry};

/// Carried impulses times `scale`; a new contact starts from the weight of body B over the
/// step (`m g dt`), an estimate of the load it will carry.
struct DampedCarry {
    scale: Real,
    /// Islands whose start the world replaced by zeros (read back through `diagnostics`).
    fallbacks: usize,
}

impl WarmStart for DampedCarry {
    fn name(&self) -> &str {
        "damped"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let g = ctx.gravity.norm();
        for (i, (o, p)) in out.iter_mut().zip(&ctx.problem.points).enumerate() {
            *o = if let Some(c) = ctx.carried[i] {
                Impulse::new(self.scale * c.normal, self.scale * c.tangent)
            } else {
                let inv_mass = ctx.problem.bodies[p.body_b as usize].inv_mass;
                let weight = if inv_mass > 0.0 {
                    g * ctx.dt / inv_mass
                } else {
                    0.0
                };
                Impulse::new(weight, 0.0)
            };
        }
        Ok(())
    }

    fn observe(&mut self, _ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.fallbacks += usize::from(seen.fell_back);
    }

    fn reset(&mut self) {
        self.fallbacks = 0;
    }

    fn diagnostics(&self) -> Vec<(String, Real)> {
        vec![("fallbacks".into(), self.fallbacks as Real)]
    }
}

/// Three unit boxes (1 kg) on the ground, each falling at one step of gravity.
fn three_box_stack() -> ContactProblem {
    let mut problem = ContactProblem::new();
    let ground = problem.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
    let falling = Vector::new(0.0, -0.0981);
    let mut below = ground;
    for i in 0..3 {
        let centre = Vector::new(0.0, 0.5 + Real::from(i));
        let body = problem.add_body(ProblemBody::dynamic(
            centre,
            0.0,
            falling,
            0.0,
            1.0,
            1.0 / 6.0,
        ));
        problem.begin_manifold();
        for x in [-0.5, 0.5] {
            let at = Vector::new(x, Real::from(i));
            problem
                .add_point(&PointDesc::new(below, body, at, Vector::new(0.0, 1.0)))
                .expect("a valid point");
        }
        below = body;
    }
    problem
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let quick = std::env::args().any(|a| a == "--quick");

    // 1-2. The comparison with our provider beside the baselines (about ten lines).
    let mut registry = full_registry();
    registry.register_provider(
        "damped",
        ProviderInfo::new("carried impulses times scale=0.95; new contacts from m g dt"),
        |p, _| {
            let scale = p.f64("scale", 0.95)?;
            Ok(Box::new(DampedCarry {
                scale,
                fallbacks: 0,
            }) as Box<dyn WarmStart>)
        },
    );
    let mut config = compare::Config::with_warm_starts("none,builtin,damped")?;
    if quick {
        config.seeds = vec![12345, 12346];
        config.steps = 60;
        config.progress = false;
    }
    let results = compare::run_experiment_with(&config, &registry)?;
    let out = std::env::temp_dir().join("external-provider-results");
    let outputs = compare::write_outputs(&results, &out, !quick)?;
    println!("{}", outputs.summary_md);
    println!("wrote {} files to {}", outputs.files.len(), out.display());

    // 3. The solver embedded on a hand-built problem, started by our provider.
    let problem = three_box_stack();
    let carried = vec![None; problem.len()];
    let ctx = WarmStartContext::new(&problem, &carried, 0, 0.01);
    let mut provider = DampedCarry {
        scale: 0.95,
        fallbacks: 0,
    };
    let mut impulses = vec![Impulse::ZERO; problem.len()];
    provider.warm_start(&ctx, &mut impulses)?;
    let start = impulses.clone();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    let mut solver = deepcontact_pgs::PgsSolver::new();
    let settings = SolverSettings {
        tolerance: 1e-9,
        ..SolverSettings::default()
    };
    solver.solve(
        &problem,
        &settings,
        &mut impulses,
        &mut velocities,
        &mut report,
    )?;
    provider.observe(&ctx, &Observation::new(&start, &impulses, false, &report));
    let total: Real = impulses.iter().map(|i| i.normal).sum();
    println!(
        "three-box stack: {} iterations, natural residual {:.1e}, total normal impulse {total:.4} N·s, \
         diagnostics {:?}",
        report.iterations,
        report.natural_residual,
        provider.diagnostics()
    );
    // The ground carries three boxes: each step it must stop them (0.0981 m/s each) and hold
    // their weight, so the bottom manifold's impulse is 3 × 0.0981 kg·m/s.
    let bottom = impulses[0].normal + impulses[1].normal;
    if (bottom - 3.0 * 0.0981).abs() > 1e-3
        || velocities.iter().skip(1).any(|v| v.linear.norm() > 1e-6)
    {
        return Err(
            format!("unexpected solution: bottom {bottom}, velocities {velocities:?}").into(),
        );
    }
    Ok(())
}
