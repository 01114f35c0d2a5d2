//! [`GridLayout`]: the one description of the grids, shared as JSON by the data
//! generator, the ONNX providers and the Python training code.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::GridError;
use crate::kernel::Kernel;
use crate::spec::GridSpec;
use crate::transfer::{G2pMethod, NeighbourSearch, Transfer};

/// Input channels, in order: body mass, body velocity x / y, body angular velocity
/// (all at body centres, dynamic bodies only), contact normal x / y (at contact points).
pub const INPUT_CHANNELS: [&str; 6] = ["mass", "vx", "vy", "omega", "nx", "ny"];
/// Output (label) channels, in order: normal impulse, tangent impulse (at contact points).
pub const OUTPUT_CHANNELS: [&str; 2] = ["normal_impulse", "tangent_impulse"];

/// Index of the mass channel in [`INPUT_CHANNELS`].
pub const CH_MASS: usize = 0;
/// Index of the velocity-x channel.
pub const CH_VX: usize = 1;
/// Index of the velocity-y channel.
pub const CH_VY: usize = 2;
/// Index of the angular-velocity channel.
pub const CH_OMEGA: usize = 3;
/// Index of the contact-normal-x channel.
pub const CH_NX: usize = 4;
/// Index of the contact-normal-y channel.
pub const CH_NY: usize = 5;
/// Index of the normal-impulse channel in [`OUTPUT_CHANNELS`].
pub const CH_NORMAL: usize = 0;
/// Index of the tangent-impulse channel in [`OUTPUT_CHANNELS`].
pub const CH_TANGENT: usize = 1;

/// Memory order of a multi-channel grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TensorOrder {
    /// Channel-major, then rows (`y`), then columns (`x`): `grid[(c · ny + iy) · nx + ix]`,
    /// row 0 at the lowest `y` (a PyTorch `[C, H, W]` tensor with `H = ny`, `W = nx`).
    #[default]
    Chw,
}

/// Everything needed to turn a world into grids and grids back into impulses.
///
/// Serialises to JSON (see [`GridLayout::to_json`]); the thesis layout
/// ([`GridLayout::thesis`], also `Default`) reads:
///
/// ```json
/// {
///   "version": 1,
///   "grid": { "origin": [0.0, 0.0], "spacing": 0.25, "nx": 61, "ny": 61 },
///   "order": "chw",
///   "kernel": { "kind": "poly6" },
///   "h": 0.5,
///   "search": "exact",
///   "g2p": "sph",
///   "input_channels": ["mass", "vx", "vy", "omega", "nx", "ny"],
///   "output_channels": ["normal_impulse", "tangent_impulse"],
///   "wall_mass": 100.0,
///   "wall_band": 0.125
/// }
/// ```
///
/// ```
/// use deepcontact_grid::GridLayout;
/// let layout = GridLayout::thesis();
/// let back = GridLayout::from_json(&layout.to_json()).unwrap();
/// assert_eq!(back, layout);
/// assert_eq!(layout.input_len(), 6 * 61 * 61);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridLayout {
    /// Format version, [`GridLayout::VERSION`] (1).
    pub version: u32,
    /// The grid (default: thesis 61 × 61 at 0.25 m over `[0, 15]²`).
    pub grid: GridSpec,
    /// Memory order of multi-channel grids (default and only: `chw`).
    #[serde(default)]
    pub order: TensorOrder,
    /// Smoothing kernel (default poly6).
    #[serde(default)]
    pub kernel: Kernel,
    /// Kernel support radius in metres (default 0.5).
    pub h: f64,
    /// Neighbour search of the transfers (default `exact`; results do not depend on it).
    #[serde(default)]
    pub search: NeighbourSearch,
    /// Grid → particles method for the outputs (default `sph`).
    #[serde(default)]
    pub g2p: G2pMethod,
    /// Input channel names, in order; must equal [`INPUT_CHANNELS`].
    pub input_channels: Vec<String>,
    /// Output channel names, in order; must equal [`OUTPUT_CHANNELS`].
    pub output_channels: Vec<String>,
    /// Mass channel value at wall nodes (default 100, the thesis's). Overwrites whatever
    /// the bodies spread there.
    pub wall_mass: f64,
    /// A node is a wall node when it lies within this distance (metres) of a static
    /// body's shape (default half the spacing: the nodes on the walls of the pile's box).
    pub wall_band: f64,
}

impl Default for GridLayout {
    /// [`GridLayout::thesis`].
    fn default() -> Self {
        Self::thesis()
    }
}

impl GridLayout {
    /// The format version this build reads and writes.
    pub const VERSION: u32 = 1;

    /// The thesis layout: 61 × 61 at 0.25 m over `[0, 15]²`, poly6, `h = 0.5`, SPH both
    /// ways, wall mass 100 on the nodes within 0.125 m of the walls.
    pub fn thesis() -> Self {
        Self::new(GridSpec::thesis(), Kernel::Poly6, 0.5)
    }

