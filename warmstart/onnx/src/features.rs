//! The grids a CNN reads and writes, in the `f32` the models use.
//!
//! A thin layer over [`deepcontact_grid::GridEncoder`], which owns the grid layout (the thesis's
//! 61 × 61 nodes at 0.25 m over `[0, 15]²`, poly6 with `h = 0.5`, SPH transfers both ways, walls
//! marked with mass 100), the channel order (`[mass, vx, vy, omega, nx, ny]` in,
//! `[normal_impulse, tangent_impulse]` out) and the transfers. This module only converts between
//! the encoder's `f64` grids and the models' `f32` tensors, reusing its buffers.
//!
//! The same code builds the training data (`deepcontact generate`) and the providers' input,
//! so what a model sees at run time is exactly what it was trained on.

use deepcontact_core::{ContactProblem, Impulse, Vector, World};
pub use deepcontact_grid::{GridEncoder, GridLayout};

use crate::card::LayoutExpectation;
use crate::error::OnnxError;

/// What a model trained on `layout` must look like (channels, shapes, the layout JSON).
pub fn expectation(layout: &GridLayout) -> LayoutExpectation {
    LayoutExpectation {
        json: serde_json::from_str(&layout.to_json()).unwrap_or(serde_json::Value::Null),
        input_channels: layout.input_channels.clone(),
        output_channels: layout.output_channels.clone(),
        nx: layout.grid.nx,
        ny: layout.grid.ny,
    }
}

fn grid_error(e: deepcontact_grid::GridError) -> OnnxError {
    OnnxError::Grid {
        reason: e.to_string(),
    }
}

/// [`GridEncoder`] with `f32` input / output tensors.
#[derive(Debug)]
pub struct GridFeatures {
    encoder: GridEncoder,
    input: Vec<f64>,
    output: Vec<f64>,
}

impl GridFeatures {
    /// Features for `layout` (validated by the grid crate).
    pub fn new(layout: GridLayout) -> Result<Self, OnnxError> {
        let input = vec![0.0; layout.input_len()];
        let output = vec![0.0; layout.output_len()];
        Ok(Self {
            encoder: GridEncoder::new(layout).map_err(grid_error)?,
            input,
            output,
        })
    }

    /// The layout.
    pub fn layout(&self) -> &GridLayout {
        self.encoder.layout()
    }

    fn to_f32(src: &[f64], dst: &mut [f32]) -> Result<(), OnnxError> {
        if src.len() != dst.len() {
            return Err(OnnxError::ShapeMismatch {
                what: "grid buffer".into(),
                expected: vec![src.len() as i64],
                found: vec![dst.len() as i64],
            });
        }
        for (d, s) in dst.iter_mut().zip(src) {
            *d = *s as f32;
        }
        Ok(())
    }

    /// Input grids of `world` as it is at the warm start of a step's first island.
    pub fn encode_world(&mut self, world: &World, out: &mut [f32]) -> Result<(), OnnxError> {
        self.encoder
            .encode_world(world, &mut self.input)
            .map_err(grid_error)?;
        Self::to_f32(&self.input, out)
    }

    /// Input grids of a bare contact problem (no walls: their shapes are unknown).
    pub fn encode_problem(
        &mut self,
        problem: &ContactProblem,
        out: &mut [f32],
    ) -> Result<(), OnnxError> {
        self.encoder
            .encode_problem(problem, &mut self.input)
            .map_err(grid_error)?;
        Self::to_f32(&self.input, out)
    }

    /// Label grids of `world` after a step: the final impulses of its contact points.
    pub fn encode_world_labels(&mut self, world: &World, out: &mut [f32]) -> Result<(), OnnxError> {
        self.encoder
            .encode_world_labels(world, &mut self.output)
            .map_err(grid_error)?;
        Self::to_f32(&self.output, out)
    }

    /// Impulses at contact points spread onto the two label grids (as the labels are):
    /// the carried-impulse input channels of a residual model.
    pub fn encode_impulses(
        &mut self,
        positions: &[Vector],
        impulses: &[Impulse],
        out: &mut [f32],
    ) -> Result<(), OnnxError> {
        self.encoder
            .encode_labels(positions, impulses, &mut self.output)
            .map_err(grid_error)?;
        Self::to_f32(&self.output, out)
    }

    /// Grid → contact points: the impulses at `positions` from the output grids `grids`
    /// (normals clamped to ≥ 0 by the encoder). A non-finite grid value is an error.
    pub fn decode(
        &mut self,
        grids: &[f32],
        positions: &[Vector],
        impulses: &mut [Impulse],
    ) -> Result<(), OnnxError> {
        self.decode_signed(grids, positions, impulses)?;
        for i in impulses.iter_mut() {
            i.normal = i.normal.max(0.0);
        }
        Ok(())
    }

    /// [`Self::decode`] for grids of corrections (a residual model's output): no clamp.
    pub fn decode_signed(
        &mut self,
        grids: &[f32],
        positions: &[Vector],
        impulses: &mut [Impulse],
    ) -> Result<(), OnnxError> {
        self.load_output(grids)?;
        self.encoder
            .decode_signed(&self.output, positions, impulses)
            .map_err(grid_error)?;
        Ok(())
    }

    /// Copies a model's output grids into the encoder's buffer; a non-finite value is an error.
    fn load_output(&mut self, grids: &[f32]) -> Result<(), OnnxError> {
        if grids.len() != self.output.len() {
            return Err(OnnxError::ShapeMismatch {
                what: "output grids".into(),
                expected: vec![self.output.len() as i64],
                found: vec![grids.len() as i64],
            });
        }
        for (i, (d, s)) in self.output.iter_mut().zip(grids).enumerate() {
            if !s.is_finite() {
                return Err(OnnxError::Inference {
                    reason: format!("model output {i} is {s}"),
                });
            }
            *d = *s as f64;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_isolated_contact_round_trips() {
        let mut f = GridFeatures::new(GridLayout::thesis()).unwrap();
        let mut enc = GridEncoder::new(GridLayout::thesis()).unwrap();
        let p = [Vector::new(3.1, 7.3)];
        let mut out64 = vec![0.0; f.layout().output_len()];
        enc.encode_labels(&p, &[Impulse::new(2.5, -0.5)], &mut out64)
            .unwrap();
        let grids: Vec<f32> = out64.iter().map(|v| *v as f32).collect();
        let mut back = [Impulse::ZERO];
        f.decode(&grids, &p, &mut back).unwrap();
        assert!(
            (back[0].normal - 2.5).abs() < 1e-5 && (back[0].tangent + 0.5).abs() < 1e-5,
            "{back:?}"
        );
        let mut bad = grids.clone();
        bad[5] = f32::NAN;
        assert!(f.decode(&bad, &p, &mut back).is_err());
    }

    #[test]
    fn expectation_matches_the_layout() {
        let e = expectation(&GridLayout::thesis());
        assert_eq!(e.input_shape(), vec![1, 6, 61, 61]);
        assert_eq!(e.output_shape(), vec![1, 2, 61, 61]);
        assert_eq!(e.json["grid"]["nx"], 61);
    }
}
