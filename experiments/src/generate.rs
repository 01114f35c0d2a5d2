//! Training data for the CNN warm starts (what `deepcontact generate` writes).
//!
//! Simulates the thesis pile for each seed (builtin warm start, the chosen solver) and writes one
//! safetensors file per seed, `pile-<seed>.safetensors`, holding for every step with contacts the
//! input grids `[6, 61, 61]`, the label grids `[2, 61, 61]` (from the step's final impulses) and
//! the raw bodies and contact points. The format is documented in `models/README.md`.
//! Seeds run in parallel (rayon); each file depends only on its seed, so the output is
//! deterministic. `--shard K/N` keeps the seeds `i` with `i mod N == K`; seeds whose file already
//! exists and is complete are skipped; files are written to a temporary name and renamed.

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use deepcontact_core::{
    CarriedWarmStart, ContactId, Impulse, PositionSolver, Registry, WarmStart, WarmStartContext,
    WarmStartError, World, WorldSettings,
};
use deepcontact_onnx::features::{GridFeatures, GridLayout};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use safetensors::tensor::{Dtype, TensorView};

use crate::ExperimentError;
use crate::atomic::write_atomic_with;

/// Version of the training-data format (the `format_version` metadata field).
pub const FORMAT_VERSION: &str = "1";
/// The `format` metadata field.
pub const FORMAT: &str = "deepcontact-train";

/// What to generate. [`GenerateConfig::default`] is the training and validation set.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerateConfig {
    /// Seeds, one file each (default 0 to 109: training 0–99, validation 100–109).
    pub seeds: Vec<u64>,
    /// Output directory, created if missing (default `data`).
    pub out: PathBuf,
    /// Steps per seed (default 250).
    pub steps: u64,
    /// Circles in the pile (default 100).
    pub bodies: usize,
    /// Worker threads; 0 (default) means one per core.
    pub threads: usize,
    /// Regenerate files that already exist and are complete (default false).
    pub force: bool,
    /// Show a progress bar on stderr (default true).
    pub progress: bool,
    /// Velocity solver spec of the simulations (default `pgs`).
    pub solver: String,
    /// World settings of the simulations (default: the thesis's).
    pub world: WorldSettings,
}

impl Default for GenerateConfig {
    fn default() -> Self {
        Self {
            seeds: (0..110).collect(),
            out: PathBuf::from("data"),
            steps: 250,
            bodies: 100,
            threads: 0,
            force: false,
            progress: true,
            solver: "pgs".into(),
            world: WorldSettings::default(),
        }
    }
}

/// What [`run_generate`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GenerateOutcome {
    /// Seed files written.
    pub written: usize,
    /// Seeds skipped because their file was already complete.
    pub skipped: usize,
}

/// Parses `K/N` (keep the seeds `i` with `i mod N == K`).
pub fn parse_shard(text: &str) -> Result<(u64, u64), ExperimentError> {
    let bad =
        || ExperimentError::Invalid(format!("--shard `{text}`: expected K/N with 0 <= K < N"));
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let (k, n): (u64, u64) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || k >= n {
        return Err(bad());
    }
    Ok((k, n))
}

/// The file of one seed.
pub fn seed_file(out: &Path, seed: u64) -> PathBuf {
    out.join(format!("pile-{seed:05}.safetensors"))
}

/// Builtin warm start that also records, at the first island of each step, the world as the
/// providers see it, and the warm start of every point.
struct StepCapture {
    features: GridFeatures,
    error: Option<String>,
    /// Whether the current step has been snapshotted.
    snap: Option<u64>,
    input: Vec<f32>,
    bodies: Vec<(f32, [f32; 2], [f32; 2], f32)>,
    warm: Vec<(ContactId, Impulse)>,
}

