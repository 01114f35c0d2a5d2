//! Training data for the CNN warm starts (what `deepcontact generate` writes).
//!
//! Simulates the thesis pile for each seed (builtin warm start, the chosen solver) and writes one
//! safetensors file per seed, `pile-<seed>.safetensors`, holding for every step with contacts the
//! input grids `[6, 61, 61]`, the label grids `[2, 61, 61]` (from the step's final impulses),
//! the raw bodies and contact points, and what per-contact models need beside them (format 2):
//! whether each impulse was carried, the impulses of the step before, separation and relative
//! velocity, the island, and the contact graph (pairs of contacts sharing a moving body); and
//! (format 3) each point's velocity-solver row — its bodies, anchors, effective masses,
//! friction and bias, with the bodies' inverse masses — so that a training script can run the
//! solver's own sweeps on the recorded problems, and the carried impulses as grids (the input
//! of a residual CNN). The grids can be left out (`grids: false`).
//! The format is documented in `models/README.md`.
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
pub const FORMAT_VERSION: &str = "3";
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
    /// Write the input and label grids (default true); without them a file holds only the
    /// per-body and per-contact tensors, ~40× smaller, for graph models.
    pub grids: bool,
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
            grids: true,
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
    /// The carried impulses spread onto the label grids (a residual CNN's extra input).
    carried: Vec<f32>,
    bodies: Vec<BodyCapture>,
    /// This step's points as the providers saw them, by contact id.
    warm: Vec<(ContactId, PointCapture)>,
    /// The warm starts of the step before (`warm_step` − 1's, sorted), by contact id.
    previous: Vec<(ContactId, PointCapture)>,
}

/// One world body at the warm start of a step's first island.
#[derive(Debug, Clone, Copy, Default)]
struct BodyCapture {
    mass: f32,
    /// Inverse mass and inverse rotational inertia (0 for static bodies).
    inverse: [f32; 2],
    position: [f32; 2],
    velocity: [f32; 2],
    angular_velocity: f32,
}

/// One contact point as a provider sees it.
#[derive(Debug, Clone, Copy, Default)]
struct PointCapture {
    warm: Impulse,
    persisted: bool,
    separation: f32,
    /// Relative velocity of body B against A at the point, along the normal and the tangent.
    velocity: [f32; 2],
    island: i32,
    row: SolverRow,
}

/// A point's row as the velocity solver sees it (see `ContactPoint`).
#[derive(Debug, Clone, Copy, Default)]
struct SolverRow {
    /// World handles of the solver's bodies A and B (the normal points from A to B).
    bodies: [i32; 2],
    normal: [f32; 2],
    /// Anchors `r_a`, `r_b` (point minus centre of mass), m.
    anchors: [f32; 4],
    /// Normal and tangent effective masses, kg.
    mass: [f32; 2],
    friction: f32,
    velocity_bias: f32,
    /// Index of the point in its island's problem (the solver's point order).
    point: i32,
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
            // The step before's warm starts (none if it had no contacts).
            let consecutive = self.snap.is_some_and(|s| s + 1 == ctx.step);
            std::mem::swap(&mut self.previous, &mut self.warm);
            if consecutive {
                self.previous.sort_unstable_by_key(|a| a.0);
            } else {
                self.previous.clear();
            }
            self.snap = Some(ctx.step);
            self.warm.clear();
            if let Some(world) = ctx.world {
                // The world's contacts are still last step's: their impulses are the carried ones.
                let encoded = self
                    .features
                    .encode_world(world, &mut self.input)
                    .and_then(|()| self.features.encode_world_labels(world, &mut self.carried));
                if let Err(e) = encoded {
                    self.error = Some(e.to_string());
                }
                self.bodies.clear();
                self.bodies
                    .extend(world.bodies().iter().map(|b| BodyCapture {
                        mass: b.mass as f32,
                        inverse: [b.inv_mass as f32, b.inv_inertia as f32],
                        position: [b.position.x as f32, b.position.y as f32],
                        velocity: [b.linear_velocity.x as f32, b.linear_velocity.y as f32],
                        angular_velocity: b.angular_velocity as f32,
                    }));
            }
        }
        let problem = ctx.problem;
        for (i, (p, w)) in problem.points.iter().zip(out.iter()).enumerate() {
            let (a, b) = (
                &problem.bodies[p.body_a as usize],
                &problem.bodies[p.body_b as usize],
            );
            let dv = problem.relative_velocity(i);
            self.warm.push((
                p.id,
                PointCapture {
                    warm: *w,
                    persisted: ctx.carried.get(i).is_some_and(Option::is_some),
                    separation: p.separation as f32,
                    velocity: [dv.dot(&p.normal) as f32, dv.dot(&p.tangent()) as f32],
                    island: ctx.island as i32,
                    row: SolverRow {
                        bodies: [a.world_index as i32, b.world_index as i32],
                        normal: [p.normal.x as f32, p.normal.y as f32],
                        anchors: [
                            p.r_a.x as f32,
                            p.r_a.y as f32,
                            p.r_b.x as f32,
                            p.r_b.y as f32,
                        ],
                        mass: [p.normal_mass as f32, p.tangent_mass as f32],
                        friction: p.friction as f32,
                        velocity_bias: p.velocity_bias as f32,
                        point: i as i32,
                    },
                },
            ));
        }
        Ok(())
    }
}

