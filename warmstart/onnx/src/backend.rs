//! Inference backends behind `ort`, and the process-wide runtime.
//!
//! `ort` keeps its C API table and its environment in process-global state, so one process
//! runs one backend: the first model loaded picks it, and asking for the other one later is a
//! [`OnnxError::BackendConflict`]. Which backends exist is decided by cargo features:
//!
//! * `tract` (default): pure Rust through ort's alternative-backend API and `ort-tract`;
//!   sessions are built with [`GraphOptimizationLevel::Level3`], which makes tract optimise the
//!   graph (about 2× faster than the plain typed graph).
//! * `load-dynamic`: real ONNX Runtime, `dlopen`ed at run time from `ORT_DYLIB_PATH` (for
//!   instance the `libonnxruntime.so.*` inside the PyPI `onnxruntime` wheel; see
//!   `.ci/onnxruntime.sh`). ort's alternative-backend API disables its dynamic loader, so build
//!   this one with `--no-default-features --features load-dynamic`.

use std::str::FromStr;
use std::sync::OnceLock;

use ort::environment::Environment;
use ort::session::Session;
use ort::session::builder::GraphOptimizationLevel;

use crate::error::OnnxError;

/// Which inference engine runs the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Backend {
    /// tract (pure Rust), through `ort-tract`.
    Tract,
    /// ONNX Runtime, loaded from `ORT_DYLIB_PATH`.
    OnnxRuntime,
}

impl Backend {
    /// The backend's name as used in specs (`tract`, `onnxruntime`).
    pub fn name(self) -> &'static str {
        match self {
            Backend::Tract => "tract",
            Backend::OnnxRuntime => "onnxruntime",
        }
    }

    /// The default backend of this build: tract when the `tract` feature is on, else ONNX Runtime.
    pub fn default_for_build() -> Self {
        if cfg!(feature = "tract") {
            Backend::Tract
        } else {
            Backend::OnnxRuntime
        }
    }

    /// Whether this build can run the backend.
    pub fn is_available(self) -> bool {
        match self {
            Backend::Tract => cfg!(feature = "tract"),
            Backend::OnnxRuntime => cfg!(all(feature = "load-dynamic", not(feature = "tract"))),
        }
    }

    /// The backend that already owns this process, if a model was loaded.
    pub fn active() -> Option<Backend> {
        RUNTIME
            .get()
            .and_then(|r| r.as_ref().ok())
            .map(|r| r.backend)
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Backend {
    type Err = OnnxError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "tract" => Ok(Backend::Tract),
            "onnxruntime" | "ort" => Ok(Backend::OnnxRuntime),
            _ => Err(OnnxError::UnknownBackend {
                name: s.to_string(),
            }),
        }
    }
}

struct Runtime {
    backend: Backend,
    env: Environment,
}

/// The process-wide runtime; an initialisation failure is kept (as text) and reported again.
static RUNTIME: OnceLock<Result<Runtime, (Backend, String)>> = OnceLock::new();

fn init(backend: Backend) -> Result<Runtime, (Backend, String)> {
    let fail = |reason: String| (backend, reason);
    match backend {
        Backend::Tract => {
            #[cfg(feature = "tract")]
            {
                ort::set_api(ort_tract::api());
                let env = ort::init()
                    .with_name("deepcontact")
                    .build()
                    .map_err(|e| fail(e.to_string()))?;
                Ok(Runtime { backend, env })
            }
            #[cfg(not(feature = "tract"))]
            Err(fail("built without the `tract` feature".into()))
        }
        Backend::OnnxRuntime => {
            #[cfg(all(feature = "load-dynamic", not(feature = "tract")))]
            {
                let path = match std::env::var_os("ORT_DYLIB_PATH") {
                    Some(p) if !p.is_empty() => std::path::PathBuf::from(p),
                    _ => {
                        return Err(fail(
                            "ORT_DYLIB_PATH is not set (point it at libonnxruntime.so)".into(),
                        ));
                    }
                };
                if !path.exists() {
                    return Err(fail(format!(
                        "ORT_DYLIB_PATH={} does not exist",
                        path.display()
                    )));
                }
                let builder = ort::init_from(&path).map_err(|e| fail(e.to_string()))?;
                let env = builder
                    .with_name("deepcontact")
                    .build()
                    .map_err(|e| fail(e.to_string()))?;
                Ok(Runtime { backend, env })
            }
            #[cfg(not(all(feature = "load-dynamic", not(feature = "tract"))))]
            Err(fail(if cfg!(feature = "load-dynamic") {
                "the `tract` feature is on too (ort's alternative-backend API replaces its dynamic loader); \
                 build with --no-default-features --features load-dynamic"
                    .into()
            } else {
                "built without the `load-dynamic` feature".into()
            }))
        }
    }
}

fn runtime(backend: Backend) -> Result<&'static Runtime, OnnxError> {
    if !backend.is_available() {
        // Do not claim the process for a backend that cannot work.
        return Err(match init(backend) {
            Err((_, reason)) => OnnxError::BackendUnavailable {
                backend: backend.name(),
                reason,
            },
            Ok(_) => OnnxError::BackendUnavailable {
                backend: backend.name(),
                reason: "not compiled in".into(),
            },
        });
    }
    match RUNTIME.get_or_init(|| init(backend)) {
        Ok(rt) if rt.backend == backend => Ok(rt),
        Ok(rt) => Err(OnnxError::BackendConflict {
            active: rt.backend.name(),
            requested: backend.name(),
        }),
        Err((b, reason)) if *b == backend => Err(OnnxError::BackendInit {
            backend: backend.name(),
            reason: reason.clone(),
        }),
        Err((b, _)) => Err(OnnxError::BackendConflict {
            active: b.name(),
            requested: backend.name(),
        }),
    }
}

/// Builds a session for `model` (ONNX bytes) on `backend`: graph optimisation level 3,
/// one intra-op thread on ONNX Runtime (the caller parallelises over worlds, not inside one).
pub(crate) fn session(
    backend: Backend,
    model: &[u8],
    path: &std::path::Path,
    threads: usize,
) -> Result<Session, OnnxError> {
    let rt = runtime(backend)?;
    let invalid = |reason: String| OnnxError::ModelInvalid {
        path: path.to_path_buf(),
        backend: backend.name(),
        reason,
    };
    let mut builder = Session::builder(&rt.env)
        .map_err(|e| invalid(e.to_string()))?
        .with_optimization_level(GraphOptimizationLevel::Level3)
        .map_err(|e| invalid(e.to_string()))?;
    if backend == Backend::OnnxRuntime {
        builder = builder
            .with_intra_threads(threads.max(1))
            .map_err(|e| invalid(e.to_string()))?
            .with_inter_threads(1)
            .map_err(|e| invalid(e.to_string()))?;
    }
    builder
        .commit_from_memory(model)
        .map_err(|e| invalid(e.to_string()))
}
