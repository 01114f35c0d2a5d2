//! A comparison in parts: the runs of some seeds as bytes (what a cluster task returns), and
//! the parts of every seed merged into the files and rows of the one-machine comparison.
//!
//! The encoding is little-endian and exact (floats as their bits), so a merged comparison has
//! the numbers of the one-machine run. A part starts with [`MAGIC`], then the solver and warm
//! start labels it ran, then its runs.

use deepcontact_experiments::compare::{Results, Run, StepRecord};
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::compare::{self, CompareArgs};
use crate::error::PythonBindingError;
use crate::provider::Pending;

/// The first bytes of a part (format name and version).
pub const MAGIC: &[u8; 8] = b"DCPART1\0";

/// Appends little-endian numbers and length-prefixed strings to a byte vector.
struct Writer(Vec<u8>);

impl Writer {
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn len(&mut self, v: usize) {
        self.u64(v as u64);
    }
    fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
    fn str(&mut self, s: &str) {
        self.len(s.len());
        self.0.extend_from_slice(s.as_bytes());
    }
    fn labels(&mut self, labels: &[String]) {
        self.len(labels.len());
        for l in labels {
            self.str(l);
        }
    }
}

/// Reads what [`Writer`] wrote; every read checks the bytes left.
struct Reader<'a> {
    bytes: &'a [u8],
    part: usize,
}

impl Reader<'_> {
    fn bad(&self, what: &str) -> PythonBindingError {
        PythonBindingError::Part {
            part: self.part,
            reason: what.to_string(),
        }
    }
    fn take(&mut self, n: usize) -> Result<&[u8], PythonBindingError> {
        if self.bytes.len() < n {
            return Err(self.bad("truncated"));
        }
        let (head, tail) = self.bytes.split_at(n);
        self.bytes = tail;
        Ok(head)
    }
    fn u64(&mut self) -> Result<u64, PythonBindingError> {
        let mut b = [0u8; 8];
        b.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(b))
    }
    /// A count or length, at most the bytes left (so a corrupt count cannot allocate much).
    fn len(&mut self) -> Result<usize, PythonBindingError> {
        let n = self.u64()?;
        if n > self.bytes.len() as u64 {
            return Err(self.bad("a length past the end"));
        }
        Ok(n as usize)
    }
    fn usize(&mut self) -> Result<usize, PythonBindingError> {
        usize::try_from(self.u64()?).map_err(|_| self.bad("a count too large"))
    }
    fn f64(&mut self) -> Result<f64, PythonBindingError> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn str(&mut self) -> Result<String, PythonBindingError> {
        let n = self.len()?;
        let bytes = self.take(n)?.to_vec();
        String::from_utf8(bytes).map_err(|_| self.bad("a label that is not UTF-8"))
    }
    fn labels(&mut self) -> Result<Vec<String>, PythonBindingError> {
        let n = self.len()?;
        (0..n).map(|_| self.str()).collect()
    }
}

/// The runs of `results` as a part.
pub fn encode(results: &Results) -> Vec<u8> {
    let mut w = Writer(MAGIC.to_vec());
    w.labels(&results.solvers);
    w.labels(&results.warm_starts);
    w.len(results.runs.len());
    for run in &results.runs {
        w.len(run.solver);
        w.len(run.warm_start);
        w.u64(run.seed);
        w.len(run.steps.len());
        for r in &run.steps {
            w.u64(r.step);
            w.len(r.contacts);
            w.len(r.islands);
            w.u64(u64::from(r.iterations));
            w.u64(r.iterations_sum);
            w.len(r.capped_islands);
            w.f64(r.final_residual);
            w.f64(r.natural_residual);
            w.f64(r.mse_normal);
            w.f64(r.mse_tangent);
            w.len(r.fallbacks);
            w.f64(r.warm_start_seconds);
            w.f64(r.solve_seconds);
            w.f64(r.step_seconds);
            w.u64(r.provider_passes);
            w.f64(r.penetration_mean);
            w.f64(r.penetration_max);
            w.f64(r.normal_velocity_error_mean);
            w.f64(r.normal_velocity_error_max);
            w.f64(r.kinetic_energy);
        }
        w.len(run.curves.len());
        for curve in &run.curves {
            w.len(curve.len());
            for &x in curve {
                w.f64(x);
            }
        }
        w.len(run.diagnostics.len());
        for (name, value) in &run.diagnostics {
            w.str(name);
            w.f64(*value);
        }
    }
    w.0
}

/// One step record read back.
fn step_record(r: &mut Reader<'_>) -> Result<StepRecord, PythonBindingError> {
    Ok(StepRecord {
        step: r.u64()?,
        contacts: r.usize()?,
        islands: r.usize()?,
        iterations: u32::try_from(r.u64()?).map_err(|_| r.bad("iterations past u32"))?,
        iterations_sum: r.u64()?,
        capped_islands: r.usize()?,
        final_residual: r.f64()?,
        natural_residual: r.f64()?,
        mse_normal: r.f64()?,
        mse_tangent: r.f64()?,
        fallbacks: r.usize()?,
        warm_start_seconds: r.f64()?,
        solve_seconds: r.f64()?,
        step_seconds: r.f64()?,
        provider_passes: r.u64()?,
        penetration_mean: r.f64()?,
        penetration_max: r.f64()?,
        normal_velocity_error_mean: r.f64()?,
        normal_velocity_error_max: r.f64()?,
        kinetic_energy: r.f64()?,
    })
}

