//! The `grid` warm start: any provider's impulses, passed through particles → grid →
//! particles. With the `copy` oracle inside it is the thesis's "grid" oracle: the best a
//! CNN that predicts impulse grids could do, given the transfer's losses.

use deepcontact_core::registry::{Params, ProviderInfo, Registry, SpecError};
use deepcontact_core::{
    Impulse, Observation, Real, Vector, WarmStart, WarmStartContext, WarmStartError,
};

use crate::error::GridError;
use crate::kernel::Kernel;
use crate::spec::GridSpec;
use crate::transfer::{G2pMethod, NeighbourSearch, Transfer};
use crate::walls::StaticBoundsCache;

/// Settings of [`GridFiltered`]. Defaults are the thesis's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridFilterConfig {
    /// Node spacing in metres (spec `res=`, default 0.25).
    pub spacing: f64,
    /// Kernel support radius in metres (spec `h=`, default 0.5).
    pub h: f64,
    /// Kernel (spec `kernel=poly6|spiky|gaussian`, `sigma=` for the Gaussian,
    /// default poly6; the Gaussian's default σ is `h / 3`).
    pub kernel: Kernel,
    /// Grid → particles method (spec `transfer=sph|bilinear`, default sph).
    pub g2p: G2pMethod,
    /// Neighbour search (spec `search=exact|kdtree`, default exact; same results).
    pub search: NeighbourSearch,
}

impl Default for GridFilterConfig {
    fn default() -> Self {
        Self {
            spacing: 0.25,
            h: 0.5,
            kernel: Kernel::Poly6,
            g2p: G2pMethod::Sph,
            search: NeighbourSearch::Exact,
        }
    }
}

impl GridFilterConfig {
    /// Checks spacing, `h` and the kernel.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(self.spacing.is_finite() && self.spacing > 0.0) {
            return Err(GridError::InvalidSpacing {
                spacing: self.spacing,
            });
        }
        self.kernel.validate(self.h)
    }

    /// Reads `res`, `h`, `kernel`, `sigma`, `transfer` and `search` from a registry spec.
    pub fn from_params(p: &mut Params<'_>) -> Result<Self, SpecError> {
        let d = Self::default();
        let spacing = p.f64("res", d.spacing)?;
        let h = p.f64("h", d.h)?;
        let invalid = |param: &str, value: &str, reason: String| SpecError::InvalidParameter {
            spec: "grid".into(),
            param: param.into(),
            value: value.into(),
            reason,
        };
        let mut kernel = match p.string("kernel") {
            None => d.kernel,
            Some(v) => v
                .parse::<Kernel>()
                .map_err(|e| invalid("kernel", v, e.to_string()))?,
        };
        if let Kernel::Gaussian { sigma } = &mut kernel {
            *sigma = h / 3.0;
        }
        if let Some(v) = p.string("sigma") {
            let s: f64 = v
                .parse()
                .map_err(|e: std::num::ParseFloatError| invalid("sigma", v, e.to_string()))?;
            match &mut kernel {
                Kernel::Gaussian { sigma } => *sigma = s,
                _ => {
                    return Err(invalid(
                        "sigma",
                        v,
                        "only the gaussian kernel takes sigma".into(),
                    ));
                }
            }
        }
        let g2p = match p.string("transfer") {
            None => d.g2p,
            Some(v) => v
                .parse()
                .map_err(|e: GridError| invalid("transfer", v, e.to_string()))?,
        };
        let search = match p.string("search") {
            None => d.search,
            Some(v) => v
                .parse()
                .map_err(|e: GridError| invalid("search", v, e.to_string()))?,
        };
        let config = Self {
            spacing,
            h,
            kernel,
            g2p,
            search,
        };
        config.validate().map_err(|e| {
            let (param, value) = match e {
                GridError::InvalidSpacing { .. } => ("res", spacing),
                GridError::InvalidSupport { .. } => ("h", h),
                _ => (
                    "sigma",
                    if let Kernel::Gaussian { sigma } = kernel {
                        sigma
                    } else {
                        f64::NAN
                    },
                ),
            };
            invalid(param, &value.to_string(), e.to_string())
        })?;
        Ok(config)
    }

    /// `grid`, followed by the settings that differ from the defaults in spec syntax.
    pub fn name(&self) -> String {
        let d = Self::default();
        let mut parts = Vec::new();
        if self.spacing != d.spacing {
            parts.push(format!("res={}", self.spacing));
        }
        if self.h != d.h {
            parts.push(format!("h={}", self.h));
        }
        match self.kernel {
            Kernel::Poly6 => {}
            Kernel::Spiky => parts.push("kernel=spiky".into()),
            Kernel::Gaussian { sigma } => {
                parts.push("kernel=gaussian".into());
                if sigma != self.h / 3.0 {
                    parts.push(format!("sigma={sigma}"));
                }
            }
        }
        if self.g2p == G2pMethod::Bilinear {
            parts.push("transfer=bilinear".into());
        }
        if self.search == NeighbourSearch::KdTree {
            parts.push("search=kdtree".into());
        }
        if parts.is_empty() {
            "grid".into()
        } else {
            format!("grid:{}", parts.join(","))
        }
    }
}

