//! One CNN inference (61 × 61 grids, batch 1, one thread) per model and backend of this
//! build: the shipped `pressure` and `peak` when `models/` has them, and deepcontact-onnx's
//! small test model always. tract is the default backend; ONNX Runtime runs when the crate is
//! built with `--no-default-features --features onnxruntime` and `ORT_DYLIB_PATH` is set.
//! Anything unavailable is skipped with a note on stderr.

use std::path::PathBuf;

use criterion::{BenchmarkId, Criterion};
use deepcontact_benches::tiny_model_path;
use deepcontact_onnx::{
    Backend, GridFeatures, GridLayout, ModelSource, OnnxModel, PEAK, PRESSURE, features,
};

use super::thesis_snapshots;

/// The `onnx` group.
pub fn bench(c: &mut Criterion) {
    if !super::wanted("onnx") {
        return;
    }
    let snap = thesis_snapshots().last().expect("recorded steps");
    let layout = GridLayout::thesis();
    let mut feats = GridFeatures::new(layout.clone()).expect("thesis layout");
    let mut input = vec![0.0f32; layout.input_len()];
    feats.encode_world(&snap.world, &mut input).expect("encode");
    let models: Vec<(&str, PathBuf)> = vec![
        ("pressure", PRESSURE.path()),
        ("peak", PEAK.path()),
        ("tiny-test-model", tiny_model_path()),
    ];
    let mut group = c.benchmark_group("onnx");
    for backend in [Backend::Tract, Backend::OnnxRuntime] {
        if !backend.is_available() {
            eprintln!(
                "onnx: skipping backend {backend}: not in this build (see the crate's features)"
            );
            continue;
        }
        for (name, path) in &models {
            if !path.exists() {
                eprintln!(
                    "onnx: skipping {name} on {backend}: {} does not exist",
                    path.display()
                );
                continue;
            }
            let source = ModelSource::Files {
                model: path,
                card: None,
            };
            let mut model = match OnnxModel::load(source, backend, &features::expectation(&layout))
            {
                Ok(m) => m,
                Err(e) => {
                    eprintln!("onnx: skipping {name} on {backend}: {e}");
                    continue;
                }
            };
            let mut output = vec![0.0f32; model.output_len()];
            group.bench_function(BenchmarkId::new(*name, backend.name()), |b| {
                b.iter(|| model.run(&input, &mut output).expect("inference"))
            });
        }
    }
    group.finish();
}
