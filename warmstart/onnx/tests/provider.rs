//! Model loading, card checks, the provider on a real pile step, and backend agreement.
//!
//! The test models in `tests/data` come from `tests/data/make_test_models.py`;
//! `tiny_reference.bin` is the output of `tiny.onnx` on the reference input as computed by
//! ONNX Runtime (Python), so the tract test below checks tract against ONNX Runtime, and the
//! `load-dynamic` test checks the Rust ONNX Runtime backend against the same numbers.

use std::path::{Path, PathBuf};

use deepcontact_core::{
    GuardPolicy, Impulse, WarmStart, WarmStartContext, WarmStartError, WorldSettings,
};
use deepcontact_onnx::{
    Backend, CnnWarmStart, GridLayout, ModelSource, OnnxError, OnnxModel, ProviderOptions,
};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("data")
        .join(name)
}

fn backend() -> Backend {
    Backend::default_for_build()
}

/// An ONNX Runtime-only build without `ORT_DYLIB_PATH` cannot run a model: skip with a note,
/// except under `CI=true`, where `.ci/onnxruntime.sh` sets it (a skip there would pass
/// without testing ONNX Runtime).
fn cannot_run() -> bool {
    let skip = backend() == Backend::OnnxRuntime && std::env::var_os("ORT_DYLIB_PATH").is_none();
    if skip {
        fail_under_ci();
        eprintln!("note: ORT_DYLIB_PATH is not set; skipping (see .ci/onnxruntime.sh)");
    }
    skip
}

/// Panics under `CI=true`: a test that needs ONNX Runtime found no `ORT_DYLIB_PATH`.
fn fail_under_ci() {
    assert!(
        std::env::var("CI").as_deref() != Ok("true"),
        "CI=true but ORT_DYLIB_PATH is not set: the ONNX Runtime tests would be skipped \
         (run them through .ci/onnxruntime.sh)"
    );
}

fn load(model: &str, card: Option<&str>) -> Result<OnnxModel, OnnxError> {
    let model = data(model);
    let card = card.map(data);
    OnnxModel::load(
        ModelSource::Files {
            model: &model,
            card: card.as_deref(),
        },
        backend(),
        &deepcontact_onnx::features::expectation(&GridLayout::thesis()),
    )
}

/// x[c, j, i] = sin(0.1 (c + 1) i) cos(0.07 j) + 0.1 c (as in make_test_models.py).
fn reference_input() -> Vec<f32> {
    let mut x = Vec::with_capacity(6 * 61 * 61);
    for c in 0..6 {
        for j in 0..61 {
            for i in 0..61 {
                let v = (0.1 * (c + 1) as f64 * i as f64).sin() * (0.07 * j as f64).cos()
                    + 0.1 * c as f64;
                x.push(v as f32);
            }
        }
    }
    x
}

