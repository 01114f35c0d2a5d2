//! The graph model against PyTorch, its provider in a world, and bad model files.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use deepcontact_core::{WarmStart, World, WorldSettings};
use deepcontact_graph::{
    Architecture, ContactGraphModel, FEATURES, GraphError, GraphWarmStart, PointInput, Scratch,
};
use safetensors::tensor::{Dtype, TensorView};

const CARD: &str = include_str!("../../../models/graph.json");

/// The Rust forward pass reproduces the corrections PyTorch computed for the card's check
/// step (a validation step touching a wall), to float32 rounding.
#[test]
fn shipped_model_matches_pytorch_on_its_cards_check_step() {
    let card: serde_json::Value = serde_json::from_str(CARD).unwrap();
    let check = &card["check"];
    let points: Vec<PointInput> = check["features"]
        .as_array()
        .unwrap()
        .iter()
        .zip(check["bodies"].as_array().unwrap())
        .map(|(f, b)| {
            let f: Vec<f32> = serde_json::from_value(f.clone()).unwrap();
            let b: [u32; 2] = serde_json::from_value(b.clone()).unwrap();
            PointInput {
                features: f.try_into().unwrap(),
                bodies: b,
            }
        })
        .collect();
    let moving: Vec<bool> = serde_json::from_value(check["moving"].clone()).unwrap();
    let expected: Vec<[f32; 2]> = serde_json::from_value(check["corrections"].clone()).unwrap();
    assert!(points.len() >= 20 && moving.iter().any(|m| !m));
    let provider = GraphWarmStart::shipped().unwrap();
    let mut out = vec![[0.0f32; 2]; points.len()];
    provider
        .model()
        .corrections(&points, &moving, &mut Scratch::default(), &mut out);
    let scale = provider.model().architecture().impulse_scale as f32;
    let mut largest = 0.0f32;
    for (i, (o, e)) in out.iter().zip(&expected).enumerate() {
        for c in 0..2 {
            let tolerance = 1e-4 * scale + 1e-4 * e[c].abs();
            assert!(
                (o[c] - e[c]).abs() <= tolerance,
                "point {i}: {o:?} against {e:?}"
            );
        }
        largest = largest.max(e[0].abs()).max(e[1].abs());
    }
    // The case is not trivial: the model moves some impulse by a visible amount.
    assert!(largest > 1e-3 * scale, "largest correction {largest}");
}

