//! Far fields of a store's viewpoint cells: choosing each cell's cull box,
//! building and storing them (`dmu farfield build`), and loading them as a
//! walk approaches (a loader thread, the eye's cell first, then its
//! neighbours).
//!
//! The cells are a grid of cubes over the model's bounds; a cell's cull box is
//! a cube around its centre, as large as the triangle budget allows (found by
//! bisection on the triangles of the chunk instances touching it, as MMR chose
//! its near field), never smaller than the cell. The index (JSON) names the
//! built cells with their boxes, sizes and build times, and a signature of
//! the model's transforms and visibility: far fields made from other poses
//! are refused, not drawn wrong.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};

use anyhow::{Context as _, bail};
use dmu_geom::Aabb3d;
use dmu_render::{FarField, FarFieldOptions};
use dmu_scene::Scene;
use dmu_store::Store;
use dmu_tree::Tree;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// One built cell in the index.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct IndexCell {
    /// Grid coordinates.
    pub grid: [i64; 3],
    /// Far-field cell segment in the store.
    pub segment: u32,
    /// The cull box: min and max corners.
    pub near_box: [[f64; 3]; 2],
    /// Triangles of the chunk instances touching the cull box.
    pub near_triangles: u64,
    /// Depth-mesh triangles.
    pub far_triangles: u64,
    /// Encoded bytes.
    pub bytes: u64,
    /// Capture and meshing time, ms.
    pub build_ms: f64,
}

/// The far-field index of a store.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FarFieldIndex {
    /// Grid origin (the model's bounds' minimum corner).
    pub origin: [f64; 3],
    /// Cell edge, model units.
    pub cell_size: f64,
    /// Triangle budget of a cull box.
    pub triangle_budget: u64,
    /// Pixels per face side.
    pub resolution: u32,
    /// The depth meshes' simplification bound, pixels.
    pub mesh_error_px: f64,
    /// Signature of the model's part transforms and visibility they show.
    pub model_signature: u64,
    /// Built cells.
    pub cells: Vec<IndexCell>,
}

impl FarFieldIndex {
    /// The grid coordinates of the cell holding `p`.
    pub fn grid_of(&self, p: DVec3) -> [i64; 3] {
        let g = ((p - DVec3::from_array(self.origin)) / self.cell_size).floor();
        [g.x as i64, g.y as i64, g.z as i64]
    }

    /// The box of the cell at grid coordinates `g`.
    pub fn cell_box(&self, g: [i64; 3]) -> Aabb3d {
        let min = DVec3::from_array(self.origin)
            + DVec3::new(g[0] as f64, g[1] as f64, g[2] as f64) * self.cell_size;
        Aabb3d::new(min, min + DVec3::splat(self.cell_size))
    }

    /// Reads the index's bytes, checking them.
    pub fn decode(bytes: &[u8]) -> anyhow::Result<Self> {
        let index: Self = serde_json::from_slice(bytes).context("the far-field index")?;
        let finite = index.origin.iter().all(|x| x.is_finite())
            && index.cell_size.is_finite()
            && index.cell_size > 0.0;
        if !finite {
            bail!("the far-field index: origin or cell size is not a finite positive number");
        }
        for (i, c) in index.cells.iter().enumerate() {
            if c.segment as usize != i || !c.near_box.iter().flatten().all(|x| x.is_finite()) {
                bail!(
                    "the far-field index: cell {i} names segment {} or has a box that is not finite",
                    c.segment
                );
            }
        }
        Ok(index)
    }
}

/// A signature of every part's world transform and visibility.
pub fn model_signature(scene: &Scene) -> u64 {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    for p in scene.part_ids() {
        h.update(bytemuck::cast_slice(&scene.part_world(p).to_cols_array()));
        h.update(&[u8::from(scene.part(p).hidden)]);
    }
    h.digest()
}

/// Triangles of the chunk instances touching `b`.
pub fn triangles_touching(tree: &Tree, b: &Aabb3d) -> u64 {
    let mut ids = Vec::new();
    tree.entries_in_box(b, &mut ids);
    ids.iter()
        .map(|e| u64::from(tree.entries()[e.0 as usize].triangles))
        .sum()
}

