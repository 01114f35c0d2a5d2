//! The grids a CNN reads and writes, built from a world (or a bare contact problem).
//!
//! Layout (the thesis's, DESIGN.md "Grids"): `nx × ny = 61 × 61` nodes, spacing 0.25 m, covering
//! `[0, 15]²`, node `(i, j)` at `origin + (i, j) · spacing`, stored row-major as `[channel][j][i]`
//! (NCHW with H = y, W = x). Particles are spread with the 2D poly6 kernel of support
//! `h = 0.5`: **particle → grid** weights are normalised to sum to one per particle; **grid →
//! particle** weights are normalised to sum to one per grid node, over the particles within `h`
//! of it. With `h = 2 × spacing` only a 5 × 5 window of nodes around a particle can be within
//! reach, so the neighbour search is a window scan (exact; no tree needed at this resolution).
//!
//! Input channels: `[mass, vx, vy, omega, nx, ny]` — the first four from the dynamic bodies'
//! centres of mass, the last two from the contact points' normals; nodes on the border of the
//! grid (where the static box of the pile lies) get mass [`GridLayout::wall_mass`] = 100.
//! Output channels: `[normal, tangent]` impulse, spread from the contact points.
//!
//! The same code builds the training data (`deepcontact generate`) and the providers' input,
//! so what a model sees at run time is exactly what it was trained on.

use deepcontact_core::{Body, Real, Vector, World};
use serde::{Deserialize, Serialize};

use crate::card::LayoutExpectation;

/// Input channel names, in tensor order.
pub const INPUT_CHANNELS: [&str; 6] = ["mass", "vx", "vy", "omega", "nx", "ny"];
/// Output channel names, in tensor order.
pub const OUTPUT_CHANNELS: [&str; 2] = ["normal", "tangent"];

/// A grid and the particle ↔ grid transfer settings; serialised verbatim into model cards and
/// training-data headers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridLayout {
    /// Nodes along x (tensor width).
    pub nx: usize,
    /// Nodes along y (tensor height).
    pub ny: usize,
    /// Node spacing (m).
    pub spacing: Real,
    /// Position of node `(0, 0)`.
    pub origin: [Real; 2],
    /// Smoothing kernel (`poly6`).
    pub kernel: String,
    /// Kernel support radius `h` (m).
    pub support: Real,
    /// Mass written on the border nodes (the static walls).
    pub wall_mass: Real,
    /// Memory order of one channel (`row-major [y][x]`).
    pub order: String,
    /// Input channel names, in order.
    pub input_channels: Vec<String>,
    /// Output channel names, in order.
    pub output_channels: Vec<String>,
}

impl Default for GridLayout {
    /// The thesis layout: 61 × 61 at 0.25 m over `[0, 15]²`, poly6 with `h = 0.5`, walls 100.
    fn default() -> Self {
        Self {
            nx: 61,
            ny: 61,
            spacing: 0.25,
            origin: [0.0, 0.0],
            kernel: "poly6".into(),
            support: 0.5,
            wall_mass: 100.0,
            order: "row-major [y][x]".into(),
            input_channels: INPUT_CHANNELS.iter().map(|s| s.to_string()).collect(),
            output_channels: OUTPUT_CHANNELS.iter().map(|s| s.to_string()).collect(),
        }
    }
}

impl GridLayout {
    /// Number of nodes of one channel.
    pub fn nodes(&self) -> usize {
        self.nx * self.ny
    }

    /// Length of the input tensor (`C_in × ny × nx`).
    pub fn input_len(&self) -> usize {
        self.input_channels.len() * self.nodes()
    }

    /// Length of the output tensor (`C_out × ny × nx`).
    pub fn output_len(&self) -> usize {
        self.output_channels.len() * self.nodes()
    }

    /// The layout as JSON (what model cards and data headers carry).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }

    /// What a model trained on this layout must look like.
    pub fn expectation(&self) -> LayoutExpectation {
        LayoutExpectation {
            json: self.to_json(),
            input_channels: self.input_channels.clone(),
            output_channels: self.output_channels.clone(),
            nx: self.nx,
            ny: self.ny,
        }
    }

    /// Unnormalised 2D poly6 weight `(h² − r²)³` for `r < h`, else 0.
    #[inline]
    fn weight(&self, r2: Real) -> Real {
        let h2 = self.support * self.support;
        if r2 < h2 { (h2 - r2).powi(3) } else { 0.0 }
    }

    /// Calls `f(node, weight)` for every node within the support of `p` (unnormalised weights).
    #[inline]
    fn for_each_node(&self, p: &Vector, mut f: impl FnMut(usize, Real)) {
        if !(p.x.is_finite() && p.y.is_finite()) {
            return;
        }
        let reach = (self.support / self.spacing).ceil() as i64;
        let gx = ((p.x - self.origin[0]) / self.spacing).round() as i64;
        let gy = ((p.y - self.origin[1]) / self.spacing).round() as i64;
        for j in (gy - reach).max(0)..=(gy + reach).min(self.ny as i64 - 1) {
            let dy = self.origin[1] + j as Real * self.spacing - p.y;
            for i in (gx - reach).max(0)..=(gx + reach).min(self.nx as i64 - 1) {
                let dx = self.origin[0] + i as Real * self.spacing - p.x;
                let w = self.weight(dx * dx + dy * dy);
                if w > 0.0 {
                    f(j as usize * self.nx + i as usize, w);
                }
            }
        }
    }

