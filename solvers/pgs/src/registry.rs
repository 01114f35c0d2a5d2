//! Registration of the PGS velocity solver.

use deepcontact_core::registry::Registry;

use crate::{MAX_DOMAINS, Ordering, OverRelaxation, PgsSettings, PgsSolver, Precision};

/// The most threads `pgs:threads=` accepts.
pub const MAX_THREADS: u64 = 64;

/// Registers `pgs` (parameters `block=true|false`, `order=coloured|sequential`,
/// `lanes=true|false`, `start=projected|raw`, `threads=1..64`, `parallel_from=POINTS`, `domains=0..63`,
/// `chunk=BATCHES`, `precision=f64|f32`, `sor=F1/F2/..`;
/// defaults: [`PgsSettings::default`]).
pub fn register(registry: &mut Registry) {
    registry.register_solver(
        "pgs",
        "sequential-impulse projected Gauss-Seidel (Box2D v2.4); block=true|false, \
         order=coloured|sequential, lanes=true|false, start=projected|raw, threads=N (default 1; \
         bit-identical for any N), parallel_from=POINTS (islands from this size are swept in \
         fixed chunks that threads share; default 2048), domains=N (such islands cut into N \
         bands of their contact graph, the even ones swept side by side on threads, then the \
         odd ones; 0: colours shared in chunks instead; default 16, the most), domain_points=N \
         (a band holds at least N contacts, at least 4 bands; 0: always domains; default 1100), \
         chunk=N (batches of 4 contacts per chunk of that colour plan, the unit a thread takes; \
         default 16), \
         precision=f64|f32 (f32: the iterations in single precision, 8 contacts per AVX2 \
         register, on the calling thread; default f64), sor=F1/F2/.. (over-relaxation factors in [1, 2) for \
         equal shares of a solve's first max_iterations - 1 sweeps, on single-point manifolds; the last sweep \
         plain; for fixed budgets; default none)",
        |p| {
            let d = PgsSettings::default();
            let block_solver = p.bool("block", d.block_solver)?;
            let lanes = p.bool("lanes", d.lanes)?;
            let threads = p.u64("threads", d.threads as u64)?;
            if !(1..=MAX_THREADS).contains(&threads) {
                return Err(p.invalid(
                    "threads",
                    &threads.to_string(),
                    format!("must be 1 to {MAX_THREADS}"),
                ));
            }
            let parallel_min_points =
                usize::try_from(p.u64("parallel_from", d.parallel_min_points as u64)?)
                    .unwrap_or(usize::MAX);
            let domains = p.u64("domains", d.domains as u64)?;
            if domains > MAX_DOMAINS as u64 {
                return Err(p.invalid(
                    "domains",
                    &domains.to_string(),
                    format!("must be 0 to {MAX_DOMAINS}"),
                ));
            }
            let domain_points = p.u64("domain_points", d.domain_points as u64)?;
            let chunk = p.u64("chunk", d.chunk as u64)?;
            if chunk == 0 {
                return Err(p.invalid("chunk", "0", "must be >= 1"));
            }
            let raw_start = match p.choice("start", &["projected", "raw"])? {
                None => d.raw_start,
                Some(v) => v == "raw",
            };
            let precision = match p.choice("precision", &["f64", "f32"])? {
                Some("f32") => Precision::F32,
                _ => d.precision,
            };
            let ordering = match p.choice("order", &["coloured", "colored", "sequential"])? {
                None => d.ordering,
                Some("sequential") => Ordering::Sequential,
                Some(_) => Ordering::Coloured,
            };
            let over_relaxation = match p.string("sor") {
                None => d.over_relaxation,
                Some(text) => OverRelaxation::parse(text)
                    .map_err(|e| p.invalid("sor", text, e.to_string()))?,
            };
            Ok(Box::new(PgsSolver::with_settings(PgsSettings {
                over_relaxation,
                block_solver,
                ordering,
                lanes,
                raw_start,
                threads: threads as usize,
                parallel_min_points,
                domains: domains as usize,
                domain_points: usize::try_from(domain_points).unwrap_or(usize::MAX),
                chunk: usize::try_from(chunk).unwrap_or(usize::MAX),
                precision,
                ..d
            })) as Box<dyn deepcontact_core::VelocitySolver>)
        },
    );
}