/// Everything recorded for one seed, column-wise.
#[derive(Default)]
struct Columns {
    steps: Vec<i64>,
    inputs: Vec<f32>,
    labels: Vec<f32>,
    carried: Vec<f32>,
    body_mass: Vec<f32>,
    body_inverse_mass: Vec<f32>,
    body_position: Vec<f32>,
    body_velocity: Vec<f32>,
    body_angular_velocity: Vec<f32>,
    contact_offsets: Vec<i64>,
    contact_position: Vec<f32>,
    contact_bodies: Vec<i32>,
    contact_normal: Vec<f32>,
    contact_warm_start: Vec<f32>,
    contact_impulse: Vec<f32>,
    contact_persisted: Vec<u8>,
    contact_previous_impulse: Vec<f32>,
    contact_separation: Vec<f32>,
    contact_relative_velocity: Vec<f32>,
    contact_island: Vec<i32>,
    contact_solver_bodies: Vec<i32>,
    contact_solver_normal: Vec<f32>,
    contact_anchors: Vec<f32>,
    contact_row_mass: Vec<f32>,
    contact_friction: Vec<f32>,
    contact_velocity_bias: Vec<f32>,
    contact_point: Vec<i32>,
    edge_offsets: Vec<i64>,
    contact_edges: Vec<i32>,
}

impl Columns {
    /// One contact's columns: raw contact `r`, as the providers saw it (`point`), its warm
    /// start the step before (`previous`) and its final impulse (`f`).
    fn push_contact(
        &mut self,
        r: &deepcontact_core::narrow_phase::RawContact,
        point: &PointCapture,
        previous: Impulse,
        f: Impulse,
    ) {
        let w = point.warm;
        self.contact_persisted.push(u8::from(point.persisted));
        self.contact_previous_impulse
            .extend([previous.normal as f32, previous.tangent as f32]);
        self.contact_separation.push(point.separation);
        self.contact_relative_velocity.extend(point.velocity);
        self.contact_island.push(point.island);
        let row = &point.row;
        self.contact_solver_bodies.extend(row.bodies);
        self.contact_solver_normal.extend(row.normal);
        self.contact_anchors.extend(row.anchors);
        self.contact_row_mass.extend(row.mass);
        self.contact_friction.push(row.friction);
        self.contact_velocity_bias.push(row.velocity_bias);
        self.contact_point.push(row.point);
        self.contact_position
            .extend([r.point.x as f32, r.point.y as f32]);
        self.contact_bodies
            .extend([r.id.body_a as i32, r.id.body_b as i32]);
        self.contact_normal
            .extend([r.normal.x as f32, r.normal.y as f32]);
        self.contact_warm_start
            .extend([w.normal as f32, w.tangent as f32]);
        self.contact_impulse
            .extend([f.normal as f32, f.tangent as f32]);
    }
}