    /// Particle → grid: adds `values[k]` of each particle into `channels[k]`, weights normalised
    /// per particle. `channels` are slices of `nodes()` values each.
    pub fn splat<const K: usize>(&self, p: &Vector, values: [f32; K], channels: &mut [&mut [f32]; K]) {
        let mut sum = 0.0;
        self.for_each_node(p, |_, w| sum += w);
        if sum <= 0.0 {
            return;
        }
        self.for_each_node(p, |node, w| {
            let w = (w / sum) as f32;
            for (c, v) in channels.iter_mut().zip(values) {
                c[node] += w * v;
            }
        });
    }

    /// Grid → particles, pass 1: accumulates every node's total weight over `points` into
    /// `node_weight` (`nodes()` values, zeroed by the caller).
    pub fn gather_weights(&self, points: impl Iterator<Item = Vector>, node_weight: &mut [Real]) {
        for p in points {
            self.for_each_node(&p, |node, w| node_weight[node] += w);
        }
    }

    /// Grid → particles, pass 2: the value of `channels` at `p`, each node's value shared among
    /// its particles by the normalised weights of pass 1.
    pub fn gather<const K: usize>(&self, p: &Vector, channels: [&[f32]; K], node_weight: &[Real]) -> [Real; K] {
        let mut out = [0.0; K];
        self.for_each_node(p, |node, w| {
            let total = node_weight[node];
            if total > 0.0 {
                let share = w / total;
                for (o, c) in out.iter_mut().zip(&channels) {
                    *o += share * c[node] as Real;
                }
            }
        });
        out
    }

    /// Writes the wall mass on the border nodes of the mass channel.
    pub fn mark_walls(&self, mass: &mut [f32]) {
        let m = self.wall_mass as f32;
        for i in 0..self.nx {
            mass[i] = m;
            mass[(self.ny - 1) * self.nx + i] = m;
        }
        for j in 0..self.ny {
            mass[j * self.nx] = m;
            mass[j * self.nx + self.nx - 1] = m;
        }
    }
}

/// A body as the grids see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyParticle {
    /// Centre of mass.
    pub position: Vector,
    /// Mass (dynamic bodies only; static ones are the walls).
    pub mass: Real,
    /// Linear velocity.
    pub velocity: Vector,
    /// Angular velocity.
    pub angular_velocity: Real,
}

impl BodyParticle {
    /// From a world body (`None` for static and kinematic bodies, which the wall mass stands for).
    pub fn from_body(b: &Body) -> Option<Self> {
        b.is_dynamic().then_some(Self {
            position: b.position,
            mass: b.mass,
            velocity: b.linear_velocity,
            angular_velocity: b.angular_velocity,
        })
    }
}

/// Builds the input grids `[6, ny, nx]` of one step into `out` (overwritten).
pub fn input_grids(
    layout: &GridLayout,
    bodies: impl Iterator<Item = BodyParticle>,
    contacts: impl Iterator<Item = (Vector, Vector)>,
    out: &mut [f32],
) {
    out.fill(0.0);
    let n = layout.nodes();
    let (mass, rest) = out.split_at_mut(n);
    let (vx, rest) = rest.split_at_mut(n);
    let (vy, rest) = rest.split_at_mut(n);
    let (w, rest) = rest.split_at_mut(n);
    let (nx, rest) = rest.split_at_mut(n);
    let ny = &mut rest[..n];
    for b in bodies {
        layout.splat(
            &b.position,
            [b.mass as f32, b.velocity.x as f32, b.velocity.y as f32, b.angular_velocity as f32],
            &mut [&mut *mass, &mut *vx, &mut *vy, &mut *w],
        );
    }
    for (p, normal) in contacts {
        layout.splat(&p, [normal.x as f32, normal.y as f32], &mut [&mut *nx, &mut *ny]);
    }
    layout.mark_walls(mass);
}

/// Builds the label grids `[2, ny, nx]` from contact points and their impulses (`out` overwritten).
pub fn label_grids(layout: &GridLayout, contacts: impl Iterator<Item = (Vector, Real, Real)>, out: &mut [f32]) {
    out.fill(0.0);
    let (normal, tangent) = out.split_at_mut(layout.nodes());
    for (p, n, t) in contacts {
        layout.splat(&p, [n as f32, t as f32], &mut [&mut *normal, &mut *tangent]);
    }
}

/// The input grids of `world` as it is during a step's warm start: dynamic bodies (velocities
/// with gravity applied) and the narrow phase's contact points.
pub fn world_input_grids(layout: &GridLayout, world: &World, out: &mut [f32]) {
    input_grids(
        layout,
        world.bodies().iter().filter_map(BodyParticle::from_body),
        world.raw_contacts().iter().map(|c| (c.point, c.normal)),
        out,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splat_conserves_and_gather_recovers_an_isolated_particle() {
        let layout = GridLayout::default();
        let mut a = vec![0.0f32; layout.nodes()];
        let p = Vector::new(3.1, 7.3);
        layout.splat(&p, [2.5], &mut [&mut a]);
        let total: f32 = a.iter().sum();
        assert!((total - 2.5).abs() < 1e-5);
        let mut wsum = vec![0.0; layout.nodes()];
        layout.gather_weights(std::iter::once(p), &mut wsum);
        let [v] = layout.gather(&p, [&a], &wsum);
        assert!((v - 2.5).abs() < 1e-5, "{v}");
    }

    #[test]
    fn walls_are_marked() {
        let layout = GridLayout::default();
        let mut g = vec![0.0f32; layout.input_len()];
        input_grids(&layout, std::iter::empty(), std::iter::empty(), &mut g);
        assert_eq!(g[0], 100.0);
        assert_eq!(g[30 * 61 + 60], 100.0);
        assert_eq!(g[30 * 61 + 30], 0.0);
        assert_eq!(g[layout.nodes()], 0.0);
    }
}
