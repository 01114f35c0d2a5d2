//! [`WarmStartHooks`]: rapier2d `PhysicsHooks` that let any deepcontact [`WarmStart`] provider
//! set rapier's contact warm starts.
//!
//! **Grouping** ([`Grouping`]). rapier calls `modify_solver_contacts` once per contact
//! manifold (collider pair and sub-shape pair) from inside its narrow phase, before islands
//! exist, and the start must be written during that call. By default the adapter builds one
//! deepcontact [`ContactProblem`] per manifold: the two bodies (mass, inertia, velocities with
//! this step's gravity added, as deepcontact's problems have them) and the manifold's points
//! (at most 2 in 2D). Providers that read only the carried impulses (`none`, `builtin`,
//! `extrapolate`, ...) behave exactly as in deepcontact; providers that sweep the problem
//! (`sor`, `learned-sor`, the `graph` model) then see one pair at a time, without the weight
//! of the bodies resting on it. [`Grouping::Island`] plans island-sized problems before the
//! step instead ([`WarmStartHooks::plan_islands`], [`crate::island`]) and writes their starts
//! from the hook.
//!
//! **Carried impulses.** rapier carries each point's impulse itself: parry2d's manifold
//! generators copy a point's data to the new point with the same feature ids, and the
//! one-point generators (ball against ball or polygon) update the point in place, keeping its
//! data when a feature id changes. The adapter hands the provider exactly what rapier carried
//! (`SolverContact::warmstart_impulse`, in per-step units), so `builtin` reproduces native
//! rapier bit for bit; a map of last step's impulses by [`PointKey`] alone lost the in-place
//! carries (measured: a ball–polygon pair of a 30-body pile diverged at step 38). The key
//! still names each point: it is the problem's [`ContactId`].
//!
//! **Threads.** rapier may call the hook from several threads (its `parallel` feature); the
//! provider sits behind a [`Mutex`], so calls are serialised, and their order may vary from
//! run to run under `parallel`: [`WarmStartHooks::finish_step`] calls `observe` in a fixed
//! (pair, sub-shape) order, but a provider whose output depends on the call order (a seeded
//! `random`) is then not reproducible. By manifold, `ctx.island` is the manifold's index in
//! call order and `ctx.island_count` the manifolds seen so far (the total is unknown during
//! the step); by island they are the planned island's index and count.
//!
//! **Units and signs:** see [`crate::units`].

use std::collections::HashMap;
use std::sync::{Mutex, MutexGuard};
use std::time::Instant;

use deepcontact_core::warm_start::check_output;
use deepcontact_core::{
    ContactId, ContactProblem, Impulse, Observation, PointDesc, ProblemBody, Real, SolveReport,
    Vector, WarmStart, WarmStartContext,
};
use rapier2d::prelude::*;

use crate::error::AdapterError;
use crate::units::{solved_per_step, substeps, to_step, to_substep};

/// What the adapter does when the provider fails or writes an unusable start for a manifold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnFailure {
    /// Keep rapier's own carried warm start for that manifold (native behaviour) and count it
    /// in [`StepStats::fallbacks`] (default).
    #[default]
    Carried,
    /// Start that manifold from zeros and count it.
    Zero,
    /// Keep rapier's own warm start, count it, and have [`WarmStartHooks::finish_step`]
    /// return the first error.
    Error,
}

/// How the adapter groups rapier's contacts into deepcontact problems.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Grouping {
    /// One problem per rapier manifold, built inside the hook from what rapier hands it
    /// (default: exact, the simplest; sweeping providers see one pair at a time).
    #[default]
    Manifold,
    /// One problem per island, planned before the step by [`WarmStartHooks::plan_islands`]
    /// from last step's manifolds moved to this step's poses ([`crate::island`]); manifolds
    /// the plan does not cover (new pairs, renamed points) take the per-manifold path.
    Island,
}