/// The value of `id` in a list sorted by id, or the default.
fn lookup<T: Copy + Default>(sorted: &[(ContactId, T)], id: &ContactId) -> T {
    sorted
        .binary_search_by(|(k, _)| k.cmp(id))
        .map(|i| sorted[i].1)
        .unwrap_or_default()
}

/// The contact graph of one step's contacts (`bodies`: their body pairs; `moving`: whether
/// a body can move): every pair `(i, j)`, `i < j`, of contacts sharing a moving body, once,
/// sorted; `by_body` is scratch.
fn contact_edges(
    bodies: &[[i32; 2]],
    moving: impl Fn(i32) -> bool,
    by_body: &mut HashMap<i32, Vec<i32>>,
    edges: &mut Vec<[i32; 2]>,
) {
    by_body.clear();
    for (k, pair) in bodies.iter().enumerate() {
        for &b in pair {
            if moving(b) {
                by_body.entry(b).or_default().push(k as i32);
            }
        }
    }
    edges.clear();
    for list in by_body.values() {
        for (x, &i) in list.iter().enumerate() {
            edges.extend(list[x + 1..].iter().map(|&j| [i.min(j), i.max(j)]));
        }
    }
    edges.sort_unstable();
    edges.dedup();
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
        carried: vec![0.0; layout.output_len()],
        bodies: Vec::new(),
        warm: Vec::new(),
        previous: Vec::new(),
    };
    let mut c = Columns {
        contact_offsets: vec![0],
        edge_offsets: vec![0],
        ..Columns::default()
    };
    let (mut by_body, mut edges, mut pairs) = (HashMap::new(), Vec::new(), Vec::new());
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
        c.steps.push(report.step as i64);
        if config.grids {
            labeler
                .encode_world_labels(&world, &mut label)
                .map_err(|e| grid_err(&e))?;
            c.inputs.extend_from_slice(&rec.input);
            c.labels.extend_from_slice(&label);
            c.carried.extend_from_slice(&rec.carried);
        }
        if c.body_mass.is_empty() {
            c.body_mass.extend(rec.bodies.iter().map(|b| b.mass));
            c.body_inverse_mass
                .extend(rec.bodies.iter().flat_map(|b| b.inverse));
        }
        for b in &rec.bodies {
            c.body_position.extend(b.position);
            c.body_velocity.extend(b.velocity);
            c.body_angular_velocity.push(b.angular_velocity);
        }
        pairs.clear();
        for r in raw {
            let (point, f) = (lookup(&rec.warm, &r.id), lookup(finals, &r.id));
            let previous = lookup(&rec.previous, &r.id).warm;
            c.push_contact(r, &point, previous, f);
            pairs.push([r.id.body_a as i32, r.id.body_b as i32]);
        }
        c.contact_offsets
            .push((c.contact_position.len() / 2) as i64);
        let mass = &c.body_mass;
        let moving = |b: i32| mass.get(b as usize).is_some_and(|&m| m > 0.0);
        contact_edges(&pairs, moving, &mut by_body, &mut edges);
        c.contact_edges.extend(edges.iter().flatten());
        c.edge_offsets.push((c.contact_edges.len() / 2) as i64);
    }
    Ok(c)
}

/// A tensor to write: name, dtype, shape, little-endian bytes.
type Tensor<'a> = (&'a str, Dtype, Vec<usize>, Vec<u8>);

