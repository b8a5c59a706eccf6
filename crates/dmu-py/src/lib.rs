//! The Python module `dmu`: open a model, pick, move parts and check clashes
//! from Python, with numpy arrays for bulk data.
//!
//! Design choices:
//! - GPU-free: it depends on the scene, store, tree, collision and samples
//!   crates only, never on wgpu, so the wheel is small and builds anywhere.
//!   Files open through [`dmu_store::open_scene`], the same path as the
//!   command line's.
//! - One abi3 wheel (CPython 3.9 and later) built by maturin
//!   (`pip install ./crates/dmu-py`): no per-version builds.
//! - Reports come from the same serde structures as the command line's JSON
//!   ([`dmu_tree::HitReport`], [`dmu_collide::Finding`]), turned into Python by
//!   the standard `json` module, so a dict from `pick` or `collide` has the
//!   fields of `dmu pick --json` or `dmu collide --json` and cannot drift.
//! - Bulk picking (`pick_many`) takes and returns numpy arrays and runs the
//!   ray loop in Rust on rayon's threads; every call that may take long
//!   (opening, picking, moving, replaying, saving) releases the GIL, so Python
//!   threads and Ray actors run alongside.
//! - `collide` replays a record from the model's current poses and puts every
//!   part it moved back afterwards, so records replayed one after another on
//!   one model each give what `dmu collide FILE --record R` gives.
//! - Errors are `dmu.DmuError` (a `ValueError`) carrying the one-line message
//!   of the command line, naming the file and the element at fault.
//! - A model is shared by Python threads: it is a frozen class whose state
//!   sits behind a read-write lock, so picks run side by side and a move or
//!   a replay waits for them (two threads got `RuntimeError: Already
//!   borrowed` from PyO3's borrow flag). The lock is taken only with the GIL
//!   released, and nothing takes the GIL while holding it, so neither can
//!   wait for the other.
//!
//! Conventions: world coordinates are f64 model units (millimetres for the
//! built-in plant); a pose is a 4×4 matrix acting on column vectors
//! (translation in the last column, last row `0 0 0 1`); parts are named by
//! name, full path, `#id`, or their integer id.
//!
//! ```python
//! import dmu
//! m = dmu.plant(triangles=100_000)
//! hit = m.pick((4_512_000.0, 5_341_000.0, 20_000.0), (1.0, 1.0, 0.0))
//! ids, distances, points = m.pick_many(origins, directions)  # (N, 3) arrays
//! clashes = m.collide("moves.jsonl", clearance=5.0, continuous=True)
//! ```

use std::path::PathBuf;
use std::sync::{PoisonError, RwLock};

use dmu_collide::{
    AllowList, Checker, Settings, Step, SweepMode, parse_record, read_record, replay,
};
use dmu_geom::Ray3d;
use dmu_scene::limits::{MAX_CHUNK_TRIANGLES, MAX_LENGTH, MAX_TRIANGLES, MIN_PLANT_TRIANGLES};
use dmu_scene::{ImportOptions, PartId, Scene};
use dmu_store::cad::CadOptions;
use dmu_tree::{HitReport, Tree, TreeOptions};
use glam::{DAffine3, DMat3, DVec3};
use numpy::{AllowTypeChange, IntoPyArray as _, PyArray1, PyArray2, PyArray3, PyArrayLike2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyByteArray, PyBytes, PyDict, PyList, PyString};

create_exception!(
    dmu,
    DmuError,
    PyValueError,
    "A dmu error: unreadable or malformed input, an unknown part, a bad argument. \
     The message names the file and the element at fault."
);

/// The Python exception for any error, with the chain of causes on one line.
fn dmu_error(e: impl Into<anyhow::Error>) -> PyErr {
    DmuError::new_err(format!("{:#}", e.into()))
}

/// Plant sizes accepted, as on the command line (`--plant-triangles`).
const PLANT_TRIANGLES: std::ops::RangeInclusive<u64> = MIN_PLANT_TRIANGLES..=MAX_TRIANGLES;

/// A model in memory, shared by Python threads (see the crate's design
/// choices): its state behind a read-write lock.
#[pyclass(module = "dmu", frozen)]
struct Model {
    state: RwLock<State>,
    /// The file it was opened from (`None` for the built-in plant).
    source: Option<PathBuf>,
}

