//! [`GridEncoder`]: worlds and contact problems → the 6 input channels, impulses ↔
//! the 2 output channels. The building block of the CNN providers and the data generator.

use deepcontact_core::{BodyKind, ContactProblem, Impulse, Vector, World};

use crate::error::GridError;
use crate::layout::{CH_MASS, CH_NX, GridLayout, INPUT_CHANNELS, OUTPUT_CHANNELS};
use crate::transfer::{Transfer, TransferStats};
use crate::walls::WallCache;

/// Counts from one [`GridEncoder::encode_world`] / [`GridEncoder::encode_problem`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EncodeStats {
    /// Dynamic bodies transferred.
    pub bodies: usize,
    /// Contact points transferred.
    pub contacts: usize,
    /// Bodies with no node within `h` (their values are lost).
    pub lost_bodies: usize,
    /// Contact points with no node within `h`.
    pub lost_contacts: usize,
    /// Nodes marked as walls (mass set to [`GridLayout::wall_mass`]).
    pub wall_nodes: usize,
}

/// Turns worlds into input grids and output grids into impulses, following one
/// [`GridLayout`]. Reuses its buffers: no allocation per call once warmed up (the wall
/// nodes are recomputed only when the static bodies change).
///
/// Grids are channel-major slices (`channels × nodes`, see [`crate::GridSpec`]).
///
/// ```
/// use deepcontact_core::{scene, CarriedWarmStart, World, WorldSettings};
/// use deepcontact_grid::{GridEncoder, GridLayout};
///
/// let mut world = scene::pile(0, 100).unwrap().build(WorldSettings::default()).unwrap();
/// let mut encoder = GridEncoder::new(GridLayout::thesis()).unwrap();
/// let mut input = vec![0.0; encoder.layout().input_len()];
/// let stats = encoder.encode_world(&world, &mut input).unwrap();
/// assert_eq!((stats.bodies, stats.wall_nodes), (100, 240));
/// ```
#[derive(Debug)]
pub struct GridEncoder {
    layout: GridLayout,
    transfer: Transfer,
    positions: Vec<Vector>,
    values: Vec<f64>,
    back: Vec<f64>,
    walls: WallCache,
}

impl GridEncoder {
    /// An encoder for a validated `layout`.
    pub fn new(layout: GridLayout) -> Result<Self, GridError> {
        let transfer = layout.transfer()?;
        Ok(Self {
            layout,
            transfer,
            positions: Vec::new(),
            values: Vec::new(),
            back: Vec::new(),
            walls: WallCache::new(),
        })
    }

    /// The layout.
    pub fn layout(&self) -> &GridLayout {
        &self.layout
    }

    /// The underlying transfer (for custom channels on the same grid).
    pub fn transfer_mut(&mut self) -> &mut Transfer {
        &mut self.transfer
    }

    fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), GridError> {
        if expected == got {
            Ok(())
        } else {
            Err(GridError::LengthMismatch {
                what,
                expected,
                got,
            })
        }
    }

    /// The 6 input channels of a world: zeroes `input` (`6 × nodes`), spreads mass,
    /// velocity and angular velocity of every dynamic body from its centre of mass,
    /// and the normal of every contact point of the last narrow phase
    /// ([`World::raw_contacts`]) from the point; then sets the mass of the nodes within
    /// [`GridLayout::wall_band`] of a static body to [`GridLayout::wall_mass`].
    ///
    /// Inside [`deepcontact_core::WarmStart::warm_start`] the world's contacts are
    /// those of the step being solved, but the velocities of bodies in islands solved
    /// earlier in the step are already updated: encode once per step, at island 0, to
    /// see the state before any solve.
    pub fn encode_world(
        &mut self,
        world: &World,
        input: &mut [f64],
    ) -> Result<EncodeStats, GridError> {
        let n = self.layout.nodes();
        Self::check_len("input grid", INPUT_CHANNELS.len() * n, input.len())?;
        input.fill(0.0);
        self.positions.clear();
        self.values.clear();
        for b in world
            .bodies()
            .iter()
            .filter(|b| b.kind == BodyKind::Dynamic)
        {
            self.positions.push(b.position);
            self.values.extend([
                b.mass,
                b.linear_velocity.x,
                b.linear_velocity.y,
                b.angular_velocity,
            ]);
        }
        let body = self.transfer.particles_to_grid(
            &self.positions,
            &self.values,
            4,
            &mut input[CH_MASS * n..CH_NX * n],
        )?;
        self.positions.clear();
        self.values.clear();
        for c in world.raw_contacts() {
            self.positions.push(c.point);
            self.values.extend([c.normal.x, c.normal.y]);
        }
        let contact = self.transfer.particles_to_grid(
            &self.positions,
            &self.values,
            2,
            &mut input[CH_NX * n..],
        )?;
        let walls = self
            .walls
            .nodes(&self.layout.grid, world.bodies(), self.layout.wall_band);
        for &node in walls {
            input[CH_MASS * n + node as usize] = self.layout.wall_mass;
        }
        Ok(EncodeStats {
            bodies: body.particles,
            contacts: contact.particles,
            lost_bodies: body.lost,
            lost_contacts: contact.lost,
            wall_nodes: walls.len(),
        })
    }

    /// The 6 input channels of a contact problem without a world (hand-built problems,
    /// foreign engines): bodies with `inv_mass > 0` give mass `1 / inv_mass` and their
    /// velocities; static bodies are skipped and no wall nodes are marked (their shapes
    /// are unknown).
    pub fn encode_problem(
        &mut self,
        problem: &ContactProblem,
        input: &mut [f64],
    ) -> Result<EncodeStats, GridError> {
        let n = self.layout.nodes();
        Self::check_len("input grid", INPUT_CHANNELS.len() * n, input.len())?;
        input.fill(0.0);
        self.positions.clear();
        self.values.clear();
        for b in problem.bodies.iter().filter(|b| b.inv_mass > 0.0) {
            self.positions.push(b.position);
            self.values.extend([
                1.0 / b.inv_mass,
                b.linear_velocity.x,
                b.linear_velocity.y,
                b.angular_velocity,
            ]);
        }
        let body = self.transfer.particles_to_grid(
            &self.positions,
            &self.values,
            4,
            &mut input[CH_MASS * n..CH_NX * n],
        )?;
        self.positions.clear();
        self.values.clear();
        for p in &problem.points {
            self.positions.push(p.point);
            self.values.extend([p.normal.x, p.normal.y]);
        }
        let contact = self.transfer.particles_to_grid(
            &self.positions,
            &self.values,
            2,
            &mut input[CH_NX * n..],
        )?;
        Ok(EncodeStats {
            bodies: body.particles,
            contacts: contact.particles,
            lost_bodies: body.lost,
            lost_contacts: contact.lost,
            wall_nodes: 0,
        })
    }

    /// The 2 output channels (labels) of impulses at `positions`: zeroes `output`
    /// (`2 × nodes`) and spreads each point's (normal, tangent) impulse.
    pub fn encode_labels(
        &mut self,
        positions: &[Vector],
        impulses: &[Impulse],
        output: &mut [f64],
    ) -> Result<TransferStats, GridError> {
        Self::check_len("impulses", positions.len(), impulses.len())?;
        Self::check_len(
            "output grid",
            OUTPUT_CHANNELS.len() * self.layout.nodes(),
            output.len(),
        )?;
        output.fill(0.0);
        self.values.clear();
        self.values
            .extend(impulses.iter().flat_map(|i| [i.normal, i.tangent]));
        self.transfer
            .particles_to_grid(positions, &self.values, 2, output)
    }

    /// The labels of a world after a step: the final impulse of every contact point of
    /// the last narrow phase (matched by contact id in [`World::contacts`]).
    pub fn encode_world_labels(
        &mut self,
        world: &World,
        output: &mut [f64],
    ) -> Result<TransferStats, GridError> {
        Self::check_len(
            "output grid",
            OUTPUT_CHANNELS.len() * self.layout.nodes(),
            output.len(),
        )?;
        output.fill(0.0);
        let solved = world.contacts();
        self.positions.clear();
        self.values.clear();
        for c in world.raw_contacts() {
            let imp = match solved.binary_search_by(|(id, _)| id.cmp(&c.id)) {
                Ok(i) => solved[i].1,
                Err(_) => Impulse::ZERO,
            };
            self.positions.push(c.point);
            self.values.extend([imp.normal, imp.tangent]);
        }
        self.transfer
            .particles_to_grid(&self.positions, &self.values, 2, output)
    }

    /// Grid → contact points for the 2 output channels (a model's prediction), with the
    /// layout's [`GridLayout::g2p`] method. Normal impulses are clamped to ≥ 0 so the
    /// result is always an admissible warm start; tangents are left as they are.
    pub fn decode(
        &mut self,
        output: &[f64],
        positions: &[Vector],
        impulses: &mut [Impulse],
    ) -> Result<TransferStats, GridError> {
        let stats = self.decode_signed(output, positions, impulses)?;
        for imp in impulses.iter_mut() {
            imp.normal = imp.normal.max(0.0);
        }
        Ok(stats)
    }

    /// [`GridEncoder::decode`] without the clamp: for grids of *corrections* to impulses,
    /// which may be negative in both channels.
    pub fn decode_signed(
        &mut self,
        output: &[f64],
        positions: &[Vector],
        impulses: &mut [Impulse],
    ) -> Result<TransferStats, GridError> {
        Self::check_len("impulses", positions.len(), impulses.len())?;
        self.back.clear();
        self.back.resize(2 * positions.len(), 0.0);
        let stats = self
            .transfer
            .grid_to_particles(output, 2, positions, &mut self.back)?;
        for (imp, v) in impulses.iter_mut().zip(self.back.chunks_exact(2)) {
            *imp = Impulse::new(v[0], v[1]);
        }
        Ok(stats)
    }

    /// [`GridEncoder::decode`] at the points of `problem` (one impulse per point).
    pub fn decode_problem(
        &mut self,
        output: &[f64],
        problem: &ContactProblem,
        impulses: &mut [Impulse],
    ) -> Result<TransferStats, GridError> {
        let mut positions = std::mem::take(&mut self.positions);
        positions.clear();
        positions.extend(problem.points.iter().map(|p| p.point));
        let r = self.decode(output, &positions, impulses);
        self.positions = positions;
        r
    }
}
