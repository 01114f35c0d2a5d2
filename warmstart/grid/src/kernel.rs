//! SPH smoothing kernels, normalised in two dimensions.

use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::GridError;

/// A smoothing kernel `W(r, h)` with compact support `r ≤ h`, normalised so that its
/// integral over the plane is one (thesis eq. 5.1): `∫ W(|x|, h) dx = 1`.
///
/// | kernel | `W(r, h)` for `0 ≤ r ≤ h` (0 beyond) |
/// |---|---|
/// | [`Kernel::Poly6`] (default) | `4 / (π h⁸) · (h² − r²)³` (thesis eq. 5.4) |
/// | [`Kernel::Spiky`] | `10 / (π h⁵) · (h − r)³` |
/// | [`Kernel::Gaussian`] | `exp(−r² / 2σ²) / (2π σ² (1 − exp(−h² / 2σ²)))` |
///
/// The spiky constant is the 2D one: `2π ∫₀ʰ (h − r)³ r dr = π h⁵ / 10`. The thesis's
/// eq. 5.3 prints `15 / (π h⁶)`, which is the 3D constant (Müller et al. 2003).
/// The Gaussian (thesis eq. 5.2) is cut off at `h` and renormalised over the disc of
/// radius `h`, so it too has compact support; `σ = h / 3` keeps 98.9 % of the untruncated
/// mass. Since the transfers normalise the discrete weights per particle (P2G) or per
/// node (G2P), only the shape of the kernel matters to them, not its constant; the
/// constants are there so that [`Kernel::value`] is a true 2D density.
///
/// ```
/// use deepcontact_grid::Kernel;
/// let k = Kernel::Poly6;
/// assert!((k.value(0.0, 0.5) - 4.0 / (std::f64::consts::PI * 0.5f64.powi(2))).abs() < 1e-12);
/// assert_eq!(k.value(0.5, 0.5), 0.0);
/// assert_eq!(k.value(0.7, 0.5), 0.0);
/// assert_eq!("spiky".parse::<Kernel>().unwrap(), Kernel::Spiky);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Kernel {
    /// `(h² − r²)³`, the thesis's choice (Müller et al. 2003). Default.
    #[default]
    Poly6,
    /// `(h − r)³`: sharper peak.
    Spiky,
    /// Gaussian of standard deviation `sigma` metres, cut off at `h`.
    Gaussian {
        /// Standard deviation in metres (finite, > 0). [`Kernel::gaussian_for`] uses `h / 3`.
        sigma: f64,
    },
}

impl Kernel {
    /// Names accepted by [`FromStr`] (`"gaussian"` gets `σ = 1`; prefer [`Kernel::gaussian_for`]).
    pub const NAMES: &'static str = "poly6, spiky, gaussian";

    /// The Gaussian with `σ = h / 3`.
    pub fn gaussian_for(h: f64) -> Self {
        Kernel::Gaussian { sigma: h / 3.0 }
    }

    /// Short name: `poly6`, `spiky` or `gaussian`.
    pub fn name(&self) -> &'static str {
        match self {
            Kernel::Poly6 => "poly6",
            Kernel::Spiky => "spiky",
            Kernel::Gaussian { .. } => "gaussian",
        }
    }

    /// Checks the support radius and the kernel's own parameters.
    pub fn validate(&self, h: f64) -> Result<(), GridError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(GridError::InvalidSupport { h });
        }
        match *self {
            Kernel::Gaussian { sigma } if !(sigma.is_finite() && sigma > 0.0) => {
                Err(GridError::InvalidKernel {
                    kernel: "gaussian",
                    param: "sigma",
                    value: sigma,
                    reason: "must be finite and > 0",
                })
            }
            _ => Ok(()),
        }
    }

    /// The normalised 2D kernel value at distance `r` (0 for `r > h`, and for bad `r`/`h`).
    pub fn value(&self, r: f64, h: f64) -> f64 {
        if !(r >= 0.0 && r <= h && h > 0.0) {
            return 0.0;
        }
        match *self {
            Kernel::Poly6 => 4.0 / (PI * h.powi(8)) * (h * h - r * r).powi(3),
            Kernel::Spiky => 10.0 / (PI * h.powi(5)) * (h - r).powi(3),
            Kernel::Gaussian { sigma } => {
                let s2 = 2.0 * sigma * sigma;
                let norm = PI * s2 * (1.0 - (-h * h / s2).exp());
                if norm > 0.0 {
                    (-r * r / s2).exp() / norm
                } else {
                    0.0
                }
            }
        }
    }

    /// Prepares the unnormalised profile for the transfer loops.
    pub(crate) fn prepare(&self, h: f64) -> Prepared {
        Prepared {
            kind: match self {
                Kernel::Poly6 => Kind::Poly6,
                Kernel::Spiky => Kind::Spiky,
                Kernel::Gaussian { .. } => Kind::Gaussian,
            },
            h,
            h2: h * h,
            neg_inv_2s2: match *self {
                Kernel::Gaussian { sigma } => -1.0 / (2.0 * sigma * sigma),
                _ => 0.0,
            },
        }
    }
}