impl WarmStart for StepCapture {
    fn name(&self) -> &str {
        "builtin"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        CarriedWarmStart.warm_start(ctx, out)?;
        if self.snap != Some(ctx.step) {
            self.snap = Some(ctx.step);
            self.warm.clear();
            if let Some(world) = ctx.world {
                if let Err(e) = self.features.encode_world(world, &mut self.input) {
                    self.error = Some(e.to_string());
                }
                self.bodies.clear();
                self.bodies.extend(world.bodies().iter().map(|b| {
                    (
                        b.mass as f32,
                        [b.position.x as f32, b.position.y as f32],
                        [b.linear_velocity.x as f32, b.linear_velocity.y as f32],
                        b.angular_velocity as f32,
                    )
                }));
            }
        }
        self.warm.extend(
            ctx.problem
                .points
                .iter()
                .map(|p| p.id)
                .zip(out.iter().copied()),
        );
        Ok(())
    }
}

/// Everything recorded for one seed, column-wise.
#[derive(Default)]
struct Columns {
    steps: Vec<i64>,
    inputs: Vec<f32>,
    labels: Vec<f32>,
    body_mass: Vec<f32>,
    body_position: Vec<f32>,
    body_velocity: Vec<f32>,
    body_angular_velocity: Vec<f32>,
    contact_offsets: Vec<i64>,
    contact_position: Vec<f32>,
    contact_bodies: Vec<i32>,
    contact_normal: Vec<f32>,
    contact_warm_start: Vec<f32>,
    contact_impulse: Vec<f32>,
}

fn lookup(sorted: &[(ContactId, Impulse)], id: &ContactId) -> Impulse {
    sorted
        .binary_search_by(|(k, _)| k.cmp(id))
        .map(|i| sorted[i].1)
        .unwrap_or(Impulse::ZERO)
}

