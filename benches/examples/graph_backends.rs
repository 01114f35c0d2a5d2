//! The contact-graph warm start's model on two backends, on the same inputs: the plain Rust
//! forward pass of deepcontact-graph ([`ContactGraphModel::corrections`]) against the ONNX
//! export of the same model (`models/train/graph.py --check-only --onnx PATH`, dense incidence
//! matrices instead of scatter-adds) run by ort on the tract backend
//! ([`GraphOptimizationLevel::Level3`], as deepcontact-onnx builds its sessions).
//!
//! The thesis pile (seed 12345, 100 circles, default world settings) runs `--steps` steps
//! (default 250) with the builtin warm start, PGS and the PGS position pass; from step
//! `--from` (default 150) on, every island's model inputs are recorded (the features
//! [`GraphWarmStart`](deepcontact_graph::GraphWarmStart) computes, by
//! [`point_inputs`]). Both backends then evaluate every recorded step, alternately (the
//! order swapped each round) for `--rounds` rounds; the ONNX side includes building its input
//! tensors (features, the two `[bodies, contacts]` incidence matrices) into reused buffers,
//! as a provider would have to. Prints µs per step (sum over the step's islands; per round
//! the mean over the recorded steps, then the median over rounds) and the largest difference
//! between the two backends' corrections.
//!
//! ```sh
//! python models/train/graph.py --data data3 --check-only --onnx /tmp/graph.onnx --out models/graph
//! cargo run --release -p deepcontact-benches --example graph_backends -- --onnx /tmp/graph.onnx
//! ```
//!
//! `--weights PATH` times another safetensors model (default: the shipped one, which must be
//! the model the ONNX file was exported from). Timings are wall-clock; compare rows of one
//! run only.

use std::path::PathBuf;
use std::time::Instant;

use deepcontact_benches::{Recorder, SEED, median};
use deepcontact_core::{CarriedWarmStart, WarmStartContext, WorldSettings, scene};
use deepcontact_graph::{
    ContactGraphModel, FEATURES, GraphWarmStart, PointInput, Scratch, point_inputs,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};
use ort::session::Session;
use ort::session::builder::GraphOptimizationLevel;
use ort::value::TensorRef;

/// Bodies of the thesis pile.
const BODIES: usize = 100;

/// Command-line options.
struct Options {
    onnx: PathBuf,
    weights: Option<PathBuf>,
    steps: u64,
    from: u64,
    rounds: usize,
}

fn parse() -> Result<Option<Options>, String> {
    let mut onnx = None;
    let mut o = Options {
        onnx: PathBuf::new(),
        weights: None,
        steps: 250,
        from: 150,
        rounds: 9,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--help" || a == "-h" {
            println!(
                "usage: graph_backends --onnx PATH [--weights PATH] [--steps 250] [--from 150] \
                 [--rounds 9]"
            );
            return Ok(None);
        }
        let value = args.next().ok_or(format!("{a} needs a value"))?;
        let number = |v: &str| v.parse::<u64>().map_err(|e| format!("{a} {v}: {e}"));
        match a.as_str() {
            "--onnx" => onnx = Some(PathBuf::from(value)),
            "--weights" => o.weights = Some(PathBuf::from(value)),
            "--steps" => o.steps = number(&value)?,
            "--from" => o.from = number(&value)?,
            "--rounds" => o.rounds = number(&value)? as usize,
            _ => return Err(format!("unknown option {a} (see --help)")),
        }
    }
    o.onnx = onnx.ok_or(
        "--onnx PATH is required (write it with `python models/train/graph.py --data DATA \
         --check-only --onnx PATH --out models/graph`)",
    )?;
    if o.from >= o.steps || o.rounds == 0 {
        return Err("--from must be below --steps, --rounds at least 1".into());
    }
    Ok(Some(o))
}

/// One island's model inputs.
struct Island {
    points: Vec<PointInput>,
    moving: Vec<bool>,
}