/// Weights for a model of the given shape: deterministic pseudo-random entries, the head
/// scaled by `head` (0 gives a model that corrects nothing).
fn weights(
    arch: &Architecture,
    head: f32,
    edit: impl Fn(&str, &mut Vec<f32>, &mut Vec<usize>),
) -> Vec<u8> {
    let (h, k) = (arch.hidden, arch.channels);
    let mut shapes: Vec<(String, Vec<usize>)> = vec![
        ("encoder.weight".into(), vec![h, FEATURES.len()]),
        ("encoder.bias".into(), vec![h]),
        ("head.weight".into(), vec![2, h]),
        ("head.bias".into(), vec![2]),
        ("feature_mean".into(), vec![FEATURES.len()]),
        ("feature_std".into(), vec![FEATURES.len()]),
    ];
    for r in 0..arch.rounds {
        shapes.push((format!("message.{r}.weight"), vec![3 * k, h]));
        shapes.push((format!("message.{r}.bias"), vec![3 * k]));
        shapes.push((format!("update.{r}.weight"), vec![h, h + 6 * k]));
        shapes.push((format!("update.{r}.bias"), vec![h]));
    }
    let mut state = 0x9e3779b97f4a7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    let tensors: Vec<(String, Vec<usize>, Vec<u8>)> = shapes
        .into_iter()
        .map(|(name, mut shape)| {
            let len = shape.iter().product();
            let mut v: Vec<f32> = (0..len).map(|_| next()).collect();
            if name == "feature_std" {
                v.iter_mut().for_each(|x| *x = 1.0 + x.abs());
            }
            if name.starts_with("head") {
                v.iter_mut().for_each(|x| *x *= head);
            }
            edit(&name, &mut v, &mut shape);
            let bytes = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            (name, shape, bytes)
        })
        .collect();
    let views: Vec<(String, TensorView<'_>)> = tensors
        .iter()
        .map(|(n, s, b)| {
            (
                n.clone(),
                TensorView::new(Dtype::F32, s.clone(), b).unwrap(),
            )
        })
        .collect();
    let meta = HashMap::from([
        ("format".to_string(), "deepcontact-graph-model".to_string()),
        (
            "architecture".to_string(),
            serde_json::to_string(arch).unwrap(),
        ),
    ]);
    safetensors::serialize(views, Some(meta)).unwrap()
}

fn small() -> Architecture {
    Architecture {
        model: "contact-graph".into(),
        features: FEATURES.iter().map(|f| f.to_string()).collect(),
        hidden: 8,
        channels: 2,
        rounds: 2,
        impulse_scale: 0.5,
    }
}

fn pile_world() -> World {
    deepcontact_core::scene::pile(7, 40)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap()
}

/// Runs `provider` for `steps` steps of a 40-circle pile; returns the fallbacks and the
/// world's contact impulses at the end.
fn run(provider: &mut dyn WarmStart, steps: usize) -> (usize, Vec<(f64, f64)>) {
    let mut world = pile_world();
    let mut solver = deepcontact_pgs::PgsSolver::default();
    let mut position = deepcontact_pgs::PgsPositionSolver::default();
    let mut fallbacks = 0;
    for _ in 0..steps {
        fallbacks += world
            .step(provider, &mut solver, &mut position)
            .unwrap()
            .fallbacks;
    }
    let impulses = world
        .contacts()
        .iter()
        .map(|(_, i)| (i.normal, i.tangent))
        .collect();
    (fallbacks, impulses)
}

/// A model whose head is zero corrects nothing: the pile runs bit-identically to builtin.
#[test]
fn a_model_with_a_zero_head_is_builtin() {
    let bytes = weights(&small(), 0.0, |_, _, _| {});
    let model = ContactGraphModel::from_safetensors(&bytes, Path::new("zero-head")).unwrap();
    let mut graph = GraphWarmStart::new("zero", Arc::new(model));
    let (fallbacks, with_graph) = run(&mut graph, 120);
    let (_, with_builtin) = run(&mut deepcontact_core::CarriedWarmStart, 120);
    assert_eq!(fallbacks, 0);
    assert!(!with_builtin.is_empty());
    let bits = |v: &[(f64, f64)]| -> Vec<(u64, u64)> {
        v.iter().map(|(n, t)| (n.to_bits(), t.to_bits())).collect()
    };
    assert_eq!(bits(&with_graph), bits(&with_builtin));
}

/// The shipped model runs a pile without fallbacks, reports what it did, and changes the
/// starts (it is not builtin in disguise).
#[test]
fn shipped_graph_runs_a_pile_and_corrects_the_carried_impulses() {
    let mut graph = GraphWarmStart::shipped().unwrap();
    let (fallbacks, impulses) = run(&mut graph, 120);
    assert_eq!(fallbacks, 0);
    assert!(
        impulses
            .iter()
            .all(|(n, t)| n.is_finite() && t.is_finite() && *n >= 0.0)
    );
    let d: HashMap<String, f64> = graph.diagnostics().into_iter().collect();
    assert!(d["points_evaluated"] > 100.0, "{d:?}");
    assert!(d["mean_abs_normal_correction"] > 0.0, "{d:?}");
}

/// Bad model files are typed errors naming what is wrong.
#[test]
fn bad_model_files_are_typed_errors() {
    let arch = small();
    let path = Path::new("bad");
    let load = |bytes: Vec<u8>| ContactGraphModel::from_safetensors(&bytes, path).unwrap_err();
    // A layer of the wrong shape.
    let e = load(weights(&arch, 1.0, |name, v, shape| {
        if name == "update.1.weight" {
            shape[1] += 1;
            v.extend(std::iter::repeat_n(0.0, shape[0]));
        }
    }));
    assert!(
        matches!(&e, GraphError::Tensor { name, .. } if name == "update.1.weight"),
        "{e}"
    );
    // A NaN weight.
    let e = load(weights(&arch, 1.0, |name, v, _| {
        if name == "encoder.bias" {
            v[3] = f32::NAN;
        }
    }));
    assert!(
        matches!(&e, GraphError::Tensor { reason, .. } if reason.contains("NaN")),
        "{e}"
    );
    // A zero feature deviation.
    let e = load(weights(&arch, 1.0, |name, v, _| {
        if name == "feature_std" {
            v[0] = 0.0;
        }
    }));
    assert!(
        matches!(&e, GraphError::Tensor { name, .. } if name == "feature_std"),
        "{e}"
    );
    // Other features than this build's.
    let mut other = arch.clone();
    other.features.swap(0, 1);
    let e = load(weights(&other, 1.0, |_, _, _| {}));
    assert!(matches!(e, GraphError::Format { .. }), "{e}");
    // Not safetensors at all.
    let e = load(b"not a model".to_vec());
    assert!(matches!(e, GraphError::Format { .. }), "{e}");
}

/// A card that does not match its weights file, or a missing card, is refused.
#[test]
fn a_card_for_other_weights_is_refused() {
    let dir = std::env::temp_dir().join(format!("dc-graph-card-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("m.safetensors");
    std::fs::write(&model, weights(&small(), 1.0, |_, _, _| {})).unwrap();
    let e = GraphWarmStart::from_files("m", &model, None).unwrap_err();
    assert!(matches!(e, GraphError::Io { .. }), "{e}");
    let mut card: serde_json::Value = serde_json::from_str(CARD).unwrap();
    card["architecture"] = serde_json::to_value(small()).unwrap();
    std::fs::write(dir.join("m.json"), card.to_string()).unwrap();
    let e = GraphWarmStart::from_files("m", &model, None).unwrap_err();
    assert!(matches!(e, GraphError::HashMismatch { .. }), "{e}");
    card["sha256"] = deepcontact_graph::card::sha256_hex(&std::fs::read(&model).unwrap()).into();
    std::fs::write(dir.join("m.json"), card.to_string()).unwrap();
    let provider = GraphWarmStart::from_files("m", &model, None).unwrap();
    assert_eq!(provider.name(), "m");
    // A CNN's card is named as another kind of card.
    let cnn = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/pressure.json");
    let e = GraphWarmStart::from_files("m", &model, Some(&cnn)).unwrap_err();
    assert!(
        matches!(&e, GraphError::Card { reason, .. } if reason.contains("deepcontact-model-card")),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
