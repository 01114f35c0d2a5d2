//! The thesis's Table 1 (section 5.5): how much of a value survives particles → grid →
//! particles, for body masses and contact normal impulses.

use deepcontact_core::{BodyKind, Impulse, Vector, World};

use crate::error::GridError;
use crate::kernel::Kernel;
use crate::spec::GridSpec;
use crate::transfer::Transfer;

/// The spacings and support radii of Table 1 (each spacing with each radius).
pub const TABLE1_VALUES: [f64; 3] = [0.125, 0.25, 0.5];

/// The thesis's Table 1: `(res, h, average body-mass difference, average contact
/// normal-impulse difference)`, 25 piles of 100 circles after 200 steps.
pub const THESIS_TABLE1: [(f64, f64, f64, f64); 9] = [
    (0.125, 0.125, 0.0000, 0.0000),
    (0.125, 0.25, 0.0000, 0.0000),
    (0.125, 0.5, 0.0000, 0.0191),
    (0.25, 0.125, 0.1137, 0.0480),
    (0.25, 0.25, 0.0000, 0.0000),
    (0.25, 0.5, 0.0000, 0.0195),
    (0.5, 0.125, 0.5177, 0.2349),
    (0.5, 0.25, 0.1074, 0.0589),
    (0.5, 0.5, 0.0000, 0.0237),
];

/// Sums of absolute round-trip differences; add worlds together with [`RoundTripSums::add`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RoundTripSums {
    /// `Σ |m' − m|` over bodies.
    pub body_abs_diff: f64,
    /// Bodies counted.
    pub bodies: usize,
    /// Bodies with no node within `h`.
    pub lost_bodies: usize,
    /// `Σ |λ' − λ|` over contact points (normal impulse).
    pub contact_abs_diff: f64,
    /// Contact points counted.
    pub contacts: usize,
    /// Contact points with no node within `h`.
    pub lost_contacts: usize,
}

impl RoundTripSums {
    /// Adds another world's sums.
    pub fn add(&mut self, other: &RoundTripSums) {
        self.body_abs_diff += other.body_abs_diff;
        self.bodies += other.bodies;
        self.lost_bodies += other.lost_bodies;
        self.contact_abs_diff += other.contact_abs_diff;
        self.contacts += other.contacts;
        self.lost_contacts += other.lost_contacts;
    }

    /// Mean absolute body-mass difference (0 without bodies).
    pub fn body_mean(&self) -> f64 {
        if self.bodies > 0 {
            self.body_abs_diff / self.bodies as f64
        } else {
            0.0
        }
    }

    /// Mean absolute contact normal-impulse difference (0 without contacts).
    pub fn contact_mean(&self) -> f64 {
        if self.contacts > 0 {
            self.contact_abs_diff / self.contacts as f64
        } else {
            0.0
        }
    }
}

/// Reusable state for [`RoundTrip::world`].
#[derive(Debug)]
pub struct RoundTrip {
    transfer: Transfer,
    positions: Vec<Vector>,
    values: Vec<f64>,
    back: Vec<f64>,
}

impl RoundTrip {
    /// SPH both ways with `kernel` of support `h` on a grid of spacing `res` covering
    /// `[min, max]` (the pile's box).
    pub fn new(
        min: Vector,
        max: Vector,
        res: f64,
        h: f64,
        kernel: Kernel,
    ) -> Result<Self, GridError> {
        let spec = GridSpec::covering(min, max, res)?;
        Ok(Self {
            transfer: Transfer::new(spec, kernel, h)?,
            positions: Vec::new(),
            values: Vec::new(),
            back: Vec::new(),
        })
    }

    fn run(&mut self) -> Result<(f64, usize), GridError> {
        self.back.clear();
        self.back.resize(self.values.len(), 0.0);
        let stats = self
            .transfer
            .round_trip(&self.positions, &self.values, 1, &mut self.back)?;
        let diff = self
            .values
            .iter()
            .zip(&self.back)
            .map(|(a, b)| (a - b).abs())
            .sum();
        Ok((diff, stats.lost))
    }

    /// The round trip of one world as it stands: the mass of every dynamic body (from
    /// its centre) and the normal impulse of every contact point of the last step (from
    /// the point; impulses matched by contact id).
    pub fn world(&mut self, world: &World) -> Result<RoundTripSums, GridError> {
        self.positions.clear();
        self.values.clear();
        for b in world
            .bodies()
            .iter()
            .filter(|b| b.kind == BodyKind::Dynamic)
        {
            self.positions.push(b.position);
            self.values.push(b.mass);
        }
        let bodies = self.positions.len();
        let (body_abs_diff, lost_bodies) = self.run()?;
        self.positions.clear();
        self.values.clear();
        let solved = world.contacts();
        for c in world.raw_contacts() {
            let imp = match solved.binary_search_by(|(id, _)| id.cmp(&c.id)) {
                Ok(i) => solved[i].1,
                Err(_) => Impulse::ZERO,
            };
            self.positions.push(c.point);
            self.values.push(imp.normal);
        }
        let contacts = self.positions.len();
        let (contact_abs_diff, lost_contacts) = self.run()?;
        Ok(RoundTripSums {
            body_abs_diff,
            bodies,
            lost_bodies,
            contact_abs_diff,
            contacts,
            lost_contacts,
        })
    }
}