/// Settings of [`WarmStartHooks`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct HookSettings {
    /// What a failing provider gets (default [`OnFailure::Carried`]).
    pub on_failure: OnFailure,
    /// [`WarmStartContext::pass_budget`] given to the provider per manifold (default `None`:
    /// the provider sweeps as its own settings say).
    pub pass_budget: Option<u32>,
    /// How contacts are grouped into problems (default [`Grouping::Manifold`]).
    pub grouping: Grouping,
}

/// What the hooks did during one step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepStats {
    /// Manifolds warm-started by the provider (or its fallback).
    pub manifolds: usize,
    /// Contact points warm-started.
    pub points: usize,
    /// Of [`Self::manifolds`], those written from the island plan ([`Grouping::Island`]);
    /// the others took the per-manifold path.
    pub planned: usize,
    /// Manifolds whose provider output was rejected (guard or problem error) and replaced.
    pub fallbacks: usize,
    /// Wall time of the provider's `warm_start` and `observe` calls and of building its
    /// problems (s).
    pub provider_seconds: Real,
    /// Passes the provider reported ([`WarmStart::passes_spent`]), summed over manifolds.
    pub provider_passes: u64,
}

/// Identity of a rapier contact point across steps: the collider pair (handles as raw
/// `(index, generation)`), the sub-shapes and the feature ids parry2d tracks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PointKey {
    /// Collider 1 of the pair, `(index, generation)`.
    pub collider1: (u32, u32),
    /// Collider 2 of the pair, `(index, generation)`.
    pub collider2: (u32, u32),
    /// Sub-shape of collider 1 (0 for a convex shape).
    pub subshape1: u32,
    /// Sub-shape of collider 2.
    pub subshape2: u32,
    /// Packed feature id on collider 1.
    pub fid1: u32,
    /// Packed feature id on collider 2.
    pub fid2: u32,
}

impl PointKey {
    /// The deepcontact [`ContactId`] of the point: the colliders' indices as the body pair,
    /// each feature packed as `subshape << 32 | fid` (the core's layout for composite shapes).
    pub fn contact_id(&self) -> ContactId {
        ContactId {
            body_a: self.collider1.0,
            body_b: self.collider2.0,
            feature_a: (u64::from(self.subshape1) << 32) | u64::from(self.fid1),
            feature_b: (u64::from(self.subshape2) << 32) | u64::from(self.fid2),
        }
    }
}

/// This step's settings, from [`WarmStartHooks::begin_step`].
#[derive(Debug, Clone, Copy)]
struct Frame {
    dt: Real,
    gravity: Vector,
    substeps: u32,
    coefficient: Real,
    passes: u32,
}

/// One manifold warm-started this step, kept for `observe`.
#[derive(Debug)]
struct Pending {
    collider1: ColliderHandle,
    collider2: ColliderHandle,
    subshape1: u32,
    subshape2: u32,
    island: usize,
    /// Manifold point index of each problem point.
    contacts: Vec<u32>,
    problem: ContactProblem,
    carried: Vec<Option<Impulse>>,
    /// Per point, the per-substep `(normal, tangent)` written into the solver contact.
    written: Vec<(f32, f32)>,
    fell_back: bool,
}

impl Pending {
    /// An empty entry, to be filled by a hook call.
    fn empty() -> Self {
        Self {
            collider1: ColliderHandle::invalid(),
            collider2: ColliderHandle::invalid(),
            subshape1: 0,
            subshape2: 0,
            island: 0,
            contacts: Vec::new(),
            problem: ContactProblem::new(),
            carried: Vec::new(),
            written: Vec::new(),
            fell_back: false,
        }
    }
}