fn f32s<'a>(name: &'a str, shape: Vec<usize>, v: &[f32]) -> Tensor<'a> {
    (
        name,
        Dtype::F32,
        shape,
        v.iter().flat_map(|x| x.to_le_bytes()).collect(),
    )
}
fn i64s<'a>(name: &'a str, shape: Vec<usize>, v: &[i64]) -> Tensor<'a> {
    (
        name,
        Dtype::I64,
        shape,
        v.iter().flat_map(|x| x.to_le_bytes()).collect(),
    )
}
fn i32s<'a>(name: &'a str, shape: Vec<usize>, v: &[i32]) -> Tensor<'a> {
    (
        name,
        Dtype::I32,
        shape,
        v.iter().flat_map(|x| x.to_le_bytes()).collect(),
    )
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
    put("grids", config.grids.to_string());
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
    let e = c.contact_edges.len() / 2;
    let mut owned: Vec<Tensor<'_>> = vec![
        i64s("steps", vec![s], &c.steps),
        f32s("body_mass", vec![b], &c.body_mass),
        f32s("body_inverse_mass", vec![b, 2], &c.body_inverse_mass),
        f32s("body_position", vec![s, b, 2], &c.body_position),
        f32s("body_velocity", vec![s, b, 2], &c.body_velocity),
        f32s(
            "body_angular_velocity",
            vec![s, b],
            &c.body_angular_velocity,
        ),
        i64s("contact_offsets", vec![s + 1], &c.contact_offsets),
        f32s("contact_position", vec![n, 2], &c.contact_position),
        i32s("contact_bodies", vec![n, 2], &c.contact_bodies),
        f32s("contact_normal", vec![n, 2], &c.contact_normal),
        f32s("contact_warm_start", vec![n, 2], &c.contact_warm_start),
        f32s("contact_impulse", vec![n, 2], &c.contact_impulse),
        (
            "contact_persisted",
            Dtype::U8,
            vec![n],
            c.contact_persisted.clone(),
        ),
        f32s(
            "contact_previous_impulse",
            vec![n, 2],
            &c.contact_previous_impulse,
        ),
        f32s("contact_separation", vec![n], &c.contact_separation),
        f32s(
            "contact_relative_velocity",
            vec![n, 2],
            &c.contact_relative_velocity,
        ),
        i32s("contact_island", vec![n], &c.contact_island),
        i32s(
            "contact_solver_bodies",
            vec![n, 2],
            &c.contact_solver_bodies,
        ),
        f32s(
            "contact_solver_normal",
            vec![n, 2],
            &c.contact_solver_normal,
        ),
        f32s("contact_anchors", vec![n, 4], &c.contact_anchors),
        f32s("contact_row_mass", vec![n, 2], &c.contact_row_mass),
        f32s("contact_friction", vec![n], &c.contact_friction),
        f32s("contact_velocity_bias", vec![n], &c.contact_velocity_bias),
        i32s("contact_point", vec![n], &c.contact_point),
        i64s("edge_offsets", vec![s + 1], &c.edge_offsets),
        i32s("contact_edges", vec![e, 2], &c.contact_edges),
    ];
    if config.grids {
        owned.push(f32s("inputs", vec![s, ci, ny, nx], &c.inputs));
        owned.push(f32s("labels", vec![s, co, ny, nx], &c.labels));
        owned.push(f32s("carried", vec![s, co, ny, nx], &c.carried));
    }
    let views = owned
        .iter()
        .map(|(name, dtype, shape, bytes)| {
            TensorView::new(*dtype, shape.clone(), bytes)
                .map(|v| (*name, v))
                .map_err(|e| ExperimentError::Invalid(format!("tensor {name}: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let meta = metadata(seed, config, layout, c);
    let bytes = safetensors::serialize(views, Some(meta))
        .map_err(|e| ExperimentError::Invalid(format!("seed {seed}: {e}")))?;
    let bytes = canonical_header(bytes)?;
    write_atomic_with(path, |tmp| std::fs::write(tmp, &bytes))
}

/// The file with its JSON header's keys sorted. safetensors writes the metadata from a
/// `HashMap`, whose order changes from run to run; sorted, the same seed gives the same bytes.
/// The header keeps its length (the same keys and values, padded with spaces as before).
fn canonical_header(mut bytes: Vec<u8>) -> Result<Vec<u8>, ExperimentError> {
    let bad = |why: String| ExperimentError::Invalid(format!("safetensors header: {why}"));
    let n = bytes
        .get(..8)
        .map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8])) as usize)
        .filter(|&n| 8 + n <= bytes.len())
        .ok_or_else(|| bad("truncated".into()))?;
    let header: serde_json::Value =
        serde_json::from_slice(&bytes[8..8 + n]).map_err(|e| bad(e.to_string()))?;
    // serde_json's `Value` keeps object keys sorted (no `preserve_order`).
    let sorted = serde_json::to_vec(&header).map_err(|e| bad(e.to_string()))?;
    if sorted.len() > n {
        return Err(bad(format!("{} bytes sorted against {n}", sorted.len())));
    }
    bytes[8..8 + sorted.len()].copy_from_slice(&sorted);
    bytes[8 + sorted.len()..8 + n].fill(b' ');
    Ok(bytes)
}

