//! Times one inference (61 × 61) and the whole provider (grids + inference + read-back) per step.
//!
//! ```sh
//! cargo run --release -p deepcontact-onnx --example infer_timing -- models/pressure.onnx
//! ORT_DYLIB_PATH=... cargo run --release -p deepcontact-onnx --no-default-features \
//!     --features load-dynamic --example infer_timing -- models/pressure.onnx
//! ```

use std::path::PathBuf;
use std::time::Instant;

use deepcontact_core::WorldSettings;
use deepcontact_onnx::{Backend, CnnWarmStart, ModelSource, ProviderOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path: PathBuf = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| deepcontact_onnx::PRESSURE.path());
    let runs: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(200);
    let backend = Backend::default_for_build();
    let t = Instant::now();
    let mut provider = CnnWarmStart::new(
        "model",
        ModelSource::Files {
            model: &path,
            card: None,
        },
        ProviderOptions { backend },
    )?;
    println!(
        "{}: loaded on {backend} in {:.1} ms",
        path.display(),
        t.elapsed().as_secs_f64() * 1e3
    );

    // A settled pile as input.
    let mut world = deepcontact_core::scene::pile(12345, 100)?.build(WorldSettings::default())?;
    let mut solver = deepcontact_pgs::PgsSolver::default();
    let mut position = deepcontact_pgs::PgsPositionSolver::default();
    for _ in 0..200 {
        world.step(
            &mut deepcontact_core::CarriedWarmStart,
            &mut solver,
            &mut position,
        )?;
    }
    let mut grid = vec![0.0f32; provider.layout().input_len()];
    let mut features = deepcontact_onnx::GridFeatures::new(provider.layout().clone())?;
    features.encode_world(&world, &mut grid)?;
    let mut model = deepcontact_onnx::OnnxModel::load(
        ModelSource::Files {
            model: &path,
            card: None,
        },
        backend,
        &deepcontact_onnx::features::expectation(provider.layout()),
    )?;
    let mut out = vec![0.0f32; model.output_len()];
    for _ in 0..10 {
        model.run(&grid, &mut out)?;
    }
    let t = Instant::now();
    for _ in 0..runs {
        model.run(&grid, &mut out)?;
    }
    let infer = t.elapsed().as_secs_f64() / runs as f64;
    println!(
        "inference: {:.3} ms per run ({runs} runs, 1 thread)",
        infer * 1e3
    );

    // Whole steps with the provider (warm start time as the world reports it).
    let (mut ws, mut steps, mut contacts) = (0.0, 0, 0);
    for _ in 0..50 {
        let r = world.step(&mut provider, &mut solver, &mut position)?;
        ws += r.warm_start_seconds;
        contacts += r.contacts;
        steps += 1;
    }
    println!(
        "provider: {:.3} ms per step (grids + inference + read-back; {:.0} contacts per step)",
        ws / steps as f64 * 1e3,
        contacts as f64 / steps as f64
    );
    Ok(())
}