/// Wraps a provider and filters its impulses through a grid: its (normal, tangent)
/// impulses are spread from the contact points onto the grid (particles → grid, weights
/// normalised per point) and brought back onto the same points (SPH weights normalised
/// per node, or bilinear); the result is the warm start. Composes with any provider.
///
/// Only the island's own points take part, so an island's impulses never leak into
/// another island's warm start. The grid: for a world with static bodies it covers their
/// bounds (the pile's box `[0, side]²`, the thesis grid at the default settings),
/// extended by whole nodes where a contact point lies more than half a spacing outside;
/// without a world (or without static bodies) it covers the problem's body positions and
/// contact points, anchored at their lower-left corner. Buffers are reused: no allocation
/// per step once warmed up (exact search; the k-d tree search allocates).
///
/// ```
/// use deepcontact_core::{CarriedWarmStart, WarmStart};
/// use deepcontact_grid::{GridFilterConfig, GridFiltered};
///
/// let provider = GridFiltered::new(Box::new(CarriedWarmStart), GridFilterConfig::default()).unwrap();
/// assert_eq!(provider.name(), "grid");
/// ```
pub struct GridFiltered {
    inner: Box<dyn WarmStart>,
    config: GridFilterConfig,
    name: String,
    transfer: Transfer,
    bounds: StaticBoundsCache,
    positions: Vec<Vector>,
    values: Vec<f64>,
    back: Vec<f64>,
}

impl std::fmt::Debug for GridFiltered {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GridFiltered")
            .field("inner", &self.inner.name())
            .field("config", &self.config)
            .field("transfer", &self.transfer)
            .finish_non_exhaustive()
    }
}

impl GridFiltered {
    /// Wraps `inner` with validated settings; the name is [`GridFilterConfig::name`].
    pub fn new(inner: Box<dyn WarmStart>, config: GridFilterConfig) -> Result<Self, GridError> {
        config.validate()?;
        // A placeholder grid; each call moves the transfer to the island's grid.
        let spec = GridSpec::new([0.0, 0.0], config.spacing, 1, 1)?;
        let transfer = Transfer::new(spec, config.kernel, config.h)?
            .with_search(config.search)
            .with_g2p(config.g2p);
        Ok(Self {
            inner,
            name: config.name(),
            config,
            transfer,
            bounds: StaticBoundsCache::new(),
            positions: Vec::new(),
            values: Vec::new(),
            back: Vec::new(),
        })
    }

    /// Replaces the name used in reports.
    pub fn with_name(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }

    /// The settings.
    pub fn config(&self) -> &GridFilterConfig {
        &self.config
    }

    /// The wrapped provider.
    pub fn inner(&self) -> &dyn WarmStart {
        self.inner.as_ref()
    }

    /// The grid used by the last call.
    pub fn last_grid(&self) -> &GridSpec {
        self.transfer.spec()
    }

    /// The grid for this call (see the type's documentation).
    fn grid_for(&mut self, ctx: &WarmStartContext<'_>) -> Result<GridSpec, GridError> {
        let s = self.config.spacing;
        let problem = ctx.problem;
        let mut pmin = Vector::repeat(f64::INFINITY);
        let mut pmax = Vector::repeat(f64::NEG_INFINITY);
        for p in &problem.points {
            pmin = pmin.inf(&p.point);
            pmax = pmax.sup(&p.point);
        }
        let statics = ctx.world.and_then(|w| self.bounds.bounds(w.bodies()));
        match statics {
            Some((lo, hi)) => {
                // Whole nodes added below / above where points lie beyond half a spacing.
                let below = |l: f64, p: f64| ((l - p) / s - 0.5).ceil().max(0.0);
                let origin = Vector::new(
                    lo.x - s * below(lo.x, pmin.x),
                    lo.y - s * below(lo.y, pmin.y),
                );
                let top = |h: f64, p: f64, o: f64| {
                    let a = ((h - o) / s - 1e-9).ceil();
                    let b = ((p - o) / s - 0.5).ceil();
                    o + s * a.max(b).max(0.0)
                };
                let max = Vector::new(top(hi.x, pmax.x, origin.x), top(hi.y, pmax.y, origin.y));
                GridSpec::covering(origin, max, s)
            }
            None => {
                for b in &problem.bodies {
                    pmin = pmin.inf(&b.position);
                    pmax = pmax.sup(&b.position);
                }
                if !(pmin.x <= pmax.x && pmin.y <= pmax.y) {
                    // Nothing to place: any grid will do.
                    return GridSpec::new([0.0, 0.0], s, 1, 1);
                }
                GridSpec::covering(pmin, pmax, s)
            }
        }
    }