/// Whether `path` is a complete file of this format for `seed` with these settings: the header
/// parses, the metadata matches, and the file is as long as the header says.
pub fn is_complete(path: &Path, seed: u64, config: &GenerateConfig) -> bool {
    let (steps, bodies) = (config.steps, config.bodies);
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
            || get("grids")? != config.grids.to_string()
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
    let per_step = if config.grids {
        4 * (layout.input_len() + 2 * layout.output_len()) as u128
    } else {
        0
    };
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
        .filter(|&s| config.force || !is_complete(&seed_file(&config.out, s), s, config))
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

    /// Contacts 0 and 1 share moving body 1 twice over (bodies 1 and 2): one edge; contact 2
    /// touches body 1 too; contact 3 only the static body 0 with contact 0: no edge there.
    #[test]
    fn contact_edges_join_contacts_sharing_a_moving_body_once() {
        let bodies = [[0, 1], [1, 2], [2, 1], [0, 3]];
        let (mut by_body, mut edges) = (HashMap::new(), Vec::new());
        contact_edges(&bodies, |b| b != 0, &mut by_body, &mut edges);
        assert_eq!(edges, vec![[0, 1], [0, 2], [1, 2]]);
    }

    /// A generated file holds the per-contact tensors with consistent shapes: flags 0/1,
    /// edges inside their step's contacts and joining contacts that share a moving body,
    /// previous impulses present exactly for contacts whose impulse was carried.
    #[test]
    fn generated_files_carry_the_contact_graph_and_the_step_before() {
        let out = std::env::temp_dir().join(format!("dc-generate-{}", std::process::id()));
        let config = GenerateConfig {
            seeds: vec![3],
            out: out.clone(),
            steps: 70,
            bodies: 100,
            threads: 1,
            progress: false,
            ..GenerateConfig::default()
        };
        run_generate(&config, &crate::full_registry()).unwrap();
        let bytes = std::fs::read(seed_file(&out, 3)).unwrap();
        let file = safetensors::SafeTensors::deserialize(&bytes).unwrap();
        let f32s = |name: &str| -> Vec<f32> {
            let t = file.tensor(name).unwrap();
            t.data()
                .chunks(4)
                .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
                .collect()
        };
        let i32s = |name: &str| -> Vec<i32> {
            let t = file.tensor(name).unwrap();
            t.data()
                .chunks(4)
                .map(|b| i32::from_le_bytes(b.try_into().unwrap()))
                .collect()
        };
        let i64s = |name: &str| -> Vec<i64> {
            let t = file.tensor(name).unwrap();
            t.data()
                .chunks(8)
                .map(|b| i64::from_le_bytes(b.try_into().unwrap()))
                .collect()
        };
        let (offsets, edge_offsets) = (i64s("contact_offsets"), i64s("edge_offsets"));
        let n = *offsets.last().unwrap() as usize;
        assert!(n > 20, "only {n} contacts");
        assert_eq!(edge_offsets.len(), offsets.len());
        let persisted = file.tensor("contact_persisted").unwrap().data().to_vec();
        assert_eq!(persisted.len(), n);
        assert!(persisted.iter().all(|&p| p <= 1));
        assert!(persisted.iter().filter(|&&p| p == 1).count() > n / 2);
        let (warm, previous) = (f32s("contact_warm_start"), f32s("contact_previous_impulse"));
        assert_eq!(previous.len(), 2 * n);
        for k in 0..n {
            if persisted[k] == 0 {
                // A new contact starts from zero and had no impulse the step before.
                assert_eq!((warm[2 * k], previous[2 * k]), (0.0, 0.0), "contact {k}");
            }
        }
        // A resting contact had a load the step before too (the column is not left at zero).
        let loaded_before = (0..n)
            .filter(|&k| persisted[k] == 1 && previous[2 * k] > 0.0)
            .count();
        assert!(loaded_before > n / 4, "{loaded_before} of {n}");
        assert_eq!(f32s("contact_separation").len(), n);
        assert_eq!(f32s("contact_relative_velocity").len(), 2 * n);
        assert_eq!(i32s("contact_island").len(), n);
        let (bodies, edges, mass) = (
            i32s("contact_bodies"),
            i32s("contact_edges"),
            f32s("body_mass"),
        );
        assert!(!edges.is_empty());
        for s in 0..offsets.len() - 1 {
            let (c0, c1) = (offsets[s] as usize, offsets[s + 1] as usize);
            for e in edge_offsets[s] as usize..edge_offsets[s + 1] as usize {
                let (i, j) = (edges[2 * e] as usize, edges[2 * e + 1] as usize);
                assert!(i < j && c0 + j < c1, "step {s}: edge ({i}, {j})");
                let (a, b) = (&bodies[2 * (c0 + i)..][..2], &bodies[2 * (c0 + j)..][..2]);
                assert!(a.iter().any(|x| b.contains(x) && mass[*x as usize] > 0.0));
            }
        }
        std::fs::remove_dir_all(&out).ok();
    }

    /// The metadata came from a `HashMap`, so the same seed gave files whose headers listed
    /// its keys in another order on every write (the tensors were the same).
    #[test]
    fn regression_generated_files_differed_between_runs_in_their_header_order() {
        let dir = std::env::temp_dir().join(format!("dc-generate-twice-{}", std::process::id()));
        let write = |sub: &str| {
            let config = GenerateConfig {
                seeds: vec![2],
                out: dir.join(sub),
                steps: 40,
                threads: 1,
                progress: false,
                grids: false,
                ..GenerateConfig::default()
            };
            run_generate(&config, &crate::full_registry()).unwrap();
            std::fs::read(seed_file(&config.out, 2)).unwrap()
        };
        let (a, b) = (write("a"), write("b"));
        assert!(a == b, "two writes of seed 2 differ");
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Tensor `name` of `file` (F32, I32 or I64) as rows of `width` numbers.
    fn rows_of(file: &safetensors::SafeTensors<'_>, name: &str, width: usize) -> Vec<Vec<f64>> {
        let t = file.tensor(name).unwrap();
        let v: Vec<f64> = match t.dtype() {
            Dtype::F32 => t
                .data()
                .chunks(4)
                .map(|b| f32::from_le_bytes(b.try_into().unwrap()) as f64)
                .collect(),
            Dtype::I32 => t
                .data()
                .chunks(4)
                .map(|b| i32::from_le_bytes(b.try_into().unwrap()) as f64)
                .collect(),
            _ => t
                .data()
                .chunks(8)
                .map(|b| i64::from_le_bytes(b.try_into().unwrap()) as f64)
                .collect(),
        };
        v.chunks(width).map(<[f64]>::to_vec).collect()
    }

    /// The recorded solver rows are the solver's: with the bodies' recorded velocities and
    /// inverse masses, the step's final impulses satisfy the contact conditions far better
    /// than a cold start does (a wrong sign, anchor or mass would break this), the effective
    /// masses follow from the anchors, and no grids are written when they are not asked for.
    #[test]
    fn generated_solver_rows_reproduce_the_solved_contact_conditions() {
        let out = std::env::temp_dir().join(format!("dc-generate-rows-{}", std::process::id()));
        let config = GenerateConfig {
            seeds: vec![4],
            out: out.clone(),
            steps: 90,
            threads: 1,
            progress: false,
            grids: false,
            ..GenerateConfig::default()
        };
        run_generate(&config, &crate::full_registry()).unwrap();
        let bytes = std::fs::read(seed_file(&out, 4)).unwrap();
        let file = safetensors::SafeTensors::deserialize(&bytes).unwrap();
        assert!(file.tensor("inputs").is_err() && file.tensor("labels").is_err());
        let raw = |name: &str, width: usize| rows_of(&file, name, width);
        let (offsets, inverse) = (raw("contact_offsets", 1), raw("body_inverse_mass", 2));
        let nb = inverse.len();
        let (vel, ang) = (raw("body_velocity", 2), raw("body_angular_velocity", 1));
        let (bodies, pair) = (raw("contact_solver_bodies", 2), raw("contact_bodies", 2));
        let (normal, anchors, mass) = (
            raw("contact_solver_normal", 2),
            raw("contact_anchors", 4),
            raw("contact_row_mass", 2),
        );
        let (bias, impulse) = (raw("contact_velocity_bias", 1), raw("contact_impulse", 2));
        let cross = |r: &[f64], n: &[f64]| r[0] * n[1] - r[1] * n[0];
        let (mut cold, mut solved, mut rows) = (0.0f64, 0.0f64, 0usize);
        for s in 0..offsets.len() - 1 {
            let range = offsets[s][0] as usize..offsets[s + 1][0] as usize;
            // Body velocities after the step's final impulses.
            let mut v: Vec<[f64; 3]> = (0..nb)
                .map(|b| [vel[s * nb + b][0], vel[s * nb + b][1], ang[s * nb + b][0]])
                .collect();
            for k in range.clone() {
                let (a, b) = (bodies[k][0] as usize, bodies[k][1] as usize);
                let mut sorted = [a, b];
                sorted.sort_unstable();
                assert_eq!(
                    [sorted[0] as f64, sorted[1] as f64],
                    [pair[k][0], pair[k][1]]
                );
                let (n, t) = (&normal[k], [-normal[k][1], normal[k][0]]);
                let (ra, rb) = (&anchors[k][..2], &anchors[k][2..]);
                let k_n = inverse[a][0]
                    + inverse[b][0]
                    + inverse[a][1] * cross(ra, n).powi(2)
                    + inverse[b][1] * cross(rb, n).powi(2);
                assert!((mass[k][0] * k_n - 1.0).abs() < 1e-4, "contact {k}");
                let p = [
                    impulse[k][0] * n[0] + impulse[k][1] * t[0],
                    impulse[k][0] * n[1] + impulse[k][1] * t[1],
                ];
                for (body, r, sign) in [(a, ra, -1.0), (b, rb, 1.0)] {
                    v[body][0] += sign * inverse[body][0] * p[0];
                    v[body][1] += sign * inverse[body][0] * p[1];
                    v[body][2] += sign * inverse[body][1] * cross(r, &p);
                }
            }
            let vn = |v: &[[f64; 3]], k: usize| {
                let (a, b) = (bodies[k][0] as usize, bodies[k][1] as usize);
                let (ra, rb) = (&anchors[k][..2], &anchors[k][2..]);
                let dv = [
                    v[b][0] - v[b][2] * rb[1] - v[a][0] + v[a][2] * ra[1],
                    v[b][1] + v[b][2] * rb[0] - v[a][1] - v[a][2] * ra[0],
                ];
                dv[0] * normal[k][0] + dv[1] * normal[k][1]
            };
            let before: Vec<[f64; 3]> = (0..nb)
                .map(|b| [vel[s * nb + b][0], vel[s * nb + b][1], ang[s * nb + b][0]])
                .collect();
            for k in range {
                // Natural residual of the normal row: λ − max(0, λ − m (vn − bias)).
                let natural = |lambda: f64, vn: f64| {
                    (lambda - (lambda - mass[k][0] * (vn - bias[k][0])).max(0.0)).abs()
                };
                solved = solved.max(natural(impulse[k][0], vn(&v, k)));
                cold = cold.max(natural(0.0, vn(&before, k)));
                rows += 1;
            }
        }
        assert!(rows > 100, "{rows} rows");
        assert!(
            solved < 0.02 && solved < 1e-2 * cold,
            "solved {solved}, cold {cold}"
        );
        std::fs::remove_dir_all(&out).ok();
    }
}
