//! Registration of the graph providers in a [`Registry`].

use std::path::Path;

use deepcontact_core::registry::{ProviderInfo, Registry, SpecError};

use crate::GraphWarmStart;

fn build_error(spec: &str, e: crate::GraphError) -> SpecError {
    SpecError::Build {
        spec: spec.to_string(),
        reason: e.to_string(),
    }
}

/// Registers `graph` (the shipped model) and `graph-file:path=...[,card=...][,name=...]` (any
/// model with a card; the card defaults to the weights path with `.json`).
pub fn register(registry: &mut Registry) {
    registry.register_provider(
        "graph",
        ProviderInfo::new(
            "carried impulses + a contact-graph network's correction (8 rounds of message passing, plain Rust forward pass; models/graph.safetensors)",
        )
        .learned(),
        |_, _| Ok(Box::new(GraphWarmStart::shipped().map_err(|e| build_error("graph", e))?)),
    );
    registry.register_provider(
        "graph-file",
        ProviderInfo::new(
            "a contact-graph model from disk: path=model.safetensors[,card=card.json][,name=...]",
        )
        .learned(),
        |p, _| {
            let Some(path) = p.string("path") else {
                return Err(SpecError::Build {
                    spec: "graph-file".into(),
                    reason:
                        "needs path=<model.safetensors> (with its card beside it, same name .json)"
                            .into(),
                });
            };
            let card = p.string("card").map(Path::new);
            let name = p.string("name").unwrap_or("graph-file");
            Ok(Box::new(
                GraphWarmStart::from_files(name, Path::new(path), card)
                    .map_err(|e| build_error("graph-file", e))?,
            ))
        },
    );
}