struct State {
    provider: Box<dyn WarmStart>,
    settings: HookSettings,
    frame: Option<Frame>,
    step: u64,
    pending: Vec<Pending>,
    stats: StepStats,
    error: Option<AdapterError>,
    unbegun: usize,
    /// Under [`Grouping::Island`]: per planned point, the per-substep start to write (`None`:
    /// keep rapier's own after a fallback).
    planned: HashMap<PointKey, Option<(f32, f32)>>,
    /// Per planned point the hook saw, what the solver contact held after the hook.
    written: HashMap<PointKey, (f32, f32)>,
    /// Entries of earlier steps, emptied and reused: a hook call then allocates nothing once
    /// the step's manifold count has been seen (allocation was most of the hooks' cost).
    spare: Vec<Pending>,
    /// The provider's output buffer, reused.
    out: Vec<Impulse>,
    /// The planned islands, kept for `observe`.
    islands: Vec<(crate::island::IslandProblem, bool)>,
}

/// rapier2d `PhysicsHooks` driving rapier's contact warm starts from a deepcontact provider.
///
/// Give every collider `ActiveHooks::MODIFY_SOLVER_CONTACTS`, call [`Self::begin_step`]
/// before and [`Self::finish_step`] after each `PhysicsPipeline::step` that receives the
/// hooks (or use [`crate::RapierWorld::step`], which does both).
pub struct WarmStartHooks {
    state: Mutex<State>,
}

impl std::fmt::Debug for WarmStartHooks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = self
            .state
            .lock()
            .map(|s| s.provider.name().to_string())
            .unwrap_or_else(|_| "<poisoned>".into());
        f.debug_struct("WarmStartHooks")
            .field("provider", &name)
            .finish()
    }
}

impl WarmStartHooks {
    /// Hooks around `provider` with the default [`HookSettings`].
    pub fn new(provider: Box<dyn WarmStart>) -> Self {
        Self::with_settings(provider, HookSettings::default())
    }

    /// Hooks around `provider` with `settings`.
    pub fn with_settings(provider: Box<dyn WarmStart>, settings: HookSettings) -> Self {
        Self {
            state: Mutex::new(State {
                provider,
                settings,
                frame: None,
                step: 0,
                pending: Vec::new(),
                stats: StepStats::default(),
                error: None,
                unbegun: 0,
                planned: HashMap::new(),
                written: HashMap::new(),
                islands: Vec::new(),
                spare: Vec::new(),
                out: Vec::new(),
            }),
        }
    }