impl fmt::Display for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Kernel::Gaussian { sigma } => write!(f, "gaussian(sigma={sigma})"),
            k => f.write_str(k.name()),
        }
    }
}

impl FromStr for Kernel {
    type Err = GridError;

    /// `poly6`, `spiky` or `gaussian` (σ = 1 m; set it with [`Kernel::Gaussian`]).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "poly6" => Ok(Kernel::Poly6),
            "spiky" => Ok(Kernel::Spiky),
            "gaussian" | "gauss" => Ok(Kernel::Gaussian { sigma: 1.0 }),
            _ => Err(GridError::UnknownName {
                what: "kernel",
                value: s.to_string(),
                accepted: Self::NAMES,
            }),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Kind {
    Poly6,
    Spiky,
    Gaussian,
}

/// The kernel's shape without its constant, as a function of the squared distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Prepared {
    pub kind: Kind,
    pub h: f64,
    pub h2: f64,
    neg_inv_2s2: f64,
}

impl Prepared {
    /// Unnormalised weight at squared distance `r2` (caller ensures `r2 <= h2`).
    #[inline(always)]
    pub fn weight(&self, r2: f64) -> f64 {
        match self.kind {
            Kind::Poly6 => {
                let d = self.h2 - r2;
                d * d * d
            }
            Kind::Spiky => {
                let d = self.h - r2.sqrt();
                d * d * d
            }
            Kind::Gaussian => (r2 * self.neg_inv_2s2).exp(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integral over the disc of radius h in polar coordinates (Simpson, 2000 panels).
    fn radial_integral(k: Kernel, h: f64) -> f64 {
        let n = 2000;
        let dr = h / n as f64;
        let f = |r: f64| 2.0 * PI * r * k.value(r, h);
        let mut s = f(0.0) + f(h);
        for i in 1..n {
            s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(i as f64 * dr);
        }
        s * dr / 3.0
    }

    #[test]
    fn kernels_integrate_to_one_radially() {
        for h in [0.125, 0.5, 2.0] {
            for k in [
                Kernel::Poly6,
                Kernel::Spiky,
                Kernel::gaussian_for(h),
                Kernel::Gaussian { sigma: h },
            ] {
                let i = radial_integral(k, h);
                assert!((i - 1.0).abs() < 1e-6, "{k} h={h}: {i}");
            }
        }
    }

    #[test]
    fn prepared_is_proportional_to_value() {
        let h = 0.5;
        for k in [Kernel::Poly6, Kernel::Spiky, Kernel::gaussian_for(h)] {
            let p = k.prepare(h);
            let c = k.value(0.1, h) / p.weight(0.01);
            for r in [0.0, 0.2, 0.3, 0.45] {
                assert!(
                    (k.value(r, h) - c * p.weight(r * r)).abs() < 1e-9 * k.value(0.0, h),
                    "{k} r={r}"
                );
            }
        }
    }

    #[test]
    fn validation_and_parsing() {
        assert!(Kernel::Poly6.validate(0.0).is_err());
        assert!(Kernel::Poly6.validate(f64::NAN).is_err());
        assert!(Kernel::Gaussian { sigma: -1.0 }.validate(0.5).is_err());
        assert!(Kernel::Gaussian { sigma: 0.2 }.validate(0.5).is_ok());
        assert!("cubic".parse::<Kernel>().is_err());
        assert_eq!(Kernel::Spiky.value(f64::NAN, 0.5), 0.0);
        let json = serde_json::to_string(&Kernel::Gaussian { sigma: 0.25 }).unwrap();
        assert_eq!(json, r#"{"kind":"gaussian","sigma":0.25}"#);
        assert_eq!(
            serde_json::from_str::<Kernel>(r#"{"kind":"poly6"}"#).unwrap(),
            Kernel::Poly6
        );
    }
}
