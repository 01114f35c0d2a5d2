//! Conversions between rapier2d's per-substep impulses and deepcontact's per-step ones.
//!
//! **Units.** deepcontact providers read and write the impulse of a whole step of `dt` (N·s):
//! a box of mass `m` resting on the ground carries `m g dt`. rapier2d 0.34 splits a step into
//! `N = IntegrationParameters::num_solver_iterations` substeps of `dt / N` (plus the island's
//! `additional_solver_iterations`, 0 unless a user sets them) and warm-starts every substep
//! from the previous substep's impulse, so the warm start it carries from one step to the
//! next (`ContactData::warmstart_impulse`) is the *last substep's* impulse, `m g dt / N` for
//! the resting box. Hence:
//!
//! * carried, deepcontact units = `N ×` rapier's `warmstart_impulse` ([`to_step`]);
//! * a provider's start `s` is written as `s / N` into `SolverContact::warmstart_impulse`
//!   ([`to_substep`]); rapier then scales it by `warmstart_coefficient` (default 1) and
//!   starts the *first* substep from it; the later substeps start from their predecessor, as
//!   in native rapier, whatever the provider wrote;
//! * the solved impulse of the step is the sum of the substeps' impulses. rapier's
//!   `ContactData::impulse` after the step is `w + Σ_s λ_s`: its accumulator adds the
//!   constraint's impulse at the start of every substep, the written warm start `w` included
//!   (`ContactWithCoulombFriction::update`: `impulse_accumulator += impulse` before
//!   `impulse *= warmstart_coefficient`), so [`solved_per_step`] subtracts `w` once.
//!
//! Multiplying and dividing an `f32` by an integer `N` in `f64` is exact both ways (24 + 4
//! mantissa bits fit in 53), so a provider that returns the carried values writes back
//! rapier's own bits: the adapter then reproduces native rapier2d bit for bit.
//!
//! **Signs.** rapier's normal `n` (`ContactManifoldData::normal`) points from collider 1 to
//! collider 2; its normal impulse pushes body 1 along `−n` and body 2 along `+n`: deepcontact's
//! convention with A = collider 1's body, B = collider 2's. Its 2D tangent is the
//! `orthonormal_basis` of `−n`, `(n.y, −n.x)`, and a positive tangent impulse pushes body 1
//! along it and body 2 against it, that is body 2 along `(−n.y, n.x)`: deepcontact's tangent.
//! Both components therefore keep their sign; only the scale changes.

use deepcontact_core::{Impulse, Real};

/// The substeps of a step: `num_solver_iterations` at least 1 (rapier treats 0 as 1 too: it
/// divides `dt` by the count and its loop would not run).
pub fn substeps(num_solver_iterations: usize) -> u32 {
    num_solver_iterations.max(1) as u32
}

/// rapier's carried warm start (last substep's impulse, N·s per substep) in deepcontact's
/// per-step units: `N ×` both components.
pub fn to_step(normal: f32, tangent: f32, substeps: u32) -> Impulse {
    let n = Real::from(substeps);
    Impulse::new(Real::from(normal) * n, Real::from(tangent) * n)
}

/// A per-step impulse (deepcontact units) as the per-substep `(normal, tangent)` rapier
/// warm-starts its first substep from: both components divided by `N`.
pub fn to_substep(impulse: Impulse, substeps: u32) -> (f32, f32) {
    let n = Real::from(substeps);
    ((impulse.normal / n) as f32, (impulse.tangent / n) as f32)
}

/// The impulse the whole step applied (N·s per step): rapier's accumulated `impulse` after the
/// step minus the warm start `written` before it (both per component, in rapier's `f32`).
pub fn solved_per_step(accumulated: (f32, f32), written: (f32, f32)) -> Impulse {
    Impulse::new(
        Real::from(accumulated.0) - Real::from(written.0),
        Real::from(accumulated.1) - Real::from(written.1),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_and_substep_units_round_trip_bit_for_bit() {
        for n in [1, 2, 3, 4, 7, 8, 16] {
            for w in [0.0f32, 1.0e-7, 0.0245, 3.3333333, -0.77, 1.0e6] {
                let step = to_step(w, -w, n);
                assert_eq!(step.normal, f64::from(w) * f64::from(n));
                let (back_n, back_t) = to_substep(step, n);
                assert_eq!(back_n.to_bits(), w.to_bits(), "n {n} w {w}");
                assert_eq!(back_t.to_bits(), (-w).to_bits(), "n {n} w {w}");
            }
        }
    }

    #[test]
    fn a_resting_box_carries_m_g_dt_per_step() {
        // 4 substeps of a 2 kg box at dt = 1/60: each substep carries m g dt / 4.
        let (m, g, dt) = (2.0f64, 9.81f64, 1.0f64 / 60.0);
        let per_substep = (m * g * dt / 4.0) as f32;
        let step = to_step(per_substep, 0.0, 4);
        assert!((step.normal - m * g * dt).abs() < 1e-6, "{step:?}");
    }

    #[test]
    fn the_solved_impulse_drops_the_written_warm_start() {
        let solved = solved_per_step((1.5, -0.25), (0.5, 0.25));
        assert_eq!(solved, Impulse::new(1.0, -0.5));
        assert_eq!(substeps(0), 1);
        assert_eq!(substeps(4), 4);
    }
}