/// A model's scene, its cell tree, and the collision checker's caches
/// (built on the first `collide`).
struct State {
    scene: Scene,
    tree: Tree,
    checker: Option<Checker>,
}

/// A key naming a part, read from Python before the model's lock is taken.
enum PartKey {
    Id(i64),
    Name(String),
}

impl PartKey {
    fn extract(key: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(id) = key.extract::<i64>() {
            return Ok(Self::Id(id));
        }
        key.extract()
            .map(Self::Name)
            .map_err(|_| DmuError::new_err("part: give a name, a path, \"#id\" or an int id"))
    }

    /// The part: an integer id, a name, a full path or `#id`.
    fn resolve(&self, scene: &Scene) -> PyResult<PartId> {
        match self {
            Self::Id(id) => {
                let count = scene.parts().len();
                match u32::try_from(*id) {
                    Ok(i) if (i as usize) < count => Ok(PartId(i)),
                    _ => Err(DmuError::new_err(format!(
                        "part {id}: no such part id (the model has {count} parts)"
                    ))),
                }
            }
            Self::Name(name) => scene.find_part(name).map_err(dmu_error),
        }
    }
}

impl Model {
    fn new(scene: Scene, source: Option<PathBuf>) -> Self {
        let tree = Tree::build(&scene, TreeOptions::default());
        Self {
            state: RwLock::new(State {
                scene,
                tree,
                checker: None,
            }),
            source,
        }
    }

    /// `f` on the state to read, run without the GIL (so the lock is waited
    /// for, and held, only while Python runs on). A call that panicked while
    /// holding the lock (a bug) left nothing half-written that a reader
    /// trusts, so a poisoned lock is taken as it is.
    fn reading<T: Send>(&self, py: Python<'_>, f: impl FnOnce(&State) -> T + Send) -> T {
        py.detach(|| f(&self.state.read().unwrap_or_else(PoisonError::into_inner)))
    }

    /// `f` on the state to change, run without the GIL.
    fn writing<T: Send>(&self, py: Python<'_>, f: impl FnOnce(&mut State) -> T + Send) -> T {
        py.detach(|| f(&mut self.state.write().unwrap_or_else(PoisonError::into_inner)))
    }
}

/// Reads a ray, scaling its direction safely (as `dmu pick --ray` does).
fn ray(what: impl std::fmt::Display, origin: [f64; 3], direction: [f64; 3]) -> PyResult<Ray3d> {
    Ray3d::with_safe_dir(DVec3::from(origin), DVec3::from(direction)).ok_or_else(|| {
        DmuError::new_err(format!(
            "{what}: origin and direction must be finite and the direction non-zero"
        ))
    })
}

/// An `(N, 3)` array as rows, or an error naming the argument and the shape.
fn rows3(name: &str, array: &PyArrayLike2<'_, f64, AllowTypeChange>) -> PyResult<Vec<[f64; 3]>> {
    let view = array.as_array();
    if view.ncols() != 3 {
        return Err(DmuError::new_err(format!(
            "{name}: expected an array of shape (N, 3), got {:?}",
            view.shape()
        )));
    }
    Ok(view
        .rows()
        .into_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

/// Serialized reports into Python objects through the `json` module.
fn from_json<'py>(py: Python<'py>, json: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (json,))
}

