//! Regression tests of the bugs found by fuzzing and property testing (one test per bug,
//! named after it). The harness is the fuzzers' own (`fuzz/src/lib.rs`).

#[path = "../../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod harness;

use std::path::Path;

use deepcontact_core::{CoreError, scene};
use deepcontact_onnx::{ModelCard, OnnxError};

fn models() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../models"))
}

/// `peak.onnx` loaded with `pressure.json` ran without complaint: both have the same input and
/// output shapes, so the card's shape checks passed. Cards now pin their file by SHA-256.
#[test]
fn regression_card_of_another_model_was_accepted() {
    let card = ModelCard::load(&models().join("pressure.json")).unwrap();
    let own = std::fs::read(models().join("pressure.onnx")).unwrap();
    card.check_model_bytes(&own, Path::new("pressure.onnx"))
        .unwrap();
    let other = std::fs::read(models().join("peak.onnx")).unwrap();
    let err = card
        .check_model_bytes(&other, Path::new("peak.onnx"))
        .unwrap_err();
    assert!(
        matches!(&err, OnnxError::ModelHashMismatch { card, .. } if card == "pressure"),
        "{err}"
    );
    // Every committed card pins its model.
    for name in ["pressure", "peak"] {
        let card = ModelCard::load(&models().join(format!("{name}.json"))).unwrap();
        assert!(
            card.model_sha256.is_some(),
            "{name}.json has no model_sha256"
        );
        let bytes = std::fs::read(models().join(format!("{name}.onnx"))).unwrap();
        card.check_model_bytes(&bytes, Path::new(name)).unwrap();
    }
}

/// `--scene nosuch` printed "invalid setting scene = NaN: unknown scene name".
#[test]
fn regression_unknown_scene_was_reported_as_a_nan_setting() {
    let err = scene::by_name("nosuch", 1, 100).unwrap_err();
    assert!(
        matches!(&err, CoreError::UnknownScene { name, known } if name == "nosuch" && known.contains("pile")),
        "{err}"
    );
}

/// `--bodies 0` blamed the circle radius ("pile.radius = 0.5: must be > 0 and fit the box").
#[test]
fn regression_empty_pile_blamed_the_radius() {
    let err = scene::pile(1, 0).unwrap_err();
    assert!(
        matches!(
            err,
            CoreError::InvalidSetting {
                name: "pile.bodies",
                ..
            }
        ),
        "{err}"
    );
}
