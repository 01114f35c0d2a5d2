//! # deepcontact-benches
//!
//! Shared helpers of the criterion benchmarks (`benches/deepcontact.rs`) and of the scaling
//! study (`examples/scaling.rs`):
//!
//! * [`registry`] — every provider and solver this workspace registers (baselines, `grid`,
//!   the CNN providers, and the solvers `pgs`, `psor`, `newton`), and [`provider_cases`], the
//!   spec to benchmark for each registered provider name;
//! * [`Recorder`] — a [`WarmStart`] wrapper that records the islands' contact problems and
//!   carried impulses at chosen steps, and [`record_step`], which runs a pile to a step and
//!   returns a [`Snapshot`] (the world right after that step plus what its warm start saw);
//! * [`SolveScratch`] — solves recorded islands again and again from their recorded warm start
//!   (for solver benchmarks), counting point-iterations so that a time can be turned into
//!   nanoseconds per contact point per iteration;
//! * settings: [`fixed_iterations`], [`fixed_world`], [`settle_world`];
//! * the examples' arithmetic: [`median`] and the [`fnv1a`] hash (with [`FNV_OFFSET`]).
//!
//! Nothing here measures time; the benchmarks and the example do.
#![warn(missing_docs)]

use std::path::PathBuf;

use deepcontact_core::Velocity;

use deepcontact_core::Registry;
use deepcontact_core::scene;
use deepcontact_core::{
    CarriedWarmStart, ContactProblem, CoreError, Impulse, Observation, PositionSettings,
    ResidualNorm, SolveReport, SolverSettings, StepReport, VelocitySolver, WarmStart,
    WarmStartContext, WarmStartError, World, WorldSettings,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Seed of the recorded pile (the first of the thesis's comparison seeds).
pub const SEED: u64 = 12345;

/// Steps of the 100-body thesis pile recorded for the provider benchmarks: early (bodies still
/// falling and landing), middle, late (nearly at rest).
pub const RECORD_STEPS: [u64; 3] = [60, 150, 240];

/// Pile sizes of the solver benchmarks and of the scaling study.
pub const SIZES: [usize; 3] = [100, 1_000, 10_000];

/// The velocity solvers compared.
pub const SOLVERS: [&str; 3] = ["pgs", "psor", "newton"];

/// The full registry ([`deepcontact_experiments::full_registry`]): every provider and solver
/// of this workspace, with their parameters (`psor:omega=1.2` works here as in the CLI).
pub fn registry() -> Registry {
    deepcontact_experiments::full_registry()
}

/// The small test CNN of deepcontact-onnx (`warmstart/onnx/tests/data/tiny.onnx`: conv 3×3,
/// ReLU, average pool, resize, 1×1 convs on the 61 × 61 grids). It stands in for the shipped
/// models when `models/` has none, so that the provider pipeline (grids, inference,
/// read-back) is still measured.
pub fn tiny_model_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../warmstart/onnx/tests/data/tiny.onnx")
}

/// One provider to benchmark: its registry name and the spec that builds it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProviderCase {
    /// Registry name.
    pub name: String,
    /// Spec passed to [`Registry::build_provider`].
    pub spec: String,
}

/// One case per registered provider, in registry order. `onnx` (which needs a model path)
/// runs the small test model ([`tiny_model_path`]), `graph-file` the shipped graph model's
/// file; every other provider runs with its defaults. A case may still fail to build (e.g. `pressure` and `peak` when `models/` holds
/// no exported model): callers skip it and say why.
pub fn provider_cases(registry: &Registry) -> Vec<ProviderCase> {
    registry
        .providers()
        .map(|(name, _)| {
            let spec = match name {
                "onnx" => format!("onnx:path={},name=onnx-tiny", tiny_model_path().display()),
                // The shipped graph model, loaded from its file (what `graph` has built in).
                "graph-file" => format!(
                    "graph-file:path={}",
                    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                        .join("../models/graph.safetensors")
                        .display()
                ),
                _ => name.to_string(),
            };
            ProviderCase {
                name: name.to_string(),
                spec,
            }
        })
        .collect()
}

/// A stop rule that always runs exactly `iterations` iterations (tolerance 0), so that a
/// solve's time divided by `iterations × contact points` is the cost per point per iteration.
pub fn fixed_iterations(iterations: u32) -> SolverSettings {
    SolverSettings {
        max_iterations: iterations,
        tolerance: 0.0,
        norm: ResidualNorm::Infinity,
        min_iterations: 1,
    }
}

