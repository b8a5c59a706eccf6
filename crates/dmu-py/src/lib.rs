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

use dmu_collide::{
    AllowList, Checker, Settings, Step, SweepMode, parse_record, read_record, replay,
};
use dmu_geom::Ray3d;
use dmu_scene::limits::{MAX_CHUNK_TRIANGLES, MAX_LENGTH, MAX_TRIANGLES, MIN_PLANT_TRIANGLES};
use dmu_scene::{ImportOptions, PartId, Scene};
use dmu_tree::{HitReport, Tree, TreeOptions};
use glam::{DAffine3, DMat3, DVec3};
use numpy::{AllowTypeChange, IntoPyArray as _, PyArray1, PyArray2, PyArrayLike2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use rayon::prelude::*;

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

/// A model in memory: its scene, its cell tree, and the collision checker's
/// caches (built on the first `collide`).
#[pyclass(module = "dmu")]
struct Model {
    scene: Scene,
    tree: Tree,
    checker: Option<Checker>,
    /// The file it was opened from (`None` for the built-in plant).
    source: Option<PathBuf>,
}

impl Model {
    fn new(scene: Scene, source: Option<PathBuf>) -> Self {
        let tree = Tree::build(&scene, TreeOptions::default());
        Self {
            scene,
            tree,
            checker: None,
            source,
        }
    }

    /// A part named by its integer id, name, full path or `#id`.
    fn part(&self, key: &Bound<'_, PyAny>) -> PyResult<PartId> {
        if let Ok(id) = key.extract::<i64>() {
            let count = self.scene.parts().len();
            return match u32::try_from(id) {
                Ok(i) if (i as usize) < count => Ok(PartId(i)),
                _ => Err(DmuError::new_err(format!(
                    "part {id}: no such part id (the model has {count} parts)"
                ))),
            };
        }
        let name: String = key
            .extract()
            .map_err(|_| DmuError::new_err("part: give a name, a path, \"#id\" or an int id"))?;
        self.scene.find_part(&name).map_err(dmu_error)
    }
}

/// Reads a ray, scaling its direction safely (as `dmu pick --ray` does).
fn ray(what: &str, origin: [f64; 3], direction: [f64; 3]) -> PyResult<Ray3d> {
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
    /// Every part as a dict: `id`, `name`, `path`, `triangles`, `hidden`.
    fn parts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let scene = &self.scene;
        let list = PyList::empty(py);
        for (i, part) in scene.parts().iter().enumerate() {
            let id = PartId(i as u32);
            let d = PyDict::new(py);
            d.set_item("id", id.0)?;
            d.set_item("name", scene.part_name(id))?;
            d.set_item("path", scene.part_path(id))?;
            d.set_item("triangles", scene.mesh(part.mesh).triangle_count())?;
            d.set_item("hidden", part.hidden)?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// The nearest part along the world ray `origin + t * direction`, as a dict
    /// with the fields of `dmu pick --json` (`part`, `part_id`, `path`,
    /// `triangle`, `distance` in world units whatever the direction's length,
    /// `point`, `normal`), or `None` when the ray hits nothing.
    fn pick<'py>(
        &self,
        py: Python<'py>,
        origin: [f64; 3],
        direction: [f64; 3],
    ) -> PyResult<Option<Bound<'py, PyAny>>> {
        let ray = ray("pick", origin, direction)?;
        let (scene, tree) = (&self.scene, &self.tree);
        let report = py.detach(|| {
            tree.pick(scene, &ray).map(|hit| {
                serde_json::to_string(&HitReport::new(scene, &hit, ray.dir.length()))
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
            .map(|(i, (&o, &d))| ray(&format!("ray {i}"), o, d))
            .collect::<PyResult<Vec<_>>>()?;
        let (scene, tree) = (&self.scene, &self.tree);
        let hits: Vec<_> = py.detach(|| {
            rays.par_iter()
                .map(|ray| tree.pick(scene, ray).map(|h| (h, ray.dir.length())))
                .collect()
        });
        let n = hits.len();
        let mut ids = Vec::with_capacity(n);
        let mut distances = Vec::with_capacity(n);
        let mut points = Vec::with_capacity(3 * n);
        for hit in &hits {
            match hit {
                Some((h, length)) => {
                    ids.push(i64::from(h.part.0));
                    distances.push(h.t * length);
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
        let world = self.scene.part_world(self.part(part)?);
        let m = glam::DMat4::from(world).transpose().to_cols_array();
        Ok(numpy::ndarray::Array2::from_shape_vec((4, 4), m.to_vec())
            .expect("sixteen numbers")
            .into_pyarray(py))
    }

    /// Moves a part (name, path, `#id` or int id) to the absolute world pose
    /// `matrix` (4×4, last row `0 0 0 1`), updating the cell tree.
    #[pyo3(name = "move")]
    fn move_part(
        &mut self,
        py: Python<'_>,
        part: &Bound<'_, PyAny>,
        matrix: PyArrayLike2<'_, f64, AllowTypeChange>,
    ) -> PyResult<()> {
        let id = self.part(part)?;
        let m = matrix.as_array();
        if m.shape() != [4, 4] {
            return Err(DmuError::new_err(format!(
                "move {}: expected a 4x4 matrix, got shape {:?}",
                self.scene.part_name(id),
                m.shape()
            )));
        }
        if [m[[3, 0]], m[[3, 1]], m[[3, 2]], m[[3, 3]]] != [0.0, 0.0, 0.0, 1.0] {
            return Err(DmuError::new_err(format!(
                "move {}: the matrix's last row must be 0 0 0 1 (an affine pose)",
                self.scene.part_name(id)
            )));
        }
        let col = |c: usize| DVec3::new(m[[0, c]], m[[1, c]], m[[2, c]]);
        let world = DAffine3 {
            matrix3: DMat3::from_cols(col(0), col(1), col(2)),
            translation: col(3),
        };
        if !self.scene.is_valid_world(id, &world) {
            return Err(DmuError::new_err(format!(
                "move {}: the pose is not finite or reaches beyond ±{:e} model units",
                self.scene.part_name(id),
                dmu_scene::MAX_WORLD_COORDINATE
            )));
        }
        let (scene, tree) = (&mut self.scene, &mut self.tree);
        py.detach(|| tree.move_part(scene, id, world));
        Ok(())
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
        &mut self,
        py: Python<'py>,
        record: &Bound<'py, PyAny>,
        clearance: f64,
        continuous: bool,
        allow: Vec<(Bound<'py, PyAny>, Bound<'py, PyAny>)>,
    ) -> PyResult<Bound<'py, PyAny>> {
        if !(0.0..=MAX_LENGTH).contains(&clearance) {
            return Err(DmuError::new_err(format!(
                "clearance {clearance}: expected a number from 0 to {MAX_LENGTH:e}"
            )));
        }
        let mut list = AllowList::default();
        for (a, b) in &allow {
            let (a, b) = (self.part(a)?, self.part(b)?);
            if a == b {
                return Err(DmuError::new_err(format!(
                    "allow: names {} twice (a part never clashes with itself)",
                    self.scene.part_name(a)
                )));
            }
            list.allow(a, b);
        }
        let settings = Settings {
            clearance,
            allow: list,
            ..Settings::default()
        };
        let steps = self.steps(py, record)?;
        let Self {
            scene,
            tree,
            checker,
            ..
        } = self;
        let findings = py.detach(|| {
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
            serde_json::to_string(&findings).expect("findings serialize")
        });
        from_json(py, &findings)
    }

    /// Writes the model: a `.dmu` store, or `.glb`/`.gltf` (temporary file,
    /// synced, renamed into place). Saving onto the store it was opened from
    /// writes the edits only.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let (scene, source) = (&self.scene, self.source.as_deref());
        py.detach(|| dmu_store::save_scene(scene, source, &path))
            .map(|_| ())
            .map_err(dmu_error)
    }

    /// Triangles, instances counted.
    #[getter]
    fn triangles(&self) -> u64 {
        self.scene.triangle_count()
    }

    fn __len__(&self) -> usize {
        self.scene.parts().len()
    }

    fn __repr__(&self) -> String {
        let source = self
            .source
            .as_ref()
            .map_or_else(|| "built-in plant".to_owned(), |p| p.display().to_string());
        format!(
            "<dmu.Model {source}: {} parts, {} triangles>",
            self.scene.parts().len(),
            self.scene.triangle_count()
        )
    }
}

impl Model {
    /// A record's steps from a path or from a list of line dicts.
    fn steps(&self, py: Python<'_>, record: &Bound<'_, PyAny>) -> PyResult<Vec<Step>> {
        if record.is_instance_of::<PyString>() || record.hasattr("__fspath__")? {
            let path: PathBuf = record.extract()?;
            let scene = &self.scene;
            return py.detach(|| read_record(&path, scene)).map_err(|e| {
                dmu_error(anyhow::Error::from(e).context(format!("record {}", path.display())))
            });
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
        parse_record(&text, &self.scene)
            .map_err(|e| dmu_error(anyhow::Error::from(e).context("steps")))
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

/// Opens a model file: a `.dmu` store, or `.glb`/`.gltf` (chunked into
/// `chunk_triangles`-triangle chunks; a store keeps its own).
#[pyfunction]
#[pyo3(signature = (path, chunk_triangles = dmu_scene::DEFAULT_CHUNK_TRIANGLES))]
fn open(py: Python<'_>, path: PathBuf, chunk_triangles: u32) -> PyResult<Model> {
    check_chunk_triangles(chunk_triangles)?;
    py.detach(|| {
        let options = ImportOptions {
            chunk_triangles,
            progress: None,
        };
        let (scene, _) = dmu_store::open_scene(&path, &options)?;
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
