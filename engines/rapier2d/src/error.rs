//! The adapter's error type.

use deepcontact_core::{CoreError, WarmStartError};

/// Why a step of the adapter could not do what was asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AdapterError {
    /// The provider failed or wrote an unusable start (wrong length, NaN, negative normal) for
    /// one manifold, under [`OnFailure::Error`](crate::OnFailure::Error); rapier's own carried
    /// values were used for that manifold.
    #[error(
        "provider {provider:?} on the manifold of colliders {collider1} and {collider2} (step {step}): {source}"
    )]
    Provider {
        /// The provider's name.
        provider: String,
        /// Step index (0 = the first step the hooks saw).
        step: u64,
        /// Index of collider 1 of the pair.
        collider1: u32,
        /// Index of collider 2 of the pair.
        collider2: u32,
        /// What the guard found.
        source: WarmStartError,
    },
    /// rapier's contacts did not make a valid deepcontact problem (e.g. a degenerate normal);
    /// rapier's own carried values were used for that manifold.
    #[error("contact problem of colliders {collider1} and {collider2}: {source}")]
    Problem {
        /// Index of collider 1 of the pair.
        collider1: u32,
        /// Index of collider 2 of the pair.
        collider2: u32,
        /// The core's complaint.
        source: CoreError,
    },
    /// A manifold warm-started during the step was not found in the narrow phase afterwards.
    #[error(
        "manifold of colliders {collider1} and {collider2} (subshapes {subshape1}, {subshape2}) vanished during the step"
    )]
    MissingManifold {
        /// Index of collider 1 of the pair.
        collider1: u32,
        /// Index of collider 2 of the pair.
        collider2: u32,
        /// Sub-shape of collider 1.
        subshape1: u32,
        /// Sub-shape of collider 2.
        subshape2: u32,
    },
    /// `modify_solver_contacts` ran without [`WarmStartHooks::begin_step`](crate::WarmStartHooks::begin_step)
    /// first: rapier's own warm starts were used for `manifolds` manifolds.
    #[error(
        "the hooks ran without begin_step for {manifolds} manifolds (rapier's own warm starts were kept)"
    )]
    NotBegun {
        /// Manifolds left with rapier's own warm start.
        manifolds: usize,
    },
    /// The provider panicked inside a hook; the hooks' state is lost.
    #[error("the provider panicked inside a hook (its state is poisoned)")]
    Poisoned,
    /// A scene body could not be turned into a rapier body or collider.
    #[error("scene body {body}: {reason}")]
    Scene {
        /// Index of the body in the scene.
        body: usize,
        /// What is wrong with it.
        reason: String,
    },
}