    fn lock(&self) -> Result<MutexGuard<'_, State>, AdapterError> {
        self.state.lock().map_err(|_| AdapterError::Poisoned)
    }

    /// The provider's name.
    pub fn provider_name(&self) -> String {
        self.lock()
            .map(|s| s.provider.name().to_string())
            .unwrap_or_else(|_| "<poisoned>".into())
    }

    /// The provider's [`WarmStart::diagnostics`].
    pub fn diagnostics(&self) -> Vec<(String, Real)> {
        self.lock()
            .map(|s| s.provider.diagnostics())
            .unwrap_or_default()
    }

    /// Prepares a step: `dt` (s), substeps and `warmstart_coefficient` from `params`, the
    /// world's `gravity` (m/s²). Before the first step (or after [`Self::reset`]) it calls the
    /// provider's [`WarmStart::reset`].
    pub fn begin_step(
        &self,
        params: &IntegrationParameters,
        gravity: Vector,
    ) -> Result<(), AdapterError> {
        let mut state = self.lock()?;
        if state.step == 0 {
            state.provider.reset();
        }
        let passes = substeps(params.num_solver_iterations)
            * params.num_internal_pgs_iterations.max(1) as u32;
        state.frame = Some(Frame {
            dt: Real::from(params.dt),
            gravity,
            substeps: substeps(params.num_solver_iterations),
            coefficient: Real::from(params.warmstart_coefficient),
            passes,
        });
        state.pending.clear();
        state.stats = StepStats::default();
        state.error = None;
        state.unbegun = 0;
        state.planned.clear();
        state.written.clear();
        state.islands.clear();
        Ok(())
    }

    /// Under [`Grouping::Island`], between [`Self::begin_step`] and the pipeline step: builds
    /// the island problems of the coming step from `narrow_phase` (last step's manifolds) at the
    /// poses of `bodies` and `colliders`, and asks the provider for each island's start (see
    /// [`crate::island`]). A failing island follows [`HookSettings::on_failure`] and counts as
    /// one fallback. Does nothing under [`Grouping::Manifold`].
    pub fn plan_islands(
        &self,
        bodies: &RigidBodySet,
        colliders: &ColliderSet,
        narrow_phase: &NarrowPhase,
        params: &IntegrationParameters,
    ) -> Result<(), AdapterError> {
        let mut guard = self.lock()?;
        let state = &mut *guard;
        if state.settings.grouping != Grouping::Island {
            return Ok(());
        }
        let Some(frame) = state.frame else {
            return Err(AdapterError::NotBegun { manifolds: 0 });
        };
        let start = Instant::now();
        let islands = crate::island::plan(
            bodies,
            colliders,
            narrow_phase,
            Real::from(params.prediction_distance()),
            frame.dt,
            &|h, c| body(bodies, colliders, h, c, &frame),
            &|n, t| to_step(n, t, frame.substeps),
        );
        let count = islands.len();
        for (i, island) in islands.into_iter().enumerate() {
            let n = island.problem.len();
            let mut ctx = context(&frame, state, &island.problem, &island.carried, i);
            ctx.island_count = count;
            let mut out = vec![Impulse::ZERO; n];
            let result = state
                .provider
                .warm_start(&ctx, &mut out)
                .and_then(|()| check_output(&out, n));
            state.stats.provider_passes += u64::from(state.provider.passes_spent());
            let fell_back = result.is_err();
            if let Err(source) = result {
                if state.settings.on_failure == OnFailure::Error && state.error.is_none() {
                    state.error = Some(AdapterError::Provider {
                        provider: state.provider.name().to_string(),
                        step: state.step,
                        collider1: island.keys.first().map_or(0, |k| k.collider1.0),
                        collider2: island.keys.first().map_or(0, |k| k.collider2.0),
                        source,
                    });
                }
                state.stats.fallbacks += 1;
            }
            for (k, key) in island.keys.iter().enumerate() {
                let value = match (fell_back, state.settings.on_failure) {
                    (false, _) => Some(to_substep(out[k], frame.substeps)),
                    (true, OnFailure::Zero) => Some((0.0, 0.0)),
                    (true, _) => None,
                };
                state.planned.insert(*key, value);
            }
            state.islands.push((island, fell_back));
        }
        state.stats.provider_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// Writes the planned starts of a manifold whose points were all planned; false (nothing
    /// written) if one was not.
    fn write_planned(state: &mut State, c: &mut ContactModificationContext<'_>) -> bool {
        let (c1, c2) = (c.collider1.into_raw_parts(), c.collider2.into_raw_parts());
        let (s1, s2) = (c.manifold.subshape1, c.manifold.subshape2);
        let key = |index: u32| {
            c.manifold.points.get(index as usize).map(|p| PointKey {
                collider1: c1,
                collider2: c2,
                subshape1: s1,
                subshape2: s2,
                fid1: p.fid1.0,
                fid2: p.fid2.0,
            })
        };
        let keys: Option<Vec<PointKey>> = c
            .solver_contacts
            .iter()
            .map(|sc| key(sc.contact_id[0]))
            .collect();
        let Some(keys) = keys else { return false };
        if !keys.iter().all(|k| state.planned.contains_key(k)) {
            return false;
        }
        for (sc, k) in c.solver_contacts.iter_mut().zip(&keys) {
            if let Some(Some((n, t))) = state.planned.get(k) {
                sc.warmstart_impulse = *n;
                sc.warmstart_tangent_impulse.x = *t;
            }
            state
                .written
                .insert(*k, (sc.warmstart_impulse, sc.warmstart_tangent_impulse.x));
        }
        state.stats.manifolds += 1;
        state.stats.planned += 1;
        state.stats.points += keys.len();
        true
    }

    /// Forgets the carried impulses and restarts the step count: a new world begins.
    pub fn reset(&self) -> Result<(), AdapterError> {
        let mut state = self.lock()?;
        state.step = 0;
        state.frame = None;
        Ok(())
    }

    /// Ends a step: reads the solved impulses of every manifold the provider warm-started from
    /// `narrow_phase`, in deepcontact's per-step units ([`crate::units`]), hands them to
    /// [`WarmStart::observe`] in (pair, sub-shape) order, and keeps rapier's carried impulses
    /// by [`PointKey`] for the next step. Returns the step's counts, or the first error under
    /// [`OnFailure::Error`] (or a structural one, whatever the policy).
    pub fn finish_step(&self, narrow_phase: &NarrowPhase) -> Result<StepStats, AdapterError> {
        let mut guard = self.lock()?;
        let state = &mut *guard;
        let frame = state.frame.take();
        let mut pending = std::mem::take(&mut state.pending);
        pending.sort_by_key(|p| {
            (
                p.collider1.into_raw_parts(),
                p.collider2.into_raw_parts(),
                p.subshape1,
                p.subshape2,
            )
        });
        let mut missing = None;
        if let Some(frame) = frame {
            let start = Instant::now();
            let report = SolveReport {
                iterations: frame.passes,
                ..SolveReport::default()
            };
            missing = observe_manifolds(state, &frame, &pending, narrow_phase, &report);
            observe_islands(state, &frame, narrow_phase, &report);
            state.stats.provider_seconds += start.elapsed().as_secs_f64();
        }
        state.spare.append(&mut pending);
        state.planned.clear();
        state.written.clear();
        state.step += 1;
        let stats = std::mem::take(&mut state.stats);
        if state.unbegun > 0 {
            return Err(AdapterError::NotBegun {
                manifolds: state.unbegun,
            });
        }
        if let Some(e) = missing {
            return Err(e);
        }
        match state.error.take() {
            Some(e) => Err(e),
            None => Ok(stats),
        }
    }

    /// The warm start of one manifold: see the [module docs](self).
    fn warm_start_manifold(
        &self,
        state: &mut State,
        frame: Frame,
        c: &mut ContactModificationContext<'_>,
    ) {
        let start = Instant::now();
        let (c1, c2) = (c.collider1, c.collider2);
        let island = state.pending.len();
        let mut slot = state.spare.pop().unwrap_or_else(Pending::empty);
        let built = fill_problem(&mut slot, c, &frame);
        let mut out = std::mem::take(&mut state.out);
        let outcome = provide(state, &frame, &slot, built, c, island, &mut out);
        let fell_back = write_starts(state, c, &out, outcome, &mut slot.written, frame.substeps);
        state.out = out;
        state.stats.manifolds += 1;
        state.stats.points += slot.written.len();
        state.stats.fallbacks += usize::from(fell_back);
        if fell_back && slot.contacts.len() != slot.written.len() {
            // The problem could not be built: nothing to observe for this manifold.
            state.spare.push(slot);
            state.stats.provider_seconds += start.elapsed().as_secs_f64();
            return;
        }
        slot.collider1 = c1;
        slot.collider2 = c2;
        slot.subshape1 = c.manifold.subshape1;
        slot.subshape2 = c.manifold.subshape2;
        slot.island = island;
        slot.fell_back = fell_back;
        state.pending.push(slot);
        state.stats.provider_seconds += start.elapsed().as_secs_f64();
    }
}