#[pymethods]
impl Model {
    /// Every part as a dict: `id`, `name`, `path`, `triangles`, `hidden`,
    /// and `properties` (a dict of what the source file says of the part:
    /// an IFC element's `GlobalId` and `IfcClass`, a STEP product's
    /// `StepProduct`, a glTF node's `extras`).
    fn parts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        type Row = (String, String, u64, bool, Vec<(String, String)>);
        let parts: Vec<Row> = self.reading(py, |st| {
            let scene = &st.scene;
            scene
                .parts()
                .iter()
                .enumerate()
                .map(|(i, part)| {
                    let id = PartId(i as u32);
                    (
                        scene.part_name(id).to_owned(),
                        scene.part_path(id),
                        scene.mesh(part.mesh).triangle_count(),
                        part.hidden,
                        scene
                            .node_properties(part.node)
                            .map(|(k, v)| (k.to_owned(), v.to_owned()))
                            .collect(),
                    )
                })
                .collect()
        });
        let list = PyList::empty(py);
        for (i, (name, path, triangles, hidden, properties)) in parts.into_iter().enumerate() {
            let d = PyDict::new(py);
            d.set_item("id", i)?;
            d.set_item("name", name)?;
            d.set_item("path", path)?;
            d.set_item("triangles", triangles)?;
            d.set_item("hidden", hidden)?;
            let p = PyDict::new(py);
            for (k, v) in properties {
                p.set_item(k, v)?;
            }
            d.set_item("properties", p)?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// The nearest part along the world ray `origin + t * direction`, as a dict
    /// with the fields of `dmu pick --json` (`part`, `part_id`, `path`,
    /// `triangle`, `distance` in world units whatever the direction's length,
    /// `point`, `normal`, `properties`), or `None` when the ray hits nothing.
    fn pick<'py>(
        &self,
        py: Python<'py>,
        origin: [f64; 3],
        direction: [f64; 3],
    ) -> PyResult<Option<Bound<'py, PyAny>>> {
        let ray = ray("pick", origin, direction)?;
        let report = self.reading(py, |st| {
            st.tree.pick(&st.scene, &ray).map(|hit| {
                serde_json::to_string(&HitReport::new(&st.scene, &hit, ray.dir.length()))
                    .expect("a hit report serializes")
            })
        });
        report.map(|json| from_json(py, &json)).transpose()
    }

    /// Picks N rays at once: `origins` and `directions` are `(N, 3)` arrays.
    /// Returns `(part_ids, distances, points)`: int64 `(N,)` (-1 for a miss),
    /// float64 `(N,)` in world units (inf for a miss) and float64 `(N, 3)`
    /// (NaN for a miss). The loop runs in Rust, in parallel, without the GIL.
    #[expect(
        clippy::type_complexity,
        reason = "a tuple of three arrays is the Python API"
    )]
    fn pick_many<'py>(
        &self,
        py: Python<'py>,
        origins: PyArrayLike2<'py, f64, AllowTypeChange>,
        directions: PyArrayLike2<'py, f64, AllowTypeChange>,
    ) -> PyResult<(
        Bound<'py, PyArray1<i64>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray2<f64>>,
    )> {
        let origins = rows3("origins", &origins)?;
        let directions = rows3("directions", &directions)?;
        if origins.len() != directions.len() {
            return Err(DmuError::new_err(format!(
                "pick_many: {} origins but {} directions",
                origins.len(),
                directions.len()
            )));
        }
        let rays = origins
            .iter()
            .zip(&directions)
            .enumerate()
            .map(|(i, (&o, &d))| ray(format_args!("ray {i}"), o, d))
            .collect::<PyResult<Vec<_>>>()?;
        let hits = self.reading(py, |st| st.tree.pick_many(&st.scene, &rays));
        let n = hits.len();
        let mut ids = Vec::with_capacity(n);
        let mut distances = Vec::with_capacity(n);
        let mut points = Vec::with_capacity(3 * n);
        for (hit, ray) in hits.iter().zip(&rays) {
            match hit {
                Some(h) => {
                    ids.push(i64::from(h.part.0));
                    distances.push(h.t * ray.dir.length());
                    points.extend_from_slice(&h.point.to_array());
                }
                None => {
                    ids.push(-1);
                    distances.push(f64::INFINITY);
                    points.extend_from_slice(&[f64::NAN; 3]);
                }
            }
        }
        let points = numpy::ndarray::Array2::from_shape_vec((n, 3), points)
            .expect("three coordinates per ray");
        Ok((
            ids.into_pyarray(py),
            distances.into_pyarray(py),
            points.into_pyarray(py),
        ))
    }

    /// The part's world pose, a 4×4 float64 array.
    fn world<'py>(
        &self,
        py: Python<'py>,
        part: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let key = PartKey::extract(part)?;
        let world = self.reading(py, |st| {
            key.resolve(&st.scene).map(|id| st.scene.part_world(id))
        })?;
        let m = glam::DMat4::from(world).transpose().to_cols_array();
        Ok(numpy::ndarray::Array2::from_shape_vec((4, 4), m.to_vec())
            .expect("sixteen numbers")
            .into_pyarray(py))
    }

    /// Moves a part (name, path, `#id` or int id) to the absolute world pose
    /// `matrix` (4×4, last row `0 0 0 1`), updating the cell tree.
    #[pyo3(name = "move")]
    fn move_part(
        &self,
        py: Python<'_>,
        part: &Bound<'_, PyAny>,
        matrix: PyArrayLike2<'_, f64, AllowTypeChange>,
    ) -> PyResult<()> {
        let key = PartKey::extract(part)?;
        let m = matrix.as_array();
        let shape = m.shape().to_vec();
        let affine =
            shape == [4, 4] && [m[[3, 0]], m[[3, 1]], m[[3, 2]], m[[3, 3]]] == [0.0, 0.0, 0.0, 1.0];
        let col = |c: usize| DVec3::new(m[[0, c]], m[[1, c]], m[[2, c]]);
        let world = affine.then(|| DAffine3 {
            matrix3: DMat3::from_cols(col(0), col(1), col(2)),
            translation: col(3),
        });
        self.writing(py, |st| {
            let id = key.resolve(&st.scene)?;
            let name = st.scene.part_name(id);
            if shape != [4, 4] {
                return Err(DmuError::new_err(format!(
                    "move {name}: expected a 4x4 matrix, got shape {shape:?}"
                )));
            }
            let Some(world) = world else {
                return Err(DmuError::new_err(format!(
                    "move {name}: the matrix's last row must be 0 0 0 1 (an affine pose)"
                )));
            };
            if !st.scene.is_valid_world(id, &world) {
                return Err(DmuError::new_err(format!(
                    "move {name}: the pose is not finite or reaches beyond ±{:e} model units",
                    dmu_scene::MAX_WORLD_COORDINATE
                )));
            }
            let State { scene, tree, .. } = st;
            tree.move_part(scene, id, world);
            Ok(())
        })
    }

    /// Replays a record of part poses and returns its clashes and impacts as
    /// dicts with the fields of `dmu collide --json` (`step`, `t`, `kind`,
    /// `a`, `b`, `a_id`, `b_id`, `distance`, `toi`, `point`, `normal`).
    ///
    /// `record` is a path to a JSON Lines record (docs/record-format.md) or a
    /// list of its lines as dicts (`t`, `part`, `translation`, `rotation`).
    /// `clearance` (model units) reports closer pairs as `soft`; `continuous`
    /// sweeps each move (without it no move is swept, as `dmu collide
    /// --discrete`); `allow` lists pairs of parts that may touch. Every part
    /// the record moved is put back afterwards.
    #[pyo3(signature = (record, clearance = 5.0, continuous = false, allow = Vec::new()))]
    fn collide<'py>(
        &self,
        py: Python<'py>,
        record: &Bound<'py, PyAny>,
        clearance: f64,
        continuous: bool,
        allow: Vec<(Bound<'py, PyAny>, Bound<'py, PyAny>)>,
    ) -> PyResult<Bound<'py, PyAny>> {
        if !(0.0..=MAX_LENGTH).contains(&clearance) {
            return Err(DmuError::new_err(format!(
                "clearance {}: expected a number from 0 to {MAX_LENGTH:e}",
                dmu_geom::Short(clearance)
            )));
        }
        let allow = allow
            .iter()
            .map(|(a, b)| Ok((PartKey::extract(a)?, PartKey::extract(b)?)))
            .collect::<PyResult<Vec<_>>>()?;
        let record = RecordSource::extract(py, record)?;
        let findings = self.writing(py, |st| {
            let mut list = AllowList::default();
            for (a, b) in &allow {
                let (a, b) = (a.resolve(&st.scene)?, b.resolve(&st.scene)?);
                if a == b {
                    return Err(DmuError::new_err(format!(
                        "allow: names {} twice (a part never clashes with itself)",
                        st.scene.part_name(a)
                    )));
                }
                list.allow(a, b);
            }
            let settings = Settings {
                clearance,
                allow: list,
                ..Settings::default()
            };
            let steps = record.steps(&st.scene)?;
            let State {
                scene,
                tree,
                checker,
            } = st;
            let checker = checker.get_or_insert_with(|| Checker::new(scene));
            let mut before: Vec<(PartId, DAffine3)> = Vec::new();
            for m in steps.iter().flat_map(|s| &s.moves) {
                if !before.iter().any(|(p, _)| *p == m.part) {
                    before.push((m.part, scene.part_world(m.part)));
                }
            }
            // Python keeps its explicit choice: swept with continuous=True only.
            let sweep = if continuous {
                SweepMode::Always
            } else {
                SweepMode::Off
            };
            let mut findings = Vec::new();
            replay(scene, tree, checker, &steps, &settings, sweep, |o| {
                findings.extend(
                    o.findings()
                        .map(|f| serde_json::to_value(f).expect("a finding serializes")),
                );
            });
            for (part, world) in before {
                tree.move_part(scene, part, world);
            }
            Ok(serde_json::to_string(&findings).expect("findings serialize"))
        })?;
        from_json(py, &findings)
    }

    /// Writes the model: a `.dmu` store, or `.glb`/`.gltf` (temporary file,
    /// synced, renamed into place). Saving onto the store it was opened from
    /// writes the edits only.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let source = self.source.as_deref();
        self.writing(py, |st| dmu_store::save_scene(&mut st.scene, source, &path))
            .map(|_| ())
            .map_err(dmu_error)
    }

    /// Every triangle of the visible parts in world coordinates, for other
    /// tools (a reference ray tracer, a mesh library): `(triangles, part_ids)`,
    /// float64 `(N, 3, 3)` (triangle, corner, coordinate) and int64 `(N,)`.
    /// Instances are expanded, so N is `triangles` less the hidden parts'.
    fn world_triangles<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray3<f64>>, Bound<'py, PyArray1<i64>>) {
        let (corners, ids) = self.reading(py, |st| {
            let scene = &st.scene;
            let visible = || scene.part_ids().filter(|&p| !scene.part(p).hidden);
            let count: u64 = visible().map(|p| scene.part_mesh(p).triangle_count()).sum();
            let count =
                usize::try_from(count).expect("a model in memory counts its triangles in usize");
            let mut corners = Vec::with_capacity(9 * count);
            let mut ids = Vec::with_capacity(count);
            for part in visible() {
                let world = scene.part_world(part);
                let mesh = scene.part(part).mesh;
                for chunk in scene.mesh(mesh).chunk_ids() {
                    for t in scene.chunk(chunk).triangles.clone() {
                        for v in scene.triangle_local(mesh, chunk, t) {
                            corners.extend(world.transform_point3(v.as_dvec3()).to_array());
                        }
                        ids.push(i64::from(part.0));
                    }
                }
            }
            (corners, ids)
        });
        let corners = numpy::ndarray::Array3::from_shape_vec((ids.len(), 3, 3), corners)
            .expect("nine coordinates per triangle");
        (corners.into_pyarray(py), ids.into_pyarray(py))
    }

    /// Triangles, instances counted.
    #[getter]
    fn triangles(&self, py: Python<'_>) -> u64 {
        self.reading(py, |st| st.scene.triangle_count())
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.reading(py, |st| st.scene.parts().len())
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let source = self
            .source
            .as_ref()
            .map_or_else(|| "built-in plant".to_owned(), |p| p.display().to_string());
        let (parts, triangles) =
            self.reading(py, |st| (st.scene.parts().len(), st.scene.triangle_count()));
        format!("<dmu.Model {source}: {parts} parts, {triangles} triangles>")
    }
}