fn simulate_seed(
    seed: u64,
    config: &GenerateConfig,
    registry: &Registry,
    layout: &GridLayout,
    on_step: &(dyn Fn() + Sync),
) -> Result<Columns, ExperimentError> {
    let scene = deepcontact_core::scene::pile(seed, config.bodies)?;
    let mut world: World = scene.build(config.world)?;
    let mut solver = registry.build_solver(&config.solver)?;
    let mut position = deepcontact_pgs::PgsPositionSolver::default();
    let position: &mut dyn PositionSolver = &mut position;
    let grid_err = |e: &dyn std::fmt::Display| ExperimentError::Grid {
        seed,
        reason: e.to_string(),
    };
    let features = GridFeatures::new(layout.clone()).map_err(|e| grid_err(&e))?;
    let mut labeler = GridFeatures::new(layout.clone()).map_err(|e| grid_err(&e))?;
    let mut rec = StepCapture {
        features,
        error: None,
        snap: None,
        input: vec![0.0; layout.input_len()],
        bodies: Vec::new(),
        warm: Vec::new(),
    };
    let mut c = Columns {
        contact_offsets: vec![0],
        ..Columns::default()
    };
    let mut label = vec![0.0f32; layout.output_len()];
    for _ in 0..config.steps {
        let report = world.step(&mut rec, solver.as_mut(), position)?;
        on_step();
        if report.contacts == 0 || rec.snap != Some(report.step) {
            continue;
        }
        if let Some(e) = rec.error.take() {
            return Err(grid_err(&e));
        }
        rec.warm.sort_unstable_by_key(|a| a.0);
        let finals = world.contacts();
        let raw = world.raw_contacts();
        labeler
            .encode_world_labels(&world, &mut label)
            .map_err(|e| grid_err(&e))?;
        c.steps.push(report.step as i64);
        c.inputs.extend_from_slice(&rec.input);
        c.labels.extend_from_slice(&label);
        if c.body_mass.is_empty() {
            c.body_mass.extend(rec.bodies.iter().map(|b| b.0));
        }
        for (_, p, v, w) in &rec.bodies {
            c.body_position.extend(p);
            c.body_velocity.extend(v);
            c.body_angular_velocity.push(*w);
        }
        for r in raw {
            let (w, f) = (lookup(&rec.warm, &r.id), lookup(finals, &r.id));
            c.contact_position
                .extend([r.point.x as f32, r.point.y as f32]);
            c.contact_bodies
                .extend([r.id.body_a as i32, r.id.body_b as i32]);
            c.contact_normal
                .extend([r.normal.x as f32, r.normal.y as f32]);
            c.contact_warm_start
                .extend([w.normal as f32, w.tangent as f32]);
            c.contact_impulse
                .extend([f.normal as f32, f.tangent as f32]);
        }
        c.contact_offsets
            .push((c.contact_position.len() / 2) as i64);
    }
    Ok(c)
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn i64_bytes(v: &[i64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn i32_bytes(v: &[i32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The metadata header of a seed's file.
fn metadata(
    seed: u64,
    config: &GenerateConfig,
    layout: &GridLayout,
    c: &Columns,
) -> HashMap<String, String> {
    let s = &config.world;
    let solver_spec = &config.solver;
    let mut m = HashMap::new();
    let mut put = |k: &str, v: String| {
        m.insert(k.to_string(), v);
    };
    put("format", FORMAT.into());
    put("format_version", FORMAT_VERSION.into());
    put("scene", "pile".into());
    put("seed", seed.to_string());
    put("bodies", config.bodies.to_string());
    put("steps_simulated", config.steps.to_string());
    put("steps_recorded", c.steps.len().to_string());
    put("dt", s.dt.to_string());
    put("gravity", format!("[{}, {}]", s.gravity.x, s.gravity.y));
    put("warm_start", "builtin".into());
    put(
        "solver",
        serde_json::json!({
            "spec": solver_spec,
            "max_iterations": s.solver.max_iterations,
            "tolerance": s.solver.tolerance,
            "norm": format!("{:?}", s.solver.norm),
            "min_iterations": s.solver.min_iterations,
        })
        .to_string(),
    );
    put("grid_layout", layout.to_json());
    put(
        "input_channels",
        serde_json::to_string(&layout.input_channels).unwrap_or_default(),
    );
    put(
        "output_channels",
        serde_json::to_string(&layout.output_channels).unwrap_or_default(),
    );
    put(
        "label_source",
        "final impulses of the step (after the velocity solve)".into(),
    );
    put(
        "generator",
        format!("deepcontact {}", env!("CARGO_PKG_VERSION")),
    );
    m
}

fn write_seed(
    path: &Path,
    seed: u64,
    config: &GenerateConfig,
    layout: &GridLayout,
    c: &Columns,
) -> Result<(), ExperimentError> {
    let (s, b, n) = (
        c.steps.len(),
        c.body_mass.len(),
        c.contact_position.len() / 2,
    );
    let (nx, ny) = (layout.grid.nx, layout.grid.ny);
    let (ci, co) = (layout.input_channels.len(), layout.output_channels.len());
    let owned: Vec<(&str, Dtype, Vec<usize>, Vec<u8>)> = vec![
        ("steps", Dtype::I64, vec![s], i64_bytes(&c.steps)),
        (
            "inputs",
            Dtype::F32,
            vec![s, ci, ny, nx],
            f32_bytes(&c.inputs),
        ),
        (
            "labels",
            Dtype::F32,
            vec![s, co, ny, nx],
            f32_bytes(&c.labels),
        ),
        ("body_mass", Dtype::F32, vec![b], f32_bytes(&c.body_mass)),
        (
            "body_position",
            Dtype::F32,
            vec![s, b, 2],
            f32_bytes(&c.body_position),
        ),
        (
            "body_velocity",
            Dtype::F32,
            vec![s, b, 2],
            f32_bytes(&c.body_velocity),
        ),
        (
            "body_angular_velocity",
            Dtype::F32,
            vec![s, b],
            f32_bytes(&c.body_angular_velocity),
        ),
        (
            "contact_offsets",
            Dtype::I64,
            vec![s + 1],
            i64_bytes(&c.contact_offsets),
        ),
        (
            "contact_position",
            Dtype::F32,
            vec![n, 2],
            f32_bytes(&c.contact_position),
        ),
        (
            "contact_bodies",
            Dtype::I32,
            vec![n, 2],
            i32_bytes(&c.contact_bodies),
        ),
        (
            "contact_normal",
            Dtype::F32,
            vec![n, 2],
            f32_bytes(&c.contact_normal),
        ),
        (
            "contact_warm_start",
            Dtype::F32,
            vec![n, 2],
            f32_bytes(&c.contact_warm_start),
        ),
        (
            "contact_impulse",
            Dtype::F32,
            vec![n, 2],
            f32_bytes(&c.contact_impulse),
        ),
    ];
    let views = owned
        .iter()
        .map(|(name, dtype, shape, bytes)| {
            TensorView::new(*dtype, shape.clone(), bytes)
                .map(|v| (*name, v))
                .map_err(|e| ExperimentError::Invalid(format!("tensor {name}: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let meta = metadata(seed, config, layout, c);
    write_atomic_with(path, |tmp| {
        safetensors::serialize_to_file(views, Some(meta), tmp)
            .map_err(|e| std::io::Error::other(e.to_string()))
    })
}

/// Whether `path` is a complete file of this format for `seed` with these settings: the header
/// parses, the metadata matches, and the file is as long as the header says.
pub fn is_complete(path: &Path, seed: u64, steps: u64, bodies: usize) -> bool {
    let check = || -> Option<bool> {
        let mut f = std::fs::File::open(path).ok()?;
        let len = f.metadata().ok()?.len();
        let mut n = [0u8; 8];
        f.read_exact(&mut n).ok()?;
        let n = u64::from_le_bytes(n);
        if n > 100 << 20 || 8 + n > len {
            return Some(false);
        }
        let mut header = vec![0u8; n as usize];
        f.read_exact(&mut header).ok()?;
        let header: serde_json::Value = serde_json::from_slice(&header).ok()?;
        let obj = header.as_object()?;
        let meta = obj.get("__metadata__")?;
        let get = |k: &str| meta.get(k).and_then(|v| v.as_str()).map(str::to_string);
        if get("format")? != FORMAT
            || get("format_version")? != FORMAT_VERSION
            || get("seed")? != seed.to_string()
            || get("steps_simulated")? != steps.to_string()
            || get("bodies")? != bodies.to_string()
        {
            return Some(false);
        }
        let end = obj
            .iter()
            .filter(|(k, _)| *k != "__metadata__")
            .filter_map(|(_, v)| v.get("data_offsets")?.get(1)?.as_u64())
            .max()
            .unwrap_or(0);
        Some(8 + n + end == len)
    };
    check().unwrap_or(false)
}

/// Simulates every seed of `config` whose file is missing or incomplete (all of them with
/// `force`), in parallel, and writes one file per seed ([`seed_file`]).
pub fn run_generate(
    config: &GenerateConfig,
    registry: &Registry,
) -> Result<GenerateOutcome, ExperimentError> {
    std::fs::create_dir_all(&config.out).map_err(|e| ExperimentError::io(&config.out, e))?;
    // Fail early on a bad solver spec, settings or a plan that cannot fit in memory (each
    // worker holds one seed's grids, inputs and labels, until its file is written).
    registry.build_solver(&config.solver)?;
    config.world.validate()?;
    crate::limits::check_threads(config.threads)?;
    let layout = GridLayout::thesis();
    let per_step = 4 * (layout.input_len() + layout.output_len()) as u128;
    let workers = crate::threads(config.threads).min(config.seeds.len().max(1)) as u128;
    crate::limits::check_memory(
        "generate",
        workers * u128::from(config.steps) * per_step,
        "lower --steps or --jobs",
    )?;
    let todo: Vec<u64> = config
        .seeds
        .iter()
        .copied()
        .filter(|&s| {
            config.force || !is_complete(&seed_file(&config.out, s), s, config.steps, config.bodies)
        })
        .collect();
    let skipped = config.seeds.len() - todo.len();
    let bar = if config.progress {
        ProgressBar::new(todo.len() as u64 * config.steps)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} steps ({eta} left) {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let done = AtomicUsize::new(0);
    let pool = crate::pool(crate::threads(config.threads))?;
    let result: Result<(), ExperimentError> = pool.install(|| {
        todo.par_iter().try_for_each(|&seed| {
            let tick = || bar.inc(1);
            let c = simulate_seed(seed, config, registry, &layout, &tick)?;
            write_seed(&seed_file(&config.out, seed), seed, config, &layout, &c)?;
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            bar.set_message(format!("{d}/{} seeds", todo.len()));
            Ok(())
        })
    });
    bar.finish_and_clear();
    result?;
    Ok(GenerateOutcome {
        written: todo.len(),
        skipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse() {
        assert_eq!(parse_shard("1/4").unwrap(), (1, 4));
        assert!(parse_shard("4/4").is_err());
        assert!(parse_shard("1").is_err());
    }
}
