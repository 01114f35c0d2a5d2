//! Soft constraint coefficients (Box2D v3's `b2Softness`, `b2MakeSoft`).
//!
//! A soft contact is a stiff spring and damper on the separation `s` (negative = overlap):
//! stiffness `k = m ω²` and damping `c = 2 m ζ ω` for the row's effective mass `m`, with
//! `ω = 2π f` (`f` in Hz, `ζ` the damping ratio). Integrating
//! `m Δv = −h (k s_next + c v_next)` implicitly over a substep `h`, with
//! `s_next = s + h v_next`, and solving for the impulse `λ = m Δv` as one sequential-impulse
//! row gives
//!
//! ```text
//! λ = −m · mass_scale · (v + bias_rate · s) − impulse_scale · λ_acc
//!
//! a1            = 2ζ + h ω
//! a2            = h ω a1
//! bias_rate     = ω / a1                (1/s: the velocity asked for per metre of overlap)
//! mass_scale    = a2 / (1 + a2)         (the fraction of the rigid row's mass that acts)
//! impulse_scale = 1 / (1 + a2)          (the fraction of the accumulated impulse let go)
//! ```
//!
//! `mass_scale + impulse_scale = 1`. With `f → ∞` the row turns rigid (`mass_scale → 1`,
//! `impulse_scale → 0`); with `f = 0` it is a plain velocity row without bias
//! (Box2D's convention for a zero frequency).

use deepcontact_core::Real;

/// The coefficients of one soft row at one substep length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Softness {
    /// Velocity asked for per metre of overlap (1/s).
    pub bias_rate: Real,
    /// Fraction of the rigid effective mass that acts (dimensionless, in [0, 1]).
    pub mass_scale: Real,
    /// Fraction of the accumulated impulse released per solve (dimensionless, in [0, 1]).
    pub impulse_scale: Real,
}

impl Softness {
    /// A rigid row without bias (what a zero frequency gives): `bias_rate = 0`,
    /// `mass_scale = 1`, `impulse_scale = 0`.
    pub const RIGID: Softness = Softness {
        bias_rate: 0.0,
        mass_scale: 1.0,
        impulse_scale: 0.0,
    };

    /// The coefficients of a spring of `hertz` Hz and damping ratio `zeta` integrated over
    /// substeps of `h` seconds (Box2D v3's `b2MakeSoft`; see the module docs for the
    /// derivation). `hertz = 0` gives [`Softness::RIGID`].
    pub fn new(hertz: Real, zeta: Real, h: Real) -> Self {
        if hertz == 0.0 {
            return Self::RIGID;
        }
        let omega = 2.0 * std::f64::consts::PI * hertz;
        let a1 = 2.0 * zeta + h * omega;
        let a2 = h * omega * a1;
        let a3 = 1.0 / (1.0 + a2);
        Self {
            bias_rate: omega / a1,
            mass_scale: a2 * a3,
            impulse_scale: a3,
        }
    }
}

/// The contact stiffness actually used (Hz): the asked-for `hertz`, but no more than a quarter
/// of the substep rate `1 / h` (Box2D v3: `contactHertz = min(contactHertz, 0.25 × substep
/// rate)`), so that a substep resolves the spring's period with four substeps at least.
pub fn contact_hertz(hertz: Real, h: Real) -> Real {
    hertz.min(0.25 / h)
}

/// The softness of the contacts of one solve: `contact` between two bodies that can both
/// move, `fixed` (twice as stiff, Box2D v3's `staticSoftness`, so that bodies are not pushed
/// into the ground) where one body cannot move at all (zero inverse mass and inertia).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSoftness {
    /// Between two movable bodies.
    pub contact: Softness,
    /// Against an immovable body.
    pub fixed: Softness,
}

impl ContactSoftness {
    /// The softness at `hertz` (capped by [`contact_hertz`]), damping ratio `zeta` and
    /// substep `h` (s).
    pub fn new(hertz: Real, zeta: Real, h: Real) -> Self {
        let f = contact_hertz(hertz, h);
        Self {
            contact: Softness::new(f, zeta, h),
            fixed: Softness::new(2.0 * f, zeta, h),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Box2D v3's defaults at 60 Hz × 4 substeps: f = min(30, 0.25 × 240) = 30 Hz, ζ = 10,
    /// h = 1/240 s; ω = 60π, a1 = 20 + ω h, a2 = ω h a1.
    #[test]
    fn make_soft_matches_the_closed_form_and_its_identities() {
        let h = 1.0 / 240.0;
        let s = Softness::new(30.0, 10.0, h);
        let omega = 60.0 * std::f64::consts::PI;
        let a1 = 20.0 + omega * h;
        let a2 = omega * h * a1;
        assert!((s.bias_rate - omega / a1).abs() < 1e-12);
        assert!((s.mass_scale - a2 / (1.0 + a2)).abs() < 1e-12);
        assert!((s.mass_scale + s.impulse_scale - 1.0).abs() < 1e-12);
        assert_eq!(Softness::new(0.0, 10.0, h), Softness::RIGID);
    }

    #[test]
    fn the_frequency_is_capped_at_a_quarter_of_the_substep_rate() {
        // 1 substep of 0.01 s: 25 Hz at most.
        assert_eq!(contact_hertz(30.0, 0.01), 25.0);
        assert_eq!(contact_hertz(30.0, 0.0025), 30.0);
        let c = ContactSoftness::new(30.0, 10.0, 0.0025);
        assert_eq!(c.fixed, Softness::new(60.0, 10.0, 0.0025));
        assert!(c.fixed.mass_scale > c.contact.mass_scale);
    }
}
