//! One island's contact problem as NumPy arrays: what a Python provider receives and what
//! `World.step_islands` returns.

use deepcontact_core::{Impulse, ProblemBody, Real, WarmStartContext};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// An owned copy of a [`WarmStartContext`], taken without the GIL and turned into NumPy
/// arrays with it ([`IslandData::into_python`]).
#[derive(Debug, Clone, PartialEq)]
pub struct IslandData {
    step: u64,
    island: usize,
    island_count: usize,
    dt: Real,
    gravity: [Real; 2],
    carried: Vec<Real>,
    persisted: Vec<bool>,
    points: Vec<Real>,
    normals: Vec<Real>,
    body_a: Vec<i64>,
    body_b: Vec<i64>,
    manifold: Vec<i64>,
    friction: Vec<Real>,
    separation: Vec<Real>,
    normal_mass: Vec<Real>,
    tangent_mass: Vec<Real>,
    body_index: Vec<i64>,
    positions: Vec<Real>,
    angles: Vec<Real>,
    velocities: Vec<Real>,
    angular_velocities: Vec<Real>,
    masses: Vec<Real>,
    inv_masses: Vec<Real>,
    inv_inertias: Vec<Real>,
}

impl IslandData {
    /// Copies the context's problem, carried impulses and step data.
    pub fn from_context(ctx: &WarmStartContext<'_>) -> Self {
        let p = ctx.problem;
        let n = p.points.len();
        let mut d = Self {
            step: ctx.step,
            island: ctx.island,
            island_count: ctx.island_count,
            dt: ctx.dt,
            gravity: [ctx.gravity.x, ctx.gravity.y],
            carried: Vec::with_capacity(2 * n),
            persisted: ctx.carried.iter().map(Option::is_some).collect(),
            points: Vec::with_capacity(2 * n),
            normals: Vec::with_capacity(2 * n),
            body_a: Vec::with_capacity(n),
            body_b: Vec::with_capacity(n),
            manifold: Vec::with_capacity(n),
            friction: Vec::with_capacity(n),
            separation: Vec::with_capacity(n),
            normal_mass: Vec::with_capacity(n),
            tangent_mass: Vec::with_capacity(n),
            body_index: Vec::with_capacity(p.bodies.len()),
            positions: Vec::with_capacity(2 * p.bodies.len()),
            angles: Vec::with_capacity(p.bodies.len()),
            velocities: Vec::with_capacity(2 * p.bodies.len()),
            angular_velocities: Vec::with_capacity(p.bodies.len()),
            masses: Vec::with_capacity(p.bodies.len()),
            inv_masses: Vec::with_capacity(p.bodies.len()),
            inv_inertias: Vec::with_capacity(p.bodies.len()),
        };
        for c in ctx.carried_impulses() {
            d.carried.extend([c.normal, c.tangent]);
        }
        for q in &p.points {
            d.points.extend([q.point.x, q.point.y]);
            d.normals.extend([q.normal.x, q.normal.y]);
            d.body_a.push(i64::from(q.body_a));
            d.body_b.push(i64::from(q.body_b));
            d.manifold.push(i64::from(q.manifold));
            d.friction.push(q.friction);
            d.separation.push(q.separation);
            d.normal_mass.push(q.normal_mass);
            d.tangent_mass.push(q.tangent_mass);
        }
        for b in &p.bodies {
            d.body_index
                .push(if b.world_index == ProblemBody::NO_WORLD {
                    -1
                } else {
                    i64::from(b.world_index)
                });
            d.positions.extend([b.position.x, b.position.y]);
            d.angles.push(b.angle);
            d.velocities
                .extend([b.linear_velocity.x, b.linear_velocity.y]);
            d.angular_velocities.push(b.angular_velocity);
            d.masses.push(if b.inv_mass > 0.0 {
                1.0 / b.inv_mass
            } else {
                Real::INFINITY
            });
            d.inv_masses.push(b.inv_mass);
            d.inv_inertias.push(b.inv_inertia);
        }
        d
    }

    /// The arrays as an [`IslandProblem`] (the vectors move into NumPy without a copy).
    pub fn into_python(self, py: Python<'_>) -> PyResult<Bound<'_, IslandProblem>> {
        Bound::new(
            py,
            IslandProblem {
                step: self.step,
                island: self.island,
                island_count: self.island_count,
                dt: self.dt,
                gravity: PyArray1::from_slice(py, &self.gravity).unbind(),
                carried: pairs(py, self.carried),
                persisted: vector(py, self.persisted),
                points: pairs(py, self.points),
                normals: pairs(py, self.normals),
                body_a: vector(py, self.body_a),
                body_b: vector(py, self.body_b),
                manifold: vector(py, self.manifold),
                friction: vector(py, self.friction),
                separation: vector(py, self.separation),
                normal_mass: vector(py, self.normal_mass),
                tangent_mass: vector(py, self.tangent_mass),
                body_index: vector(py, self.body_index),
                positions: pairs(py, self.positions),
                angles: vector(py, self.angles),
                velocities: pairs(py, self.velocities),
                angular_velocities: vector(py, self.angular_velocities),
                masses: vector(py, self.masses),
                inv_masses: vector(py, self.inv_masses),
                inv_inertias: vector(py, self.inv_inertias),
            },
        )
    }
}

/// A 1-D NumPy array owning `v`.
fn vector<T: numpy::Element>(py: Python<'_>, v: Vec<T>) -> Py<PyArray1<T>> {
    v.into_pyarray(py).unbind()
}

/// An `(n, 2)` NumPy array owning the row-major `flat`.
fn pairs(py: Python<'_>, flat: Vec<Real>) -> Py<PyArray2<Real>> {
    pairs_to_python(py, flat).unbind()
}

/// Impulses as an `(n, 2)` array of (normal, tangent) rows.
pub fn impulses_to_python<'py>(
    py: Python<'py>,
    impulses: &[Impulse],
) -> Bound<'py, PyArray2<Real>> {
    pairs_to_python(
        py,
        impulses
            .iter()
            .flat_map(|i| [i.normal, i.tangent])
            .collect(),
    )
}

