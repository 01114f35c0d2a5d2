//! Contact identity and impulses.

use crate::math::Real;

/// Identity of a contact point across steps: the ordered body pair and the
/// features (vertex / edge / face ids, packed by parry2d, with the sub-shape
/// index of composite shapes in the high bits) of each body that produce it.
/// A point whose id matches one of the previous step inherits its impulse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct ContactId {
    /// Smaller body index of the pair.
    pub body_a: u32,
    /// Larger body index of the pair.
    pub body_b: u32,
    /// Feature of body A.
    pub feature_a: u64,
    /// Feature of body B.
    pub feature_b: u64,
}

/// Accumulated impulse of one contact point (N·s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Impulse {
    /// Along the contact normal (≥ 0 when admissible).
    pub normal: Real,
    /// Along the tangent `(-n.y, n.x)` (|t| ≤ μ n when admissible).
    pub tangent: Real,
}

impl Impulse {
    /// The zero impulse.
    pub const ZERO: Impulse = Impulse {
        normal: 0.0,
        tangent: 0.0,
    };

    /// Builds an impulse.
    pub const fn new(normal: Real, tangent: Real) -> Self {
        Self { normal, tangent }
    }

    /// Both components finite.
    pub fn is_finite(&self) -> bool {
        self.normal.is_finite() && self.tangent.is_finite()
    }
}