/// The runs of part number `part`, checked against the labels the merged comparison expects.
fn decode(
    bytes: &[u8],
    part: usize,
    solvers: &[String],
    warm_starts: &[String],
) -> Result<Vec<Run>, PythonBindingError> {
    let mut r = Reader { bytes, part };
    if r.take(MAGIC.len())? != MAGIC {
        return Err(r.bad("not a comparison part (wrong magic bytes)"));
    }
    if r.labels()? != solvers || r.labels()? != warm_starts {
        return Err(r.bad("its solvers or warm starts differ from the comparison's"));
    }
    let n = r.len()?;
    let mut runs = Vec::with_capacity(n);
    for _ in 0..n {
        let solver = r.usize()?;
        let warm_start = r.usize()?;
        let seed = r.u64()?;
        let steps = (0..r.len()?)
            .map(|_| step_record(&mut r))
            .collect::<Result<Vec<_>, _>>()?;
        let mut curves = Vec::new();
        for _ in 0..r.len()? {
            let len = r.len()?;
            curves.push((0..len).map(|_| r.f64()).collect::<Result<Vec<_>, _>>()?);
        }
        let diagnostics = (0..r.len()?)
            .map(|_| Ok((r.str()?, r.f64()?)))
            .collect::<Result<Vec<_>, PythonBindingError>>()?;
        if solver >= solvers.len() || warm_start >= warm_starts.len() {
            return Err(r.bad("a run's solver or warm start index is out of range"));
        }
        runs.push(Run {
            solver,
            warm_start,
            seed,
            steps,
            curves,
            diagnostics,
        });
    }
    if !r.bytes.is_empty() {
        return Err(r.bad("bytes after the last run"));
    }
    Ok(runs)
}

/// Runs the comparison `args` describe (usually a few of its seeds) and returns it as a part.
pub fn run_part(py: Python<'_>, args: &CompareArgs) -> Result<Vec<u8>, PythonBindingError> {
    let results = compare::results(py, args)?;
    Ok(encode(&results))
}

/// Merges `parts` (whose seeds together are `args.seeds`, each run exactly once) into the
/// comparison of `args`: writes its files into `args.out` (if any) and returns its summary
/// rows, as [`compare::run`] would have. `threads` and `wall_seconds` are what the summary
/// reports as the threads and wall time.
pub fn merge(
    py: Python<'_>,
    args: &CompareArgs,
    parts: &[Vec<u8>],
    threads: usize,
    wall_seconds: f64,
) -> Result<Py<PyList>, PythonBindingError> {
    let pending = std::sync::Arc::new(Pending::default());
    let (_, warm_starts) = compare::resolve(py, args, &pending)?;
    let config = compare::config(args, warm_starts)?;
    config.validate()?;
    let solvers = config.solver_labels();
    let labels = config.warm_start_labels();
    let mut runs = Vec::new();
    for (i, part) in parts.iter().enumerate() {
        runs.extend(decode(part, i, &solvers, &labels)?);
    }
    // Exactly one run per (solver, warm start, seed) of the comparison, in its job order.
    let seed_order = |seed: u64| config.seeds.iter().position(|&k| k == seed);
    let merge_error = PythonBindingError::Merge;
    let mut keyed = Vec::with_capacity(runs.len());
    for run in runs {
        let Some(k) = seed_order(run.seed) else {
            return Err(merge_error(format!(
                "seed {} is not in the comparison",
                run.seed
            )));
        };
        keyed.push(((run.solver, run.warm_start, k), run));
    }
    keyed.sort_by_key(|(key, _)| *key);
    let expected = solvers.len() * labels.len() * config.seeds.len();
    for (i, w) in keyed.windows(2).enumerate() {
        if w[0].0 == w[1].0 {
            return Err(merge_error(format!(
                "the run of ({}, {}, seed {}) came twice (run {i})",
                solvers[w[0].1.solver], labels[w[0].1.warm_start], w[0].1.seed
            )));
        }
    }
    if keyed.len() != expected {
        return Err(merge_error(format!(
            "{} runs of the {expected} (solvers x warm starts x seeds) came back",
            keyed.len()
        )));
    }
    let results = Results {
        config,
        solvers,
        warm_starts: labels,
        runs: keyed.into_iter().map(|(_, run)| run).collect(),
        threads,
        // Which of the cluster's workers ran a task is Ray's to know, not the parts'.
        workers_used: 0,
        wall_seconds,
    };
    compare::finish(py, &results, args)
}