/// The row-major pairs of `flat` as an `(len / 2, 2)` array (a trailing odd value is dropped).
pub fn pairs_to_python(py: Python<'_>, mut flat: Vec<Real>) -> Bound<'_, PyArray2<Real>> {
    let rows = flat.len() / 2;
    flat.truncate(2 * rows);
    match Array2::from_shape_vec((rows, 2), flat) {
        Ok(array) => array.into_pyarray(py),
        Err(_) => PyArray2::zeros(py, (0, 2), false),
    }
}

/// One island's contact problem, the argument of a Python warm start.
///
/// Per contact point (``n`` rows): ``carried`` (n, 2) the (normal, tangent) impulses carried
/// from the previous step by contact id, zero where ``persisted`` is false; ``points`` and
/// ``normals`` (n, 2), the normal pointing from body A to body B; ``body_a``/``body_b``
/// (indices into the body arrays); ``manifold``; ``friction``; ``separation``;
/// ``normal_mass``/``tangent_mass`` (effective masses). Per body of the island (``m`` rows):
/// ``body_index`` (index in the world, -1 for none), ``positions``, ``angles``, ``velocities``
/// (m, 2) and ``angular_velocities`` before the solve (gravity applied), ``masses`` (``inf``
/// for static bodies), ``inv_masses``, ``inv_inertias``. And ``step``, ``island``,
/// ``island_count``, ``dt``, ``gravity``. Units N·s, m, s, kg. The arrays are fresh copies.
#[pyclass(module = "deepcontact._deepcontact", frozen, get_all)]
#[derive(Debug)]
pub struct IslandProblem {
    /// Index of the step being solved (0 = the world's first).
    pub step: u64,
    /// Index of the island within the step.
    pub island: usize,
    /// Islands in the step.
    pub island_count: usize,
    /// Time step (s).
    pub dt: Real,
    /// Gravity (m/s²), shape (2,).
    pub gravity: Py<PyArray1<Real>>,
    /// Carried (normal, tangent) impulses, (n, 2); zero where not persisted.
    pub carried: Py<PyArray2<Real>>,
    /// Whether the point's contact id existed in the previous step, (n,).
    pub persisted: Py<PyArray1<bool>>,
    /// Contact points (m), (n, 2).
    pub points: Py<PyArray2<Real>>,
    /// Unit normals from body A to body B, (n, 2).
    pub normals: Py<PyArray2<Real>>,
    /// Body A of each point (row of the body arrays), (n,).
    pub body_a: Py<PyArray1<i64>>,
    /// Body B of each point, (n,).
    pub body_b: Py<PyArray1<i64>>,
    /// Manifold (body pair) of each point, (n,).
    pub manifold: Py<PyArray1<i64>>,
    /// Mixed friction coefficient, (n,).
    pub friction: Py<PyArray1<Real>>,
    /// Signed distance, negative = penetration (m), (n,).
    pub separation: Py<PyArray1<Real>>,
    /// Effective mass of the normal row, (n,).
    pub normal_mass: Py<PyArray1<Real>>,
    /// Effective mass of the tangent row, (n,).
    pub tangent_mass: Py<PyArray1<Real>>,
    /// Index of each body in the world (-1 if none), (m,).
    pub body_index: Py<PyArray1<i64>>,
    /// Body centres (m), (m, 2).
    pub positions: Py<PyArray2<Real>>,
    /// Body angles (rad), (m,).
    pub angles: Py<PyArray1<Real>>,
    /// Linear velocities before the solve (m/s), (m, 2).
    pub velocities: Py<PyArray2<Real>>,
    /// Angular velocities before the solve (rad/s), (m,).
    pub angular_velocities: Py<PyArray1<Real>>,
    /// Masses (kg; inf for static bodies), (m,).
    pub masses: Py<PyArray1<Real>>,
    /// Inverse masses (0 for static bodies), (m,).
    pub inv_masses: Py<PyArray1<Real>>,
    /// Inverse moments of inertia, (m,).
    pub inv_inertias: Py<PyArray1<Real>>,
}

#[pymethods]
impl IslandProblem {
    /// Number of contact points.
    fn __len__(&self, py: Python<'_>) -> usize {
        self.persisted.bind(py).len()
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "IslandProblem(step={}, island={}/{}, points={}, bodies={})",
            self.step,
            self.island,
            self.island_count,
            self.persisted.bind(py).len(),
            self.angles.bind(py).len()
        )
    }
}