    fn filter(&mut self, ctx: &WarmStartContext<'_>, out: &mut [Impulse]) -> Result<(), GridError> {
        let spec = self.grid_for(ctx)?;
        self.transfer.set_spec(spec)?;
        self.positions.clear();
        self.positions
            .extend(ctx.problem.points.iter().map(|p| p.point));
        self.values.clear();
        self.values
            .extend(out.iter().flat_map(|i| [i.normal, i.tangent]));
        self.back.clear();
        self.back.resize(self.values.len(), 0.0);
        self.transfer
            .round_trip(&self.positions, &self.values, 2, &mut self.back)?;
        for (o, v) in out.iter_mut().zip(self.back.chunks_exact(2)) {
            // SPH and bilinear weights are non-negative, so non-negative normals stay so;
            // the clamp only guards against an inner provider's negative values.
            *o = Impulse::new(v[0].max(0.0), v[1]);
        }
        Ok(())
    }
}

impl WarmStart for GridFiltered {
    fn name(&self) -> &str {
        &self.name
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.inner.warm_start(ctx, out)?;
        if out.len() != ctx.problem.points.len() {
            return Err(WarmStartError::WrongLength {
                expected: ctx.problem.points.len(),
                got: out.len(),
            });
        }
        if let Some((point, imp)) = out.iter().enumerate().find(|(_, i)| !i.is_finite()) {
            return Err(WarmStartError::NonFinite {
                point,
                normal: imp.normal,
                tangent: imp.tangent,
            });
        }
        self.filter(ctx, out)
            .map_err(|e| WarmStartError::Provider(format!("{}: {e}", self.name)))
    }

    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.inner.observe(ctx, seen);
    }
    fn reset(&mut self) {
        self.inner.reset();
    }
    fn diagnostics(&self) -> Vec<(String, Real)> {
        self.inner.diagnostics()
    }
    /// The inner provider's passes (the filter itself sweeps no rows): under a budget they
    /// come out of the solver's share.
    fn passes_spent(&self) -> u32 {
        self.inner.passes_spent()
    }
}

/// Registers the `grid` provider: `registry.build_provider("copy")` (or `inner=NAME`)
/// filtered through a grid. Parameters: `res` (spacing, default 0.25), `h` (default 0.5),
/// `kernel` (poly6 | spiky | gaussian, default poly6), `sigma` (Gaussian σ, default
/// h / 3), `transfer` (sph | bilinear, default sph), `search` (exact | kdtree, default
/// exact), `inner` (a provider name without parameters, default copy).
///
/// ```
/// let mut registry = deepcontact_core::Registry::empty();
/// deepcontact_pgs::register(&mut registry);
/// deepcontact_warmstart::register(&mut registry);
/// deepcontact_grid::register(&mut registry);
/// let p = registry.build_provider("grid:inner=builtin,res=0.125").unwrap();
/// assert_eq!(p.name(), "grid:res=0.125,inner=builtin");
/// assert!(registry.build_provider("grid:h=-1,inner=builtin").is_err());
/// assert!(registry.build_provider("grid:inner=builtin,bogus=1").is_err());
/// ```
pub fn register(registry: &mut Registry) {
    registry.register_provider(
        "grid",
        ProviderInfo::new(
            "copy -> particles-to-grid -> grid-to-particles (thesis grid oracle); res=0.25, h=0.5, \
             kernel=poly6|spiky|gaussian, sigma=h/3, transfer=sph|bilinear, search=exact|kdtree, inner=copy",
        )
        .oracle(),
        |p, reg| {
            let config = GridFilterConfig::from_params(p)?;
            let inner_spec = p.string("inner").unwrap_or("copy");
            let inner = reg.build_provider(inner_spec)?;
            let mut provider = GridFiltered::new(inner, config)
                .map_err(|e| SpecError::Build { spec: "grid".into(), reason: e.to_string() })?;
            if inner_spec != "copy" {
                let name = config.name();
                let sep = if name.contains(':') { ',' } else { ':' };
                provider = provider.with_name(&format!("{name}{sep}inner={inner_spec}"));
            }
            Ok(Box::new(provider))
        },
    );
}