/// One manifold's problem into `slot` (its buffers cleared first): its two bodies, a point
/// for each of rapier's solver contacts (keyed by [`PointKey`]; deepcontact manifolds hold at
/// most two points, as rapier's 2D ones do), and rapier's carried value of each point, `None`
/// for a point new to it.
fn fill_problem(
    slot: &mut Pending,
    c: &ContactModificationContext<'_>,
    frame: &Frame,
) -> Result<(), deepcontact_core::CoreError> {
    let Pending {
        problem,
        contacts,
        carried,
        written,
        ..
    } = slot;
    problem.clear();
    contacts.clear();
    carried.clear();
    written.clear();
    let (c1, c2) = (c.collider1, c.collider2);
    let a = problem.add_body(body(c.bodies, c.colliders, c.rigid_body1, c1, frame));
    let b = problem.add_body(body(c.bodies, c.colliders, c.rigid_body2, c2, frame));
    let normal = Vector::new(Real::from(c.normal.x), Real::from(c.normal.y));
    for (i, sc) in c.solver_contacts.iter().enumerate() {
        let index = sc.contact_id[0];
        let Some(tracked) = c.manifold.points.get(index as usize) else {
            continue;
        };
        let key = PointKey {
            collider1: c1.into_raw_parts(),
            collider2: c2.into_raw_parts(),
            subshape1: c.manifold.subshape1,
            subshape2: c.manifold.subshape2,
            fid1: tracked.fid1.0,
            fid2: tracked.fid2.0,
        };
        if i % 2 == 0 {
            problem.begin_manifold();
        }
        let desc = PointDesc::new(
            a,
            b,
            Vector::new(Real::from(sc.point.x), Real::from(sc.point.y)),
            normal,
        )
        .id(key.contact_id())
        .separation(Real::from(sc.dist))
        .friction(Real::from(sc.friction))
        .restitution(Real::from(sc.restitution), 1.0);
        problem.add_point(&desc)?;
        contacts.push(index);
        // rapier's own carried value: a point that carried nothing is new to deepcontact.
        let (wn, wt) = (sc.warmstart_impulse, sc.warmstart_tangent_impulse.x);
        let new = sc.is_new != 0.0 && wn == 0.0 && wt == 0.0;
        carried.push((!new).then(|| to_step(wn, wt, frame.substeps)));
    }
    Ok(())
}