/// A record as `collide` was given it, read from Python before the model's
/// lock is taken: a path, or the lines of a list of dicts.
enum RecordSource {
    Path(PathBuf),
    Lines(String),
}

impl RecordSource {
    fn extract(py: Python<'_>, record: &Bound<'_, PyAny>) -> PyResult<Self> {
        // Bytes iterate as integers, which read as record lines of numbers.
        if record.is_instance_of::<PyBytes>() || record.is_instance_of::<PyByteArray>() {
            return Err(DmuError::new_err(
                "record: give a path (str or os.PathLike) or a list of line dicts, not bytes \
                 (decode them, or write them to a file)",
            ));
        }
        if record.is_instance_of::<PyString>() || record.hasattr("__fspath__")? {
            return Ok(Self::Path(record.extract()?));
        }
        if record.is_instance_of::<PyDict>() {
            return Err(DmuError::new_err(
                "record: give a list of line dicts, not one dict",
            ));
        }
        let dumps = py.import("json")?.getattr("dumps")?;
        let mut text = String::new();
        for (i, line) in record.try_iter()?.enumerate() {
            let json: String = dumps
                .call1((line?,))
                .and_then(|s| s.extract())
                .map_err(|e| DmuError::new_err(format!("steps[{i}]: {e}")))?;
            text.push_str(&json);
            text.push('\n');
        }
        Ok(Self::Lines(text))
    }