/// Runs the pile and returns, per recorded step, its islands' model inputs.
fn record(o: &Options) -> Result<Vec<Vec<Island>>, String> {
    let settings = WorldSettings::default();
    let dt = settings.dt;
    let mut world = scene::pile(SEED, BODIES)
        .and_then(|s| s.build(settings))
        .map_err(|e| e.to_string())?;
    let at: Vec<u64> = (o.from..o.steps).collect();
    let mut recorder = Recorder::new(CarriedWarmStart, &at);
    let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
    for _ in 0..o.steps {
        world
            .step(&mut recorder, &mut solver, &mut position)
            .map_err(|e| e.to_string())?;
    }
    Ok(recorder
        .records
        .iter()
        .map(|(step, islands)| {
            islands
                .iter()
                .map(|r| {
                    let ctx = WarmStartContext::new(&r.problem, &r.carried, *step, dt);
                    let mut points = Vec::new();
                    point_inputs(&ctx, &mut points);
                    let moving = r.problem.bodies.iter().map(|b| b.inv_mass > 0.0).collect();
                    Island { points, moving }
                })
                .collect()
        })
        .collect())
}

/// The Rust forward pass, buffers reused across calls.
struct RustBackend<'m> {
    model: &'m ContactGraphModel,
    scratch: Scratch,
}

impl RustBackend<'_> {
    fn run(&mut self, island: &Island, out: &mut [[f32; 2]]) {
        self.model
            .corrections(&island.points, &island.moving, &mut self.scratch, out);
    }
}

/// The ONNX export on ort + tract, with the input buffers a provider would keep.
struct OnnxBackend {
    session: Session,
    features: Vec<f32>,
    incidence_a: Vec<f32>,
    incidence_b: Vec<f32>,
}