/// The provider's start of the manifold in `slot` into `out` (checked: finite, one per
/// point), or why there is none: the problem could not be built (`built`), it lacks some of
/// rapier's solver contacts, or the provider failed.
fn provide(
    state: &mut State,
    frame: &Frame,
    slot: &Pending,
    built: Result<(), deepcontact_core::CoreError>,
    c: &ContactModificationContext<'_>,
    island: usize,
    out: &mut Vec<Impulse>,
) -> Result<(), AdapterError> {
    let (c1, c2) = (
        c.collider1.into_raw_parts().0,
        c.collider2.into_raw_parts().0,
    );
    let n = slot.problem.len();
    let problem = |source| AdapterError::Problem {
        collider1: c1,
        collider2: c2,
        source,
    };
    built.map_err(problem)?;
    if n != c.solver_contacts.len() {
        return Err(problem(deepcontact_core::CoreError::InvalidProblem(
            format!(
                "{} solver contacts, {n} manifold points found",
                c.solver_contacts.len()
            ),
        )));
    }
    let mut ctx = context(frame, state, &slot.problem, &slot.carried, island);
    ctx.island_count = island + 1;
    out.clear();
    out.resize(n, Impulse::ZERO);
    let result = state
        .provider
        .warm_start(&ctx, out)
        .and_then(|()| check_output(out, n));
    state.stats.provider_passes += u64::from(state.provider.passes_spent());
    result.map_err(|source| AdapterError::Provider {
        provider: state.provider.name().to_string(),
        step: state.step,
        collider1: c1,
        collider2: c2,
        source,
    })
}