    /// A layout on `grid` with `kernel` and `h`, the other fields at their defaults
    /// (wall band half the spacing). Not validated: call [`GridLayout::validate`].
    pub fn new(grid: GridSpec, kernel: Kernel, h: f64) -> Self {
        Self {
            version: Self::VERSION,
            grid,
            order: TensorOrder::Chw,
            kernel,
            h,
            search: NeighbourSearch::Exact,
            g2p: G2pMethod::Sph,
            input_channels: INPUT_CHANNELS.iter().map(|s| s.to_string()).collect(),
            output_channels: OUTPUT_CHANNELS.iter().map(|s| s.to_string()).collect(),
            wall_mass: 100.0,
            wall_band: 0.5 * grid.spacing,
        }
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), GridError> {
        if self.version != Self::VERSION {
            return Err(GridError::UnsupportedVersion {
                got: self.version,
                supported: Self::VERSION,
            });
        }
        self.grid.validate()?;
        self.kernel.validate(self.h)?;
        let check = |which, expected: &[&str], got: &[String]| {
            if got.iter().map(String::as_str).eq(expected.iter().copied()) {
                Ok(())
            } else {
                Err(GridError::ChannelMismatch {
                    which,
                    expected: expected.iter().map(|s| s.to_string()).collect(),
                    got: got.to_vec(),
                })
            }
        };
        check("input", &INPUT_CHANNELS, &self.input_channels)?;
        check("output", &OUTPUT_CHANNELS, &self.output_channels)?;
        if !self.wall_mass.is_finite() {
            return Err(GridError::InvalidSetting {
                name: "wall_mass",
                value: self.wall_mass,
                reason: "must be finite",
            });
        }
        if !(self.wall_band.is_finite() && self.wall_band >= 0.0) {
            return Err(GridError::InvalidSetting {
                name: "wall_band",
                value: self.wall_band,
                reason: "must be finite and >= 0",
            });
        }
        Ok(())
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.grid.len()
    }

    /// Length of an input grid: `6 · nodes`.
    pub fn input_len(&self) -> usize {
        INPUT_CHANNELS.len() * self.nodes()
    }

    /// Length of an output grid: `2 · nodes`.
    pub fn output_len(&self) -> usize {
        OUTPUT_CHANNELS.len() * self.nodes()
    }

    /// Shape of the input tensor for a batch of one: `[1, 6, ny, nx]`.
    pub fn input_shape(&self) -> [usize; 4] {
        [1, INPUT_CHANNELS.len(), self.grid.ny, self.grid.nx]
    }

    /// Shape of the output tensor for a batch of one: `[1, 2, ny, nx]`.
    pub fn output_shape(&self) -> [usize; 4] {
        [1, OUTPUT_CHANNELS.len(), self.grid.ny, self.grid.nx]
    }

    /// A [`Transfer`] configured by this layout (validates it first).
    pub fn transfer(&self) -> Result<Transfer, GridError> {
        self.validate()?;
        Ok(Transfer::new(self.grid, self.kernel, self.h)?
            .with_search(self.search)
            .with_g2p(self.g2p))
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        // Serialising plain data with string keys cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Parses and validates JSON.
    pub fn from_json(text: &str) -> Result<Self, GridError> {
        let layout: Self =
            serde_json::from_str(text).map_err(|e| GridError::Json(e.to_string()))?;
        layout.validate()?;
        Ok(layout)
    }

    /// Reads and validates a layout file.
    pub fn load(path: &Path) -> Result<Self, GridError> {
        let text = std::fs::read_to_string(path).map_err(|e| GridError::Io {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        Self::from_json(&text)
    }

    /// Writes the layout as JSON (to a temporary file renamed into place).
    pub fn save(&self, path: &Path) -> Result<(), GridError> {
        let io = |e: std::io::Error| GridError::Io {
            path: path.display().to_string(),
            reason: e.to_string(),
        };
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".tmp");
        std::fs::write(&tmp, self.to_json() + "\n").map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_json_round_trips_and_matches_the_doc() {
        let l = GridLayout::thesis();
        l.validate().unwrap();
        let v: serde_json::Value = serde_json::from_str(&l.to_json()).unwrap();
        assert_eq!(v["grid"]["nx"], 61);
        assert_eq!(v["kernel"]["kind"], "poly6");
        assert_eq!(v["order"], "chw");
        assert_eq!(v["search"], "exact");
        assert_eq!(v["g2p"], "sph");
        assert_eq!(v["wall_band"], 0.125);
        assert_eq!(v["input_channels"][3], "omega");
        assert_eq!(GridLayout::from_json(&l.to_json()).unwrap(), l);
    }

    #[test]
    fn optional_fields_default() {
        let text = r#"{"version":1,"grid":{"origin":[0,0],"spacing":0.25,"nx":61,"ny":61},"h":0.5,
            "input_channels":["mass","vx","vy","omega","nx","ny"],
            "output_channels":["normal_impulse","tangent_impulse"],"wall_mass":100,"wall_band":0.125}"#;
        assert_eq!(GridLayout::from_json(text).unwrap(), GridLayout::thesis());
    }

    #[test]
    fn bad_layouts_are_rejected() {
        let mut l = GridLayout::thesis();
        l.input_channels.swap(0, 1);
        assert!(matches!(
            l.validate(),
            Err(GridError::ChannelMismatch { which: "input", .. })
        ));
        let mut l = GridLayout::thesis();
        l.version = 2;
        assert!(matches!(
            l.validate(),
            Err(GridError::UnsupportedVersion { got: 2, .. })
        ));
        let mut l = GridLayout::thesis();
        l.h = -1.0;
        assert!(l.transfer().is_err());
        let mut l = GridLayout::thesis();
        l.wall_band = f64::NAN;
        assert!(l.validate().is_err());
        assert!(matches!(
            GridLayout::from_json("{"),
            Err(GridError::Json(_))
        ));
        assert!(GridLayout::load(Path::new("/nonexistent/layout.json")).is_err());
    }

    #[test]
    fn save_and_load() {
        let dir =
            std::env::temp_dir().join(format!("deepcontact-grid-layout-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("layout.json");
        let l = GridLayout::new(
            GridSpec::new([1.0, 2.0], 0.125, 10, 20).unwrap(),
            Kernel::gaussian_for(0.5),
            0.5,
        );
        l.save(&path).unwrap();
        assert_eq!(GridLayout::load(&path).unwrap(), l);
        std::fs::remove_dir_all(&dir).ok();
    }
}