impl OnnxBackend {
    fn new(path: &std::path::Path) -> Result<Self, String> {
        ort::set_api(ort_tract::api());
        let env = ort::init()
            .with_name("graph_backends")
            .build()
            .map_err(|e| e.to_string())?;
        let session = Session::builder(&env)
            .map_err(|e| e.to_string())?
            .with_optimization_level(GraphOptimizationLevel::Level3)
            .map_err(|e| e.to_string())?
            .commit_from_file(path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let inputs: Vec<&str> = session.inputs().iter().map(|i| i.name()).collect();
        let outputs: Vec<&str> = session.outputs().iter().map(|i| i.name()).collect();
        if inputs != ["features", "incidence_a", "incidence_b"] || outputs != ["corrections"] {
            return Err(format!(
                "{}: inputs {inputs:?}, outputs {outputs:?}; expected the export of \
                 models/train/graph.py --onnx",
                path.display()
            ));
        }
        Ok(Self {
            session,
            features: Vec::new(),
            incidence_a: Vec::new(),
            incidence_b: Vec::new(),
        })
    }

    /// Fills the input buffers for `island` (features, incidence matrices).
    fn fill(&mut self, island: &Island) {
        let c = island.points.len();
        self.features.clear();
        self.features
            .extend(island.points.iter().flat_map(|p| p.features));
        for m in [&mut self.incidence_a, &mut self.incidence_b] {
            m.clear();
            m.resize(island.moving.len() * c, 0.0);
        }
        for (k, p) in island.points.iter().enumerate() {
            for (side, m) in [&mut self.incidence_a, &mut self.incidence_b]
                .into_iter()
                .enumerate()
            {
                let body = p.bodies[side] as usize;
                if island.moving[body] {
                    m[body * c + k] = 1.0;
                }
            }
        }
    }

    fn run(&mut self, island: &Island, out: &mut [[f32; 2]]) -> Result<(), String> {
        let (c, b) = (island.points.len(), island.moving.len());
        self.fill(island);
        let fail = |e: ort::Error| e.to_string();
        let features =
            TensorRef::from_array_view(([c, FEATURES.len()], &self.features[..])).map_err(fail)?;
        let a = TensorRef::from_array_view(([b, c], &self.incidence_a[..])).map_err(fail)?;
        let bb = TensorRef::from_array_view(([b, c], &self.incidence_b[..])).map_err(fail)?;
        let outputs = self
            .session
            .run(ort::inputs![features, a, bb])
            .map_err(fail)?;
        let (_, data) = outputs[0].try_extract_tensor::<f32>().map_err(fail)?;
        if data.len() != 2 * c {
            return Err(format!("{} outputs for {c} contacts", data.len()));
        }
        for (o, d) in out.iter_mut().zip(data.chunks_exact(2)) {
            *o = [d[0], d[1]];
        }
        Ok(())
    }
}

/// Per-island output buffers of every recorded step.
type Outputs = Vec<Vec<Vec<[f32; 2]>>>;

/// µs per step of the Rust forward pass over all recorded steps.
fn time_rust(rust: &mut RustBackend<'_>, steps: &[Vec<Island>], out: &mut Outputs) -> f64 {
    let t = Instant::now();
    for (islands, outs) in steps.iter().zip(out.iter_mut()) {
        for (island, out) in islands.iter().zip(outs.iter_mut()) {
            rust.run(island, out);
        }
    }
    t.elapsed().as_secs_f64() / steps.len() as f64 * 1e6
}

/// µs per step of the ONNX model (inputs built, run, outputs copied) over all recorded steps.
fn time_onnx(
    onnx: &mut OnnxBackend,
    steps: &[Vec<Island>],
    out: &mut Outputs,
) -> Result<f64, String> {
    let t = Instant::now();
    for (islands, outs) in steps.iter().zip(out.iter_mut()) {
        for (island, out) in islands.iter().zip(outs.iter_mut()) {
            onnx.run(island, out)?;
        }
    }
    Ok(t.elapsed().as_secs_f64() / steps.len() as f64 * 1e6)
}

/// µs per step of building the ONNX inputs alone (a part of [`time_onnx`]).
fn time_fill(onnx: &mut OnnxBackend, steps: &[Vec<Island>]) -> f64 {
    let t = Instant::now();
    for island in steps.iter().flatten() {
        onnx.fill(island);
        std::hint::black_box((&onnx.features, &onnx.incidence_a, &onnx.incidence_b));
    }
    t.elapsed().as_secs_f64() / steps.len() as f64 * 1e6
}

/// µs per step of each round, the two backends in alternating order: Rust, ONNX, and the
/// ONNX inputs' building alone.
type Times = (Vec<f64>, Vec<f64>, Vec<f64>);

/// Times `count` rounds (see [`Times`]).
fn rounds(
    count: usize,
    (rust, onnx): (&mut RustBackend<'_>, &mut OnnxBackend),
    steps: &[Vec<Island>],
    (out_rust, out_onnx): (&mut Outputs, &mut Outputs),
) -> Result<Times, String> {
    let (mut us_rust, mut us_onnx, mut us_fill) = (Vec::new(), Vec::new(), Vec::new());
    for round in 0..count {
        let (r, x) = if round % 2 == 0 {
            let r = time_rust(rust, steps, out_rust);
            (r, time_onnx(onnx, steps, out_onnx)?)
        } else {
            let x = time_onnx(onnx, steps, out_onnx)?;
            (time_rust(rust, steps, out_rust), x)
        };
        let f = time_fill(onnx, steps);
        eprintln!(
            "round {round}: Rust {r:.1} µs/step, ONNX (tract) {x:.1} µs/step (inputs {f:.1})"
        );
        us_rust.push(r);
        us_onnx.push(x);
        us_fill.push(f);
    }
    Ok((us_rust, us_onnx, us_fill))
}

/// The largest difference between the two backends' corrections, and the largest correction.
fn largest_difference(a: &Outputs, b: &Outputs) -> (f32, f32) {
    let (mut diff, mut size) = (0.0f32, 0.0f32);
    for (a, b) in a.iter().flatten().zip(b.iter().flatten()) {
        for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
            diff = diff.max((x - y).abs());
            size = size.max(x.abs());
        }
    }
    (diff, size)
}

fn main() -> Result<(), String> {
    let Some(o) = parse()? else {
        return Ok(());
    };
    let shipped;
    let loaded;
    let model = match &o.weights {
        Some(path) => {
            loaded = ContactGraphModel::load(path).map_err(|e| e.to_string())?;
            &loaded
        }
        None => {
            shipped = GraphWarmStart::shipped().map_err(|e| e.to_string())?;
            shipped.model()
        }
    };
    let t0 = Instant::now();
    let steps = record(&o)?;
    let islands: usize = steps.iter().map(Vec::len).sum();
    let points: usize = steps.iter().flatten().map(|i| i.points.len()).sum();
    let bodies: usize = steps.iter().flatten().map(|i| i.moving.len()).sum();
    let largest = steps
        .iter()
        .flatten()
        .map(|i| (i.points.len(), i.moving.len()))
        .max()
        .unwrap_or_default();
    eprintln!(
        "recorded {} steps ({islands} islands) in {:.1} s",
        steps.len(),
        t0.elapsed().as_secs_f64()
    );
    if points == 0 {
        return Err("no contact points recorded".into());
    }

    let mut rust = RustBackend {
        model,
        scratch: Scratch::default(),
    };
    let mut onnx = OnnxBackend::new(&o.onnx)?;
    // One output buffer per island and backend; both backends write all of them each round.
    let buffers = || -> Outputs {
        steps
            .iter()
            .map(|s| s.iter().map(|i| vec![[0.0; 2]; i.points.len()]).collect())
            .collect()
    };
    let (mut out_rust, mut out_onnx) = (buffers(), buffers());
    // Warm-up (not timed): buffers grown, tract's plans built.
    time_rust(&mut rust, &steps, &mut out_rust);
    time_onnx(&mut onnx, &steps, &mut out_onnx)?;
    let (us_rust, us_onnx, us_fill) = rounds(
        o.rounds,
        (&mut rust, &mut onnx),
        &steps,
        (&mut out_rust, &mut out_onnx),
    )?;

    let (diff, size) = largest_difference(&out_rust, &out_onnx);
    if !diff.is_finite() {
        return Err("the backends' outputs are not finite".into());
    }
    let times = (us_rust, us_onnx, us_fill);
    let counts = Counts {
        steps: steps.len(),
        islands,
        points,
        bodies,
        largest,
    };
    print_report(&o, model, &counts, &times, (diff, size));
    Ok(())
}

/// What was recorded: steps, islands, points and bodies in all, the largest island's points
/// and bodies.
struct Counts {
    steps: usize,
    islands: usize,
    points: usize,
    bodies: usize,
    largest: (usize, usize),
}

/// Prints the scene, the table and the backends' agreement.
fn print_report(
    o: &Options,
    model: &ContactGraphModel,
    c: &Counts,
    (us_rust, us_onnx, us_fill): &Times,
    (diff, size): (f32, f32),
) {
    let (n, islands, points, bodies, largest) =
        (c.steps as f64, c.islands, c.points, c.bodies, c.largest);
    let (r, x, f) = (median(us_rust), median(us_onnx), median(us_fill));
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    println!(
        "Pile of {BODIES} circles (seed {SEED}), steps {}..{}: {:.1} islands, {:.1} contact \
         points and {:.1} bodies (static included) per step; largest island {} points, {} bodies. \
         Model: hidden {}, channels {}, rounds {}. {} rounds, order swapped each round.\n",
        o.from,
        o.steps,
        islands as f64 / n,
        points as f64 / n,
        bodies as f64 / n,
        largest.0,
        largest.1,
        model.architecture().hidden,
        model.architecture().channels,
        model.architecture().rounds,
        o.rounds,
    );
    let per_point = n / points as f64;
    println!("| backend | µs/step (median) | µs/step (min) | µs/point |");
    println!("|---|---:|---:|---:|");
    for (what, times, median) in [
        ("Rust forward pass", &us_rust, r),
        ("ONNX, ort + tract (Level3, inputs built)", &us_onnx, x),
        (
            "(of which: ONNX inputs built, features + incidence matrices)",
            &us_fill,
            f,
        ),
    ] {
        println!(
            "| {what} | {median:.1} | {:.1} | {:.3} |",
            min(times),
            median * per_point
        );
    }
    println!(
        "\nONNX / Rust: {:.1}×. Largest |Rust − ONNX| over all corrections: {diff:.3e} N·s \
         (largest |correction| {size:.3e} N·s, relative {:.1e}).",
        x / r,
        diff / size.max(f32::MIN_POSITIVE)
    );
}
