//! The full registry: every provider and solver of this build.

use deepcontact_core::Registry;
use deepcontact_core::scene::{self, Scene};

use crate::ExperimentError;

/// The scene that `--scene` text names, for `seed`: a registered spec with parameters
/// (`box-pile:bodies=1000,friction=0.3`, built by `registry`), or a bare name with `bodies`
/// ([`scene::by_name`]: `pile`, `pyramid`, `thesis`, `file:PATH`, ...).
pub fn scene_for(
    registry: &Registry,
    text: &str,
    seed: u64,
    bodies: usize,
) -> Result<Scene, ExperimentError> {
    if text.contains(':') && !text.starts_with("file:") {
        return Ok(registry.build_scene(text, seed)?);
    }
    Ok(scene::by_name(text, seed, bodies)?)
}

/// Every scene, provider and solver this build knows: the scenes of
/// [`deepcontact_core::scene`] (`pile`, `box-pile`, `pyramid`, ...), `pgs` (deepcontact-pgs),
/// `psor`, `newton` and `pgs-rescue`
/// (deepcontact-lcp), the soft step `soft` (deepcontact-soft), the baselines (deepcontact-warmstart), `grid` (deepcontact-grid), the
/// contact-graph network `graph` and `graph-file:` (deepcontact-graph) and,
/// with the `onnx` feature, the CNNs `pressure`, `peak` and `onnx:` (deepcontact-onnx).
/// The CLI, benches, fuzz targets and tests all use this one; add your own entries to it.
///
/// ```
/// let registry = deepcontact_experiments::full_registry();
/// assert!(registry.build_solver("psor:omega=1.2").is_ok());
/// assert!(registry.build_solver("soft:substeps=4,relax=1").is_ok());
/// assert!(registry.provider_info("copy").unwrap().oracle);
/// assert!(registry.build_scene("box-pile:bodies=50", 7).is_ok());
/// ```
pub fn full_registry() -> Registry {
    let mut registry = Registry::empty();
    deepcontact_core::scene::register(&mut registry);
    deepcontact_pgs::register(&mut registry);
    deepcontact_lcp::register(&mut registry);
    deepcontact_soft::register(&mut registry);
    deepcontact_warmstart::register(&mut registry);
    deepcontact_grid::register(&mut registry);
    deepcontact_graph::register(&mut registry);
    deepcontact_relax::register(&mut registry);
    #[cfg(feature = "onnx")]
    deepcontact_onnx::register(&mut registry);
    registry
}