    /// The record's steps, parts found in `scene`.
    fn steps(&self, scene: &Scene) -> PyResult<Vec<Step>> {
        match self {
            Self::Path(path) => read_record(path, scene).map_err(|e| {
                dmu_error(anyhow::Error::from(e).context(format!("record {}", path.display())))
            }),
            Self::Lines(text) => parse_record(text, scene)
                .map_err(|e| dmu_error(anyhow::Error::from(e).context("steps"))),
        }
    }
}

/// Refuses chunk sizes the command line refuses.
fn check_chunk_triangles(chunk_triangles: u32) -> PyResult<()> {
    if (1..=MAX_CHUNK_TRIANGLES).contains(&chunk_triangles) {
        Ok(())
    } else {
        Err(DmuError::new_err(format!(
            "chunk_triangles {chunk_triangles}: expected 1 to {MAX_CHUNK_TRIANGLES}"
        )))
    }
}

/// Opens a model file: a `.dmu` store, `.glb`/`.gltf`, or STEP (`.step`,
/// `.stp`) or IFC (`.ifc`) through OpenCascade and IfcOpenShell run by this
/// interpreter (`pip install 'dmu[cad]'`), chunked into
/// `chunk_triangles`-triangle chunks (a store keeps its own). STEP is
/// tessellated within `deflection` of each part's size and
/// `angular_deflection` radians; `ifc_include` keeps IFC classes left out
/// by default (`IfcSpace`, `IfcOpeningElement`).
#[pyfunction]
#[pyo3(signature = (path, chunk_triangles = dmu_scene::DEFAULT_CHUNK_TRIANGLES, deflection = CadOptions::default().deflection, angular_deflection = CadOptions::default().angular_deflection, ifc_include = Vec::new()))]
fn open(
    py: Python<'_>,
    path: PathBuf,
    chunk_triangles: u32,
    deflection: f64,
    angular_deflection: f64,
    ifc_include: Vec<String>,
) -> PyResult<Model> {
    check_chunk_triangles(chunk_triangles)?;
    let python: PathBuf = py
        .import("sys")?
        .getattr("executable")?
        .extract::<String>()?
        .into();
    let cad = CadOptions {
        deflection,
        angular_deflection,
        ifc_include,
        python: (!python.as_os_str().is_empty()).then_some(python),
        ..Default::default()
    };
    cad.check().map_err(DmuError::new_err)?;
    py.detach(|| {
        let options = ImportOptions {
            chunk_triangles,
            progress: None,
        };
        let (scene, _) = dmu_store::open_scene(&path, &options, &cad)?;
        Ok(Model::new(scene, Some(path)))
    })
    .map_err(|e: dmu_store::StoreError| dmu_error(e))
}

/// The built-in procedural plant (deterministic by `seed`), as `dmu` uses
/// when given no file.
#[pyfunction]
#[pyo3(signature = (triangles = 100_000, seed = 1, chunk_triangles = dmu_scene::DEFAULT_CHUNK_TRIANGLES))]
fn plant(py: Python<'_>, triangles: u64, seed: u64, chunk_triangles: u32) -> PyResult<Model> {
    if !PLANT_TRIANGLES.contains(&triangles) {
        return Err(DmuError::new_err(format!(
            "triangles {triangles}: expected {} to {}",
            PLANT_TRIANGLES.start(),
            PLANT_TRIANGLES.end()
        )));
    }
    check_chunk_triangles(chunk_triangles)?;
    let options = dmu_samples::PlantOptions {
        triangles,
        seed,
        chunk_triangles,
        ..Default::default()
    };
    Ok(py.detach(|| Model::new(dmu_samples::plant(&options), None)))
}

#[pymodule]
#[pyo3(name = "dmu")]
fn dmu_py(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("DmuError", m.py().get_type::<DmuError>())?;
    m.add_class::<Model>()?;
    m.add_function(wrap_pyfunction!(open, m)?)?;
    m.add_function(wrap_pyfunction!(plant, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