fn reference_output() -> Vec<f32> {
    let bytes = std::fs::read(data("tiny_reference.bin")).unwrap();
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn swapped_channels_in_card_are_named() {
    match load("tiny.onnx", Some("tiny_swapped_channels.json")) {
        Err(OnnxError::ChannelMismatch {
            tensor,
            index,
            expected,
            found,
        }) => {
            assert_eq!(
                (tensor, index, expected.as_str(), found.as_str()),
                ("input", 1, "vx", "vy")
            );
        }
        other => panic!("expected ChannelMismatch, got {other:?}"),
    }
}

#[test]
fn wrong_card_shape_is_named() {
    match load("tiny.onnx", Some("tiny_wrong_shape.json")) {
        Err(OnnxError::ShapeMismatch {
            what,
            expected,
            found,
        }) => {
            assert_eq!(what, "card input");
            assert_eq!(expected, vec![1, 6, 61, 61]);
            assert_eq!(found, vec![1, 6, 64, 64]);
        }
        other => panic!("expected ShapeMismatch, got {other:?}"),
    }
}

#[test]
fn model_with_wrong_output_channels_is_rejected() {
    if cannot_run() {
        return;
    }
    match load("wrong_output.onnx", None) {
        Err(OnnxError::ShapeMismatch {
            what,
            expected,
            found,
        }) => {
            assert_eq!(what, "model output");
            assert_eq!(expected, vec![1, 2, 61, 61]);
            assert_eq!(found, vec![1, 3, 61, 61]);
        }
        other => panic!("expected ShapeMismatch, got {other:?}"),
    }
}

#[test]
fn card_grid_layout_difference_is_named() {
    let card = std::fs::read_to_string(data("tiny.json"))
        .unwrap()
        .replace("\"spacing\": 0.25", "\"spacing\": 0.125");
    let model = std::fs::read(data("tiny.onnx")).unwrap();
    let err = OnnxModel::load(
        ModelSource::Memory {
            model: &model,
            card: &card,
            name: "tiny",
        },
        backend(),
        &deepcontact_onnx::features::expectation(&GridLayout::thesis()),
    )
    .unwrap_err();
    match err {
        OnnxError::GridMismatch {
            field,
            expected,
            found,
        } => {
            assert_eq!(field, "grid_layout.grid.spacing");
            assert_eq!((expected.as_str(), found.as_str()), ("0.25", "0.125"));
        }
        other => panic!("expected GridMismatch, got {other:?}"),
    }
}

#[test]
fn missing_and_corrupt_files_are_typed_errors() {
    if cannot_run() {
        return;
    }
    assert!(matches!(
        load("nope.onnx", Some("tiny.json")),
        Err(OnnxError::ModelMissing { .. })
    ));
    let dir = std::env::temp_dir().join(format!("deepcontact-onnx-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A model without a card.
    let lonely = dir.join("lonely.onnx");
    std::fs::copy(data("tiny.onnx"), &lonely).unwrap();
    let layout = deepcontact_onnx::features::expectation(&GridLayout::thesis());
    let r = OnnxModel::load(
        ModelSource::Files {
            model: &lonely,
            card: None,
        },
        backend(),
        &layout,
    );
    assert!(matches!(r, Err(OnnxError::CardMissing { .. })), "{r:?}");
    // A corrupt model with a valid card.
    let corrupt = dir.join("corrupt.onnx");
    std::fs::write(&corrupt, b"this is not an onnx protobuf \x00\x01\x02\xff").unwrap();
    std::fs::copy(data("tiny.json"), dir.join("corrupt.json")).unwrap();
    let r = OnnxModel::load(
        ModelSource::Files {
            model: &corrupt,
            card: None,
        },
        backend(),
        &layout,
    );
    assert!(matches!(r, Err(OnnxError::ModelInvalid { .. })), "{r:?}");
    // A corrupt card.
    std::fs::write(dir.join("lonely.json"), b"{ not json").unwrap();
    let r = OnnxModel::load(
        ModelSource::Files {
            model: &lonely,
            card: None,
        },
        backend(),
        &layout,
    );
    assert!(matches!(r, Err(OnnxError::CardInvalid { .. })), "{r:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unknown_backend_and_registry_errors() {
    if cannot_run() {
        return;
    }
    assert!(matches!(
        "nope".parse::<Backend>(),
        Err(OnnxError::UnknownBackend { .. })
    ));
    let mut registry = deepcontact_core::Registry::empty();
    deepcontact_pgs::register(&mut registry);
    deepcontact_warmstart::register(&mut registry);
    deepcontact_onnx::register(&mut registry);
    assert!(registry.build_provider("onnx").is_err());
    assert!(
        registry
            .build_provider("onnx:path=/does/not/exist.onnx")
            .is_err()
    );
    assert!(registry.build_provider("pressure:backend=nope").is_err());
    let spec = format!("onnx:path={},name=tiny", data("tiny.onnx").display());
    let p = registry.build_provider(&spec).unwrap();
    assert_eq!(p.name(), "tiny");
}

/// Checks every warm start on the way (finite, normal ≥ 0), counts the calls, and keeps the
/// starts and the carried impulses it was given.
struct Checked {
    inner: CnnWarmStart,
    calls: usize,
    points: usize,
    starts: Vec<Impulse>,
    carried: Vec<Impulse>,
}

impl Checked {
    fn new(inner: CnnWarmStart) -> Self {
        Self {
            inner,
            calls: 0,
            points: 0,
            starts: Vec::new(),
            carried: Vec::new(),
        }
    }
}

impl WarmStart for Checked {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.inner.warm_start(ctx, out)?;
        assert_eq!(out.len(), ctx.problem.points.len());
        for imp in out.iter() {
            assert!(imp.is_finite(), "{imp:?}");
            assert!(imp.normal >= 0.0, "{imp:?}");
        }
        self.calls += 1;
        self.points += out.len();
        self.starts.extend_from_slice(out);
        self.carried.extend(ctx.carried_impulses());
        Ok(())
    }
}

#[test]
fn provider_output_on_a_pile_step_is_finite_and_admissible() {
    if cannot_run() {
        return;
    }
    let settings = WorldSettings {
        guard: GuardPolicy::Error,
        ..WorldSettings::default()
    };
    let mut world = deepcontact_core::scene::pile(3, 100)
        .unwrap()
        .build(settings)
        .unwrap();
    let mut solver = deepcontact_pgs::PgsSolver::default();
    let mut position = deepcontact_pgs::PgsPositionSolver::default();
    let mut builtin = deepcontact_core::CarriedWarmStart;
    for _ in 0..400 {
        let r = world
            .step(&mut builtin, &mut solver, &mut position)
            .unwrap();
        if r.contacts >= 30 {
            break;
        }
    }
    let inner = CnnWarmStart::new(
        "tiny",
        ModelSource::Files {
            model: &data("tiny.onnx"),
            card: None,
        },
        ProviderOptions { backend: backend() },
    )
    .unwrap();
    let mut provider = Checked::new(inner);
    let report = world
        .step(&mut provider, &mut solver, &mut position)
        .unwrap();
    assert!(
        report.contacts >= 30,
        "pile never touched: {} contacts",
        report.contacts
    );
    assert_eq!(report.fallbacks, 0);
    assert_eq!(provider.calls, report.islands);
    assert_eq!(provider.points, report.contacts);
    // The input grids carry the walls and the bodies.
    let input = provider.inner.last_input();
    assert_eq!(input[0], 100.0);
    let body_mass: f32 = input[..61 * 61].iter().filter(|&&m| m < 50.0).sum();
    assert!(
        (body_mass - 100.0 * std::f32::consts::PI * 0.25).abs() < 1.0,
        "{body_mass}"
    );
}

#[cfg(feature = "tract")]
#[test]
fn tract_agrees_with_onnxruntime_reference() {
    let mut model = load("tiny.onnx", None).unwrap();
    assert_eq!(model.backend(), Backend::Tract);
    let mut out = vec![0.0; model.output_len()];
    model.run(&reference_input(), &mut out).unwrap();
    let diff = max_abs_diff(&out, &reference_output());
    assert!(diff < 1e-4, "tract differs from ONNX Runtime by {diff}");
    // Wrong buffer sizes are errors, not panics.
    assert!(matches!(
        model.run(&[0.0; 3], &mut out),
        Err(OnnxError::ShapeMismatch { .. })
    ));
}

#[cfg(all(feature = "load-dynamic", not(feature = "tract")))]
#[test]
fn onnxruntime_agrees_with_reference() {
    if std::env::var_os("ORT_DYLIB_PATH").is_none() {
        fail_under_ci();
        eprintln!(
            "note: ORT_DYLIB_PATH is not set; skipping the ONNX Runtime backend test (see .ci/onnxruntime.sh)"
        );
        return;
    }
    let mut model = load("tiny.onnx", None).unwrap();
    assert_eq!(model.backend(), Backend::OnnxRuntime);
    let mut out = vec![0.0; model.output_len()];
    model.run(&reference_input(), &mut out).unwrap();
    let diff = max_abs_diff(&out, &reference_output());
    assert!(
        diff < 1e-4,
        "ONNX Runtime (Rust) differs from the reference by {diff}"
    );
}

#[test]
fn shipped_models_load_and_run_on_a_pile_step() {
    if cannot_run() {
        return;
    }
    let mut registry = deepcontact_core::Registry::empty();
    deepcontact_pgs::register(&mut registry);
    deepcontact_warmstart::register(&mut registry);
    deepcontact_onnx::register(&mut registry);
    let (mut world, mut solver, mut position) = pile_after(60);
    for shipped in [deepcontact_onnx::PRESSURE, deepcontact_onnx::PEAK] {
        let card =
            deepcontact_onnx::ModelCard::load(&shipped.path().with_extension("json")).unwrap();
        assert_eq!(card.name, shipped.name);
        assert!(card.parameters > 0);
        let mut provider = registry.build_provider(shipped.name).unwrap();
        assert_eq!(provider.name(), shipped.name);
        let report = world
            .step(provider.as_mut(), &mut solver, &mut position)
            .unwrap();
        assert!(report.contacts > 0);
        assert_eq!(report.fallbacks, 0, "{} fell back to zeros", shipped.name);
    }
}

/// The residual model reads the carried impulses as two more grids (its card says so, and a
/// card that denies it is refused) and corrects them: on a settled pile its starts stay near
/// the carried impulses (a correction, not a new prediction) without being them.
#[test]
fn residual_model_corrects_the_carried_impulses() {
    if cannot_run() {
        return;
    }
    let shipped = deepcontact_onnx::PRESSURE_RESIDUAL;
    let card_path = shipped.path().with_extension("json");
    let card = deepcontact_onnx::ModelCard::load(&card_path).unwrap();
    assert!(card.residual);
    assert_eq!(card.input.shape, vec![1, 8, 61, 61]);
    // The same model with a card that denies the carried channels is refused.
    let mut denied: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&card_path).unwrap()).unwrap();
    denied["residual"] = false.into();
    let denied_path = std::env::temp_dir().join(format!("dc-denied-{}.json", std::process::id()));
    std::fs::write(&denied_path, denied.to_string()).unwrap();
    let e = CnnWarmStart::new(
        "denied",
        ModelSource::Files {
            model: &shipped.path(),
            card: Some(&denied_path),
        },
        ProviderOptions { backend: backend() },
    )
    .unwrap_err();
    std::fs::remove_file(&denied_path).ok();
    assert!(
        matches!(
            e,
            OnnxError::ChannelCount { .. } | OnnxError::ShapeMismatch { .. }
        ),
        "{e}"
    );

    let (mut world, mut solver, mut position) = pile_after(150);
    let inner = CnnWarmStart::shipped(shipped, ProviderOptions { backend: backend() }).unwrap();
    let mut provider = Checked::new(inner);
    let report = world
        .step(&mut provider, &mut solver, &mut position)
        .unwrap();
    assert_eq!(report.fallbacks, 0);
    assert_eq!(provider.inner.last_input().len(), 8 * 61 * 61);
    let carried_grid: f32 = provider.inner.last_input()[6 * 61 * 61..7 * 61 * 61]
        .iter()
        .sum();
    assert!(
        carried_grid > 0.0,
        "the carried normal impulses are on the grid"
    );
    let n = provider.starts.len() as f64;
    assert!(n > 50.0);
    let moved: f64 = provider
        .starts
        .iter()
        .zip(&provider.carried)
        .map(|(s, c)| (s.normal - c.normal).abs())
        .sum::<f64>()
        / n;
    let load: f64 = provider.carried.iter().map(|c| c.normal).sum::<f64>() / n;
    assert!(moved > 0.0 && moved < load, "moved {moved}, carried {load}");
}

/// The thesis pile (seed 12345) after `steps` builtin steps, with its solvers; a provider
/// failure is an error, not a fallback.
fn pile_after(
    steps: usize,
) -> (
    deepcontact_core::World,
    deepcontact_pgs::PgsSolver,
    deepcontact_pgs::PgsPositionSolver,
) {
    let mut world = deepcontact_core::scene::pile(12345, 100)
        .unwrap()
        .build(WorldSettings {
            guard: GuardPolicy::Error,
            ..WorldSettings::default()
        })
        .unwrap();
    let mut solver = deepcontact_pgs::PgsSolver::default();
    let mut position = deepcontact_pgs::PgsPositionSolver::default();
    for _ in 0..steps {
        world
            .step(
                &mut deepcontact_core::CarriedWarmStart,
                &mut solver,
                &mut position,
            )
            .unwrap();
    }
    (world, solver, position)
}