/// Thesis world settings with a fixed velocity iteration count and the position pass capped
/// at the same count (it still stops early once the overlap is resolved). This is the
/// setting compared with rapier2d's `num_solver_iterations = iterations`.
pub fn fixed_world(iterations: u32) -> WorldSettings {
    WorldSettings {
        solver: fixed_iterations(iterations),
        position: PositionSettings {
            max_iterations: iterations,
            ..PositionSettings::default()
        },
        ..WorldSettings::default()
    }
}

/// Settings used to settle large piles quickly before recording: the thesis stop rule
/// (tolerance 1e-4, ∞-norm) with the velocity cap lowered to `cap` iterations and the
/// position cap to 20.
pub fn settle_world(cap: u32) -> WorldSettings {
    WorldSettings {
        solver: SolverSettings {
            max_iterations: cap,
            ..SolverSettings::default()
        },
        position: PositionSettings {
            max_iterations: 20,
            ..PositionSettings::default()
        },
        ..WorldSettings::default()
    }
}

/// What a warm start saw for one island: the problem and the impulses carried from the
/// previous step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IslandRecord {
    /// The island's contact problem.
    pub problem: ContactProblem,
    /// Per point, the impulse carried from the previous step (`None` for a new point).
    pub carried: Vec<Option<Impulse>>,
}

/// A [`WarmStart`] wrapper that records every island's [`IslandRecord`] at chosen steps and
/// otherwise behaves exactly as the provider it wraps.
#[derive(Debug)]
pub struct Recorder<W> {
    /// The wrapped provider.
    pub inner: W,
    at: Vec<u64>,
    /// `(step, islands)` for each recorded step, in step order.
    pub records: Vec<(u64, Vec<IslandRecord>)>,
}

impl<W: WarmStart> Recorder<W> {
    /// Wraps `inner`, recording at the steps in `at`.
    pub fn new(inner: W, at: &[u64]) -> Self {
        Self {
            inner,
            at: at.to_vec(),
            records: Vec::new(),
        }
    }
}

impl<W: WarmStart> WarmStart for Recorder<W> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        if self.at.contains(&ctx.step) {
            if self.records.last().is_none_or(|(s, _)| *s != ctx.step) {
                self.records
                    .push((ctx.step, Vec::with_capacity(ctx.island_count)));
            }
            if let Some((_, islands)) = self.records.last_mut() {
                islands.push(IslandRecord {
                    problem: ctx.problem.clone(),
                    carried: ctx.carried.to_vec(),
                });
            }
        }
        self.inner.warm_start(ctx, out)
    }

    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.inner.observe(ctx, seen)
    }
    fn reset(&mut self) {
        self.inner.reset();
    }
    fn diagnostics(&self) -> Vec<(String, deepcontact_core::Real)> {
        self.inner.diagnostics()
    }
    fn passes_spent(&self) -> u32 {
        self.inner.passes_spent()
    }
}

/// A recorded step: the world right after it, and the islands its warm start saw.
#[derive(Debug)]
pub struct Snapshot {
    /// The world after the recorded step (its [`World::last_problems`] are `islands`' problems).
    pub world: World,
    /// Index of the recorded step.
    pub step: u64,
    /// Islands of the step, in the world's island order.
    pub islands: Vec<IslandRecord>,
    /// Report of the recorded step.
    pub report: StepReport,
}

impl Snapshot {
    /// Contact points of the step.
    pub fn contacts(&self) -> usize {
        self.islands.iter().map(|i| i.problem.points.len()).sum()
    }

    /// Dynamic bodies of the world.
    pub fn dynamic_bodies(&self) -> usize {
        self.world
            .bodies()
            .iter()
            .filter(|b| b.is_dynamic())
            .count()
    }

    /// The warm-start context of island `k`, as [`World::step`] builds it (with the world
    /// attached, so that world-level providers such as the CNNs see the whole pile).
    pub fn context(&self, k: usize) -> WarmStartContext<'_> {
        let island = &self.islands[k];
        WarmStartContext::new(
            &island.problem,
            &island.carried,
            self.step,
            self.world.settings().dt,
        )
        .with_world(&self.world, k, self.islands.len())
    }

    /// Runs `provider` on every island of the step, as the world would, writing into `out`
    /// (resized per island). Returns the number of islands whose warm start failed.
    pub fn warm_start_all(&self, provider: &mut dyn WarmStart, out: &mut Vec<Impulse>) -> usize {
        let mut failures = 0;
        for k in 0..self.islands.len() {
            let ctx = self.context(k);
            out.clear();
            out.resize(ctx.problem.points.len(), Impulse::ZERO);
            failures += usize::from(provider.warm_start(&ctx, out).is_err());
        }
        failures
    }
}