/// The starts rapier's solver contacts of `c` get, in rapier's substep units, into `written`
/// and into the contacts: the provider's `out`, or after a failure (`outcome`, recorded under
/// [`OnFailure::Error`]) rapier's own carried values or zeros. Returns whether it fell back.
fn write_starts(
    state: &mut State,
    c: &mut ContactModificationContext<'_>,
    out: &[Impulse],
    outcome: Result<(), AdapterError>,
    written: &mut Vec<(f32, f32)>,
    substeps: u32,
) -> bool {
    let fell_back = match outcome {
        Ok(()) => {
            written.extend(out.iter().map(|&s| to_substep(s, substeps)));
            false
        }
        Err(e) => {
            let policy = state.settings.on_failure;
            if policy == OnFailure::Error && state.error.is_none() {
                state.error = Some(e);
            }
            // rapier's own carried values, or zeros.
            written.extend(c.solver_contacts.iter().map(|sc| {
                if policy == OnFailure::Zero {
                    (0.0, 0.0)
                } else {
                    (sc.warmstart_impulse, sc.warmstart_tangent_impulse.x)
                }
            }));
            true
        }
    };
    for (sc, &(wn, wt)) in c.solver_contacts.iter_mut().zip(written.iter()) {
        sc.warmstart_impulse = wn;
        sc.warmstart_tangent_impulse.x = wt;
    }
    fell_back
}

/// The step's manifolds shown to the provider (`pending`, in pair and sub-shape order): the
/// starts written and rapier's solved impulses, per deepcontact step. Returns the first
/// manifold that is no longer in `narrow_phase`.
fn observe_manifolds(
    state: &mut State,
    frame: &Frame,
    pending: &[Pending],
    narrow_phase: &NarrowPhase,
    report: &SolveReport,
) -> Option<AdapterError> {
    let mut missing = None;
    for p in pending {
        let manifold = narrow_phase
            .contact_pair(p.collider1, p.collider2)
            .and_then(|pair| {
                pair.manifolds
                    .iter()
                    .find(|m| m.subshape1 == p.subshape1 && m.subshape2 == p.subshape2)
            });
        let Some(manifold) = manifold else {
            missing.get_or_insert(AdapterError::MissingManifold {
                collider1: p.collider1.into_raw_parts().0,
                collider2: p.collider2.into_raw_parts().0,
                subshape1: p.subshape1,
                subshape2: p.subshape2,
            });
            continue;
        };
        let solved: Vec<Impulse> = p
            .contacts
            .iter()
            .zip(&p.written)
            .map(|(&c, &w)| {
                let data = manifold.points.get(c as usize).map(|pt| pt.data);
                data.map_or(Impulse::ZERO, |d| {
                    solved_per_step((d.impulse, d.tangent_impulse.x), w)
                })
            })
            .collect();
        let used: Vec<Impulse> = p.written.iter().map(|&w| used_start(w, frame)).collect();
        let ctx = context(frame, state, &p.problem, &p.carried, p.island);
        let seen = Observation::new(&used, &solved, p.fell_back, report);
        state.provider.observe(&ctx, &seen);
    }
    missing
}

/// The step's planned islands shown to the provider: each point's start as written and
/// rapier's solved impulse, found by its [`PointKey`] (zeros for a point that was no solver
/// contact this step after all).
fn observe_islands(
    state: &mut State,
    frame: &Frame,
    narrow_phase: &NarrowPhase,
    report: &SolveReport,
) {
    let islands = std::mem::take(&mut state.islands);
    let count = islands.len();
    for (i, (island, fell_back)) in islands.iter().enumerate() {
        let mut used = Vec::with_capacity(island.keys.len());
        let mut solved = Vec::with_capacity(island.keys.len());
        for key in &island.keys {
            let Some(&w) = state.written.get(key) else {
                used.push(Impulse::ZERO);
                solved.push(Impulse::ZERO);
                continue;
            };
            used.push(used_start(w, frame));
            solved.push(solved_point(narrow_phase, key).map_or(Impulse::ZERO, |d| {
                solved_per_step((d.impulse, d.tangent_impulse.x), w)
            }));
        }
        let mut ctx = context(frame, state, &island.problem, &island.carried, i);
        ctx.island_count = count;
        let seen = Observation::new(&used, &solved, *fell_back, report);
        state.provider.observe(&ctx, &seen);
    }
}

