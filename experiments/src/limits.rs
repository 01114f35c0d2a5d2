//! What a run will need, checked before any work starts: a request that cannot fit is a clear
//! error at once, not a silent hang or an out-of-memory kill an hour later.

use crate::ExperimentError;

/// The most memory an experiment may plan to hold in its results (16 GiB; the development
/// machines have 24 GB).
pub const MEMORY_LIMIT_BYTES: u64 = 16 << 30;

/// The most worker threads a run may ask for.
pub const MAX_THREADS: usize = 4096;

/// Refuses a plan whose results would need more than [`MEMORY_LIMIT_BYTES`]; `what` names the
/// run, `advice` says which option to lower.
pub fn check_memory(what: &str, bytes: u128, advice: &str) -> Result<(), ExperimentError> {
    if bytes > u128::from(MEMORY_LIMIT_BYTES) {
        return Err(ExperimentError::Invalid(format!(
            "{what} would hold about {:.1} GiB of results (limit {} GiB): {advice}",
            bytes as f64 / f64::from(1u32 << 30),
            MEMORY_LIMIT_BYTES >> 30
        )));
    }
    Ok(())
}

/// Refuses more than [`MAX_THREADS`] threads.
pub fn check_threads(threads: usize) -> Result<(), ExperimentError> {
    if threads > MAX_THREADS {
        return Err(ExperimentError::Invalid(format!(
            "--threads {threads} is above the ceiling of {MAX_THREADS}"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_over_the_limit_are_refused_with_the_figure() {
        assert!(check_memory("x", 1 << 20, "").is_ok());
        let e = check_memory("compare", 40 << 30, "lower --steps").unwrap_err();
        assert!(e.to_string().contains("40.0 GiB"), "{e}");
        assert!(check_threads(8).is_ok() && check_threads(1 << 20).is_err());
    }
}