/// The thesis pile of `bodies` circles (seed `seed`), stepped with the builtin warm start,
/// PGS and `settings` up to and including step `step`, recording that step.
pub fn record_step(
    seed: u64,
    bodies: usize,
    step: u64,
    settings: WorldSettings,
) -> Result<Snapshot, CoreError> {
    let mut world = scene::pile(seed, bodies)?.build(settings)?;
    let mut recorder = Recorder::new(CarriedWarmStart, &[step]);
    let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
    let mut report = StepReport::default();
    for _ in 0..=step {
        report = world.step(&mut recorder, &mut solver, &mut position)?;
    }
    let islands = recorder
        .records
        .pop()
        .map(|(_, islands)| islands)
        .unwrap_or_default();
    Ok(Snapshot {
        world,
        step,
        islands,
        report,
    })
}

/// Counts of one [`SolveScratch::solve_islands`] call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SolveCounts {
    /// Largest iteration count over the islands.
    pub iterations_max: u32,
    /// `Σ iterations × points` over the islands: the number of point-iterations done.
    pub point_iterations: u64,
}

/// Buffers to solve recorded islands repeatedly, each from its recorded (carried) warm start.
#[derive(Debug, Default)]
pub struct SolveScratch {
    impulses: Vec<Impulse>,
    velocities: Vec<Velocity>,
    /// Report of the last island solved.
    pub report: SolveReport,
}

impl SolveScratch {
    /// Solves every island with `solver` under `settings`, starting each from its carried
    /// impulses (the builtin warm start). Returns the iteration counts.
    pub fn solve_islands(
        &mut self,
        solver: &mut dyn VelocitySolver,
        islands: &[IslandRecord],
        settings: &SolverSettings,
    ) -> Result<SolveCounts, CoreError> {
        let mut counts = SolveCounts::default();
        for island in islands {
            self.impulses.clear();
            self.impulses
                .extend(island.carried.iter().map(|c| c.unwrap_or(Impulse::ZERO)));
            self.velocities.clear();
            self.velocities
                .resize(island.problem.bodies.len(), Velocity::default());
            solver.solve(
                &island.problem,
                settings,
                &mut self.impulses,
                &mut self.velocities,
                &mut self.report,
            )?;
            counts.iterations_max = counts.iterations_max.max(self.report.iterations);
            counts.point_iterations +=
                u64::from(self.report.iterations) * island.problem.points.len() as u64;
        }
        Ok(counts)
    }
}

/// The median of `v`: its middle value, the mean of the two middle ones for an even count
/// (NaN when empty).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// FNV-1a's offset basis: the hash of no bytes, where a hash starts.
pub const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// The 64-bit FNV-1a hash of `bytes`, continuing from `hash` ([`FNV_OFFSET`] to start): the
/// examples' fingerprints of bit patterns and reports.
pub fn fnv1a(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_fnv1a_give_their_textbook_values() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&[]).is_nan());
        // FNV-1a 64 of "a" and of "foobar" (the published test vectors).
        assert_eq!(fnv1a(FNV_OFFSET, b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(FNV_OFFSET, b"foobar"), 0x8594_4171_f739_67e8);
        assert_eq!(
            fnv1a(fnv1a(FNV_OFFSET, b"foo"), b"bar"),
            fnv1a(FNV_OFFSET, b"foobar")
        );
    }

    #[test]
    fn recorder_sees_the_worlds_problems() {
        let snap = record_step(SEED, 100, 60, WorldSettings::default()).unwrap();
        assert_eq!(snap.islands.len(), snap.world.last_problems().len());
        for (a, b) in snap.islands.iter().zip(snap.world.last_problems()) {
            assert_eq!(&a.problem, b);
            assert_eq!(a.carried.len(), b.points.len());
        }
        assert_eq!(snap.contacts(), snap.report.contacts);
    }

    #[test]
    fn fixed_iterations_run_to_the_cap() {
        let snap = record_step(SEED, 100, 60, WorldSettings::default()).unwrap();
        let mut solver = PgsSolver::default();
        let counts = SolveScratch::default()
            .solve_islands(&mut solver, &snap.islands, &fixed_iterations(7))
            .unwrap();
        assert_eq!(counts.iterations_max, 7);
        assert_eq!(counts.point_iterations, 7 * snap.contacts() as u64);
    }

    #[test]
    fn every_provider_has_a_case() {
        let registry = registry();
        let cases = provider_cases(&registry);
        assert_eq!(cases.len(), registry.providers().count());
        for name in ["none", "builtin", "copy", "grid", "onnx", "graph"] {
            assert!(cases.iter().any(|c| c.name == name), "{name}");
        }
        // The providers that need a file get one that loads.
        for name in ["onnx", "graph-file"] {
            let case = cases.iter().find(|c| c.name == name).unwrap();
            assert!(registry.build_provider(&case.spec).is_ok(), "{}", case.spec);
        }
    }
}
