//! Registration of the CNN providers in a [`Registry`].

use std::path::Path;

use deepcontact_core::registry::{Params, ProviderInfo, Registry, SpecError};

use crate::backend::Backend;
use crate::model::ModelSource;
use crate::provider::{
    CnnWarmStart, PEAK, PRESSURE, PRESSURE_RESIDUAL, ProviderOptions, ShippedModel,
};

fn options(p: &mut Params<'_>) -> Result<ProviderOptions, SpecError> {
    let mut options = ProviderOptions::default();
    if let Some(v) = p.string("backend") {
        options.backend = v
            .parse::<Backend>()
            .map_err(|e| SpecError::InvalidParameter {
                spec: p.name().to_string(),
                param: "backend".into(),
                value: v.into(),
                reason: e.to_string(),
            })?;
    }
    Ok(options)
}

fn build_error(spec: &str, e: crate::OnnxError) -> SpecError {
    SpecError::Build {
        spec: spec.to_string(),
        reason: e.to_string(),
    }
}

fn shipped(registry: &mut Registry, model: ShippedModel, help: &str) {
    registry.register_provider(
        model.name,
        ProviderInfo::new(help).learned(),
        move |p, _| {
            let options = options(p)?;
            Ok(Box::new(
                CnnWarmStart::shipped(model, options).map_err(|e| build_error(model.name, e))?,
            ))
        },
    );
}

/// Registers `pressure`, `peak`, `pressure-residual` (the shipped models in `models/`) and
/// `onnx:path=...` (any model with a card). All take `backend=tract|onnxruntime`; `onnx` also
/// takes `card=...` (default: the model path with `.json`) and `name=...` (the name shown in
/// reports).
pub fn register(registry: &mut Registry) {
    shipped(
        registry,
        PRESSURE,
        "CNN (Pressure, multi-scale convolutions + 1x1 convs) on 61x61 grids via ONNX; backend=tract|onnxruntime",
    );
    shipped(
        registry,
        PEAK,
        "CNN (Peak, conv blocks + multi-scale sum + small dense layers) on 61x61 grids via ONNX; backend=tract|onnxruntime",
    );
    shipped(
        registry,
        PRESSURE_RESIDUAL,
        "residual CNN (Pressure on 8 grids: the world and the carried impulses) predicting the correction to the carried impulses; backend=tract|onnxruntime",
    );
    registry.register_provider(
        "onnx",
        ProviderInfo::new(
            "any ONNX model with a model card: path=model.onnx[,card=card.json][,name=...][,backend=tract|onnxruntime]",
        )
        .learned(),
        |p, _| {
            let Some(path) = p.string("path") else {
                return Err(SpecError::Build {
                    spec: "onnx".into(),
                    reason: "needs path=<model.onnx> (with a card beside it, same name .json)".into(),
                });
            };
            let card = p.string("card");
            let name = p.string("name").unwrap_or("onnx");
            let options = options(p)?;
            let source = ModelSource::Files { model: Path::new(path), card: card.map(Path::new) };
            Ok(Box::new(CnnWarmStart::new(name, source, options).map_err(|e| build_error("onnx", e))?))
        },
    );
}