/// The cull box of `cell`: the largest cube around its centre whose chunk
/// instances hold at most `budget` triangles (bisection, 12 steps), never
/// smaller than the cell.
pub fn cull_box(tree: &Tree, cell: &Aabb3d, budget: u64) -> Aabb3d {
    let c = cell.center();
    let cube = |h: f64| Aabb3d::new(c - DVec3::splat(h), c + DVec3::splat(h));
    let mut lo = cell.extent().max_element() * 0.5;
    let mut hi = tree.bounds().extent().max_element().max(lo);
    if triangles_touching(tree, &cube(hi)) <= budget {
        return cube(hi);
    }
    for _ in 0..12 {
        let mid = 0.5 * (lo + hi);
        if triangles_touching(tree, &cube(mid)) <= budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    cube(lo)
}

/// The far fields of a store, loaded as the eye approaches them.
#[derive(Debug)]
pub struct FarFieldSet {
    index: FarFieldIndex,
    by_grid: HashMap<[i64; 3], u32>,
    loaded: Arc<Mutex<BTreeMap<u32, Arc<FarField>>>>,
    requests: Sender<u32>,
    errors: Receiver<String>,
    requested: BTreeSet<u32>,
    /// Far fields kept in memory at most.
    capacity: usize,
}

impl FarFieldSet {
    /// The far fields of `store` (`None` when it has none), for a model of
    /// `scene`'s poses: an index made from other poses is an error.
    pub fn open(store: &Arc<Store>, scene: &Scene) -> anyhow::Result<Option<Self>> {
        let Some(bytes) = store.far_field_index()? else {
            return Ok(None);
        };
        let index =
            FarFieldIndex::decode(&bytes).with_context(|| format!("{}", store.path().display()))?;
        if index.model_signature != model_signature(scene) {
            bail!(
                "{}: its far fields were made from other part poses; build them again with `dmu farfield build`",
                store.path().display()
            );
        }
        let by_grid = index.cells.iter().map(|c| (c.grid, c.segment)).collect();
        let loaded = Arc::new(Mutex::new(BTreeMap::new()));
        let (requests, queue) = channel::<u32>();
        let (report, errors) = channel();
        let parts = scene.parts().len();
        let (store, into) = (store.clone(), loaded.clone());
        std::thread::Builder::new()
            .name("far-field loader".into())
            .spawn(move || {
                for cell in queue {
                    let result = store
                        .far_field_cell(cell)
                        .map_err(|e| e.to_string())
                        .and_then(|bytes| FarField::decode(&bytes, parts));
                    match result {
                        Ok(field) => {
                            into.lock().expect("loader").insert(cell, Arc::new(field));
                        }
                        Err(e) => {
                            let _ = report.send(format!(
                                "{}: far-field cell #{cell}: {e}",
                                store.path().display()
                            ));
                        }
                    }
                }
            })
            .context("starting the far-field loader")?;
        Ok(Some(Self {
            index,
            by_grid,
            loaded,
            requests,
            errors,
            requested: BTreeSet::new(),
            capacity: 27 + 9,
        }))
    }

    /// The index.
    pub fn index(&self) -> &FarFieldIndex {
        &self.index
    }

    /// Asks for the far field of the eye's cell and its 26 neighbours (the
    /// eye's first), drops the loaded ones farthest away past the capacity,
    /// and gives the eye's cell's far field if loaded and serving the eye.
    pub fn for_eye(&mut self, eye: DVec3) -> anyhow::Result<Option<Arc<FarField>>> {
        if let Ok(e) = self.errors.try_recv() {
            bail!(e);
        }
        let g = self.index.grid_of(eye);
        let mut wanted = Vec::new();
        for d in 0..27i64 {
            let n = [g[0] + d % 3 - 1, g[1] + d / 3 % 3 - 1, g[2] + d / 9 - 1];
            if let Some(&cell) = self.by_grid.get(&n) {
                let dist = (n[0] - g[0]).abs() + (n[1] - g[1]).abs() + (n[2] - g[2]).abs();
                wanted.push((dist, cell));
            }
        }
        wanted.sort_unstable();
        for &(_, cell) in &wanted {
            if self.requested.insert(cell) {
                let _ = self.requests.send(cell);
            }
        }
        let mut loaded = self.loaded.lock().expect("loader");
        if loaded.len() > self.capacity {
            let keep: BTreeSet<u32> = wanted.iter().map(|w| w.1).collect();
            let drop: Vec<u32> = loaded
                .keys()
                .copied()
                .filter(|c| !keep.contains(c))
                .collect();
            for c in drop.into_iter().take(loaded.len() - self.capacity) {
                loaded.remove(&c);
                self.requested.remove(&c);
            }
        }
        Ok(self
            .by_grid
            .get(&g)
            .and_then(|c| loaded.get(c).cloned())
            .filter(|f| f.serves(eye)))
    }

    /// Waits until the eye's cell's far field is loaded (none there: at once).
    pub fn wait_for(&mut self, eye: DVec3) -> anyhow::Result<Option<Arc<FarField>>> {
        let Some(&cell) = self.by_grid.get(&self.index.grid_of(eye)) else {
            return Ok(None);
        };
        loop {
            let field = self.for_eye(eye)?;
            if field.is_some() || !self.requested.contains(&cell) {
                return Ok(field);
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
    }
}

/// What to build: the cell size, the cull boxes' triangle budget and the
/// captures' options.
#[derive(Clone, Copy, Debug)]
pub struct BuildOptions {
    /// Cell edge, model units.
    pub cell_size: f64,
    /// Triangles of a cull box at most.
    pub triangle_budget: u64,
    /// Capture options.
    pub capture: FarFieldOptions,
}

/// The grid cells holding any of `points` (deduplicated, in first-seen
/// order), for an index of `cell_size` over `tree`'s bounds.
pub fn cells_along(
    tree: &Tree,
    cell_size: f64,
    points: impl Iterator<Item = DVec3>,
) -> Vec<[i64; 3]> {
    let index = grid(tree, cell_size);
    let mut seen = BTreeSet::new();
    points
        .map(|p| index.grid_of(p))
        .filter(|g| seen.insert(*g))
        .collect()
}

/// Every cell of the grid over `tree`'s bounds.
pub fn all_cells(tree: &Tree, cell_size: f64) -> Vec<[i64; 3]> {
    let n = (tree.bounds().extent() / cell_size).ceil();
    let mut cells = Vec::new();
    for z in 0..n.z.max(1.0) as i64 {
        for y in 0..n.y.max(1.0) as i64 {
            for x in 0..n.x.max(1.0) as i64 {
                cells.push([x, y, z]);
            }
        }
    }
    cells
}

fn grid(tree: &Tree, cell_size: f64) -> FarFieldIndex {
    FarFieldIndex {
        origin: tree.bounds().min.to_array(),
        cell_size,
        triangle_budget: 0,
        resolution: 0,
        mesh_error_px: 0.0,
        model_signature: 0,
        cells: Vec::new(),
    }
}

/// Builds the far fields of `cells` and writes them into the store at
/// `path` (replacing any it had; temp file, fsync, rename), calling
/// `progress` after each cell. Returns the index.
#[expect(
    clippy::too_many_arguments,
    reason = "the model, the GPU, the cells and the options, passed through once"
)]
pub fn build(
    store: &Store,
    scene: &Scene,
    tree: &Tree,
    renderer: &mut dmu_render::Renderer,
    cells: &[[i64; 3]],
    options: &BuildOptions,
    progress: &mut dyn FnMut(&IndexCell),
) -> anyhow::Result<FarFieldIndex> {
    let mut index = grid(tree, options.cell_size);
    index.triangle_budget = options.triangle_budget;
    index.resolution = options.capture.resolution;
    index.mesh_error_px = options.capture.mesh_error_px;
    index.model_signature = model_signature(scene);
    let mut encoded = Vec::with_capacity(cells.len());
    for &g in cells {
        let cell = index.cell_box(g);
        let near_box = cull_box(tree, &cell, options.triangle_budget);
        let (field, build) = renderer.capture_far_field(
            scene,
            tree,
            scene,
            cell,
            near_box,
            &BTreeSet::new(),
            &options.capture,
        )?;
        let bytes = field.encode();
        let entry = IndexCell {
            grid: g,
            segment: index.cells.len() as u32,
            near_box: [near_box.min.to_array(), near_box.max.to_array()],
            near_triangles: triangles_touching(tree, &near_box),
            far_triangles: build.triangles,
            bytes: bytes.len() as u64,
            build_ms: field.build_ms,
        };
        progress(&entry);
        index.cells.push(entry);
        encoded.push(bytes);
    }
    let index_bytes = serde_json::to_vec(&index)?;
    dmu_store::write_far_fields::<dmu_store::StoreError>(
        store,
        &index_bytes,
        encoded.into_iter().map(|b| Ok(Some(b))),
    )?
    .commit()?;
    Ok(index)
}