/// The start rapier applied from a written substep value `w`, per deepcontact step: scaled by
/// its warm-start coefficient.
fn used_start(w: (f32, f32), frame: &Frame) -> Impulse {
    let s = to_step(w.0, w.1, frame.substeps);
    Impulse::new(s.normal * frame.coefficient, s.tangent * frame.coefficient)
}

/// Rapier's solver data of the point `key` names, if its pair, manifold and point are still
/// in `narrow_phase`.
fn solved_point(narrow_phase: &NarrowPhase, key: &PointKey) -> Option<ContactData> {
    narrow_phase
        .contact_pair(
            ColliderHandle::from_raw_parts(key.collider1.0, key.collider1.1),
            ColliderHandle::from_raw_parts(key.collider2.0, key.collider2.1),
        )
        .and_then(|pair| {
            pair.manifolds
                .iter()
                .find(|m| m.subshape1 == key.subshape1 && m.subshape2 == key.subshape2)
        })
        .and_then(|m| {
            m.points
                .iter()
                .find(|p| p.fid1.0 == key.fid1 && p.fid2.0 == key.fid2)
        })
        .map(|p| p.data)
}

/// The provider's context for one manifold's problem.
fn context<'a>(
    frame: &Frame,
    state: &State,
    problem: &'a ContactProblem,
    carried: &'a [Option<Impulse>],
    island: usize,
) -> WarmStartContext<'a> {
    let mut ctx =
        WarmStartContext::new(problem, carried, state.step, frame.dt).with_gravity(frame.gravity);
    if let Some(budget) = state.settings.pass_budget {
        ctx = ctx.with_pass_budget(budget);
    }
    ctx.island = island;
    ctx.island_count = island + 1;
    ctx
}

/// A manifold's body as the solver sees it: dynamic bodies with their effective inverse mass
/// and world inverse inertia and this step's gravity already in the velocity (deepcontact's
/// problems are built after gravity; rapier adds it inside the solver, a substep at a time);
/// kinematic ones immovable with their velocity; static bodies and body-less colliders
/// immovable at rest.
fn body(
    bodies: &RigidBodySet,
    colliders: &ColliderSet,
    handle: Option<RigidBodyHandle>,
    collider: ColliderHandle,
    frame: &Frame,
) -> ProblemBody {
    let v = |v: rapier2d::math::Vector| Vector::new(Real::from(v.x), Real::from(v.y));
    let Some(rb) = handle.and_then(|h| bodies.get(h)) else {
        let at = colliders
            .get(collider)
            .map_or(Vector::zeros(), |co| v(co.translation()));
        return ProblemBody::fixed(at);
    };
    let mut out = ProblemBody::fixed(v(rb.center_of_mass()));
    out.angle = Real::from(rb.rotation().angle());
    if rb.is_dynamic() {
        let props = rb.mass_properties();
        out.linear_velocity =
            v(rb.linvel()) + frame.gravity * (Real::from(rb.gravity_scale()) * frame.dt);
        out.angular_velocity = Real::from(rb.angvel());
        out.inv_mass = Real::from(props.effective_inv_mass.x);
        out.inv_inertia = Real::from(props.effective_world_inv_inertia);
    } else if rb.is_kinematic() {
        out.linear_velocity = v(rb.linvel());
        out.angular_velocity = Real::from(rb.angvel());
    }
    out
}

impl PhysicsHooks for WarmStartHooks {
    fn modify_solver_contacts(&self, context: &mut ContactModificationContext<'_>) {
        if context.solver_contacts.is_empty() {
            return;
        }
        // A poisoned lock (the provider panicked earlier) keeps rapier's own warm starts;
        // `finish_step` reports it.
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        let Some(frame) = state.frame else {
            state.unbegun += 1;
            return;
        };
        if state.settings.grouping == Grouping::Island && Self::write_planned(&mut state, context) {
            return;
        }
        self.warm_start_manifold(&mut state, frame, context);
    }
}
