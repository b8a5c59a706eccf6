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
//!
//! Where they are drawn is the caller's choice ([`FarUse`]): always where
//! the eye's cell has one, or where they pay ([`FarAuto`] times frames with
//! and without). A caller that moves parts captures the far fields that went
//! stale again and hands them to [`FarFieldSet::replace`] (in memory only:
//! the store keeps the far fields of the poses it was built from).

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};

use anyhow::{Context as _, bail};
use dmu_geom::{Aabb3d, Short};
use dmu_render::{FarField, FarFieldOptions, FarFieldRegion};
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
    /// Pixels between depth-mesh grid vertices.
    #[serde(default = "default_grid_step")]
    pub grid_step: u32,
    /// Skins kept across depth discontinuities.
    #[serde(default = "default_skins")]
    pub skins: bool,
    /// Signature of the model's part transforms and visibility they show.
    pub model_signature: u64,
    /// Built cells.
    pub cells: Vec<IndexCell>,
}

fn default_grid_step() -> u32 {
    FarFieldOptions::default().grid_step
}

fn default_skins() -> bool {
    FarFieldOptions::default().skins
}

impl FarFieldIndex {
    /// The capture options its far fields were made with (to capture one
    /// again alike).
    pub fn capture_options(&self) -> FarFieldOptions {
        FarFieldOptions {
            resolution: self.resolution,
            grid_step: self.grid_step,
            mesh_error_px: self.mesh_error_px,
            skins: self.skins,
            ..FarFieldOptions::default()
        }
    }

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
        // Captured again with these (after moves), so checked here.
        if !dmu_render::FAR_FIELD_RESOLUTIONS.contains(&index.resolution) {
            bail!(
                "the far-field index: resolution {} is not within {:?}",
                index.resolution,
                dmu_render::FAR_FIELD_RESOLUTIONS
            );
        }
        if !(index.mesh_error_px.is_finite() && index.mesh_error_px >= 0.0) {
            bail!(
                "the far-field index: mesh error {} px is not a finite number of pixels",
                index.mesh_error_px
            );
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
        if index.model_signature != scene.pose_hash() {
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
                        .and_then(|bytes| {
                            FarField::decode(&bytes, parts).map_err(|e| e.to_string())
                        });
                    match result {
                        Ok(field) => {
                            // A far field captured again while this one
                            // loaded ([`FarFieldSet::replace`]) is newer.
                            into.lock()
                                .expect("loader")
                                .entry(cell)
                                .or_insert_with(|| Arc::new(field));
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

    /// Whether the index has a far field for the cell holding `eye` (loaded
    /// or not).
    pub fn has_cell_at(&self, eye: DVec3) -> bool {
        self.by_grid.contains_key(&self.index.grid_of(eye))
    }

    /// The far fields in memory now (loaded or replaced), by cell segment.
    pub fn loaded(&self) -> Vec<(u32, Arc<FarField>)> {
        let loaded = self.loaded.lock().expect("loader");
        loaded.iter().map(|(&c, f)| (c, f.clone())).collect()
    }

    /// Puts `field` (captured again, e.g. after parts moved) in place of the
    /// in-memory far field of the index cell whose box is `field.cell`, and
    /// returns that cell's segment; `None` (nothing replaced) when no built
    /// cell has that box. Memory only: the store is not written, so a
    /// replaced far field dropped past the capacity loads again as stored
    /// (stale for the moved parts, which the caller then captures again).
    pub fn replace(&mut self, field: Arc<FarField>) -> Option<u32> {
        let g = self.index.grid_of(field.cell.center());
        let &cell = self.by_grid.get(&g)?;
        if self.index.cell_box(g) != field.cell {
            return None;
        }
        // Requested, so that `for_eye` never asks the loader for it again
        // while it is in memory (the loader would not overwrite it anyway).
        self.requested.insert(cell);
        self.loaded.lock().expect("loader").insert(cell, field);
        Some(cell)
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

/// Where far fields are drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FarUse {
    /// Not drawn.
    #[default]
    Off,
    /// Drawn wherever the eye's cell has one loaded.
    On,
    /// Drawn where they pay: [`FarAuto`] times frames with and without.
    Auto,
}

impl FarUse {
    /// The names on the command line.
    pub const NAMES: [&'static str; 3] = ["off", "on", "auto"];

    /// From its name on the command line (`off`, `on`, `auto`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "off" => Some(Self::Off),
            "on" => Some(Self::On),
            "auto" => Some(Self::Auto),
            _ => None,
        }
    }

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Off => "off",
            Self::On => "on",
            Self::Auto => "auto",
        }
    }
}

/// Frames between two probes of [`FarAuto`].
pub const FAR_AUTO_PROBE_EVERY: u64 = 60;

/// `--far-field auto`: every [`FAR_AUTO_PROBE_EVERY`] frames, two frames
/// without the far field and two with it are timed (each pair after one
/// frame not timed, which takes the switch's uploads), and the faster way
/// (by their means) is kept until the next probe.
///
/// ```
/// use dmu_app::farfield::FarAuto;
///
/// let mut auto = FarAuto::default();
/// for frame in 0..6 {
///     let with_far = auto.next_frame();
///     // Frames with the far field take 5 ms here, without 20 ms.
///     auto.after(if with_far { 5.0 } else { 20.0 }, frame);
/// }
/// assert!(auto.uses_far());
/// assert_eq!(auto.last(), Some((20.0, 5.0)));
/// assert!(auto.next_frame()); // kept until the next probe
/// ```
#[derive(Clone, Debug, Default)]
pub struct FarAuto {
    frame: u64,
    off_ms: Vec<f64>,
    on_ms: Vec<f64>,
    use_far: bool,
    /// The last probe's means, ms (without, with).
    last: Option<(f64, f64)>,
    changes: Vec<String>,
}

impl FarAuto {
    /// Whether this frame draws the far field (call once a frame, then
    /// [`FarAuto::after`] with its time).
    pub fn next_frame(&mut self) -> bool {
        let k = self.frame % FAR_AUTO_PROBE_EVERY;
        self.frame += 1;
        match k {
            0..=2 => false,
            3..=5 => true,
            _ => self.use_far,
        }
    }

    /// The time of the frame [`FarAuto::next_frame`] was last asked about, ms;
    /// `frame` numbers it in the change lines.
    pub fn after(&mut self, ms: f64, frame: usize) {
        let Some(k) = self.frame.checked_sub(1) else {
            return;
        };
        match k % FAR_AUTO_PROBE_EVERY {
            1 | 2 => self.off_ms.push(ms),
            4 | 5 => {
                self.on_ms.push(ms);
                if self.on_ms.len() == 2 {
                    let mean = |v: &mut Vec<f64>| {
                        let m = v.iter().sum::<f64>() / v.len() as f64;
                        v.clear();
                        m
                    };
                    let (off, on) = (mean(&mut self.off_ms), mean(&mut self.on_ms));
                    let use_far = on < off;
                    if use_far != self.use_far || self.last.is_none() {
                        self.changes.push(format!(
                            "frame {frame}: far field {} ({on:.1} ms a frame with it, {off:.1} ms without)",
                            if use_far { "on" } else { "off" }
                        ));
                    }
                    self.use_far = use_far;
                    self.last = Some((off, on));
                }
            }
            _ => {}
        }
    }

    /// Whether the last probe chose the far field (false before the first).
    pub fn uses_far(&self) -> bool {
        self.use_far
    }

    /// The last probe's mean frame times, ms: (without, with).
    pub fn last(&self) -> Option<(f64, f64)> {
        self.last
    }

    /// Each probe that changed the choice (and the first), `frame N: ...`.
    pub fn changes(&self) -> &[String] {
        &self.changes
    }

    /// The choice now, in one sentence (the viewer's "Why").
    pub fn now(&self) -> String {
        match self.last {
            None => format!(
                "far field auto: measuring (frames with and without it are timed every {FAR_AUTO_PROBE_EVERY} frames)"
            ),
            Some((off, on)) => format!(
                "far field {} by auto: a frame took {on:.1} ms with it, {off:.1} ms without (timed again every {FAR_AUTO_PROBE_EVERY} frames)",
                if self.use_far { "on" } else { "off" }
            ),
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

/// Bytes a cell's far field is taken to hold while a build keeps it (every
/// encoded far field is held until the store is written): an eighth of a
/// byte per face pixel, below the 247-267 kB measured at 512 px faces
/// (docs/measurements.md, "Far fields"), so the cap errs towards allowing.
pub fn far_field_bytes_estimate(resolution: u32) -> u64 {
    (6 * u64::from(resolution).pow(2) / 8).max(4096)
}

/// Most cells a build may list with `memory_bytes` to hold their far fields
/// of `resolution` pixels a face ([`far_field_bytes_estimate`]).
pub fn max_cells(memory_bytes: u64, resolution: u32) -> u64 {
    (memory_bytes / far_field_bytes_estimate(resolution)).max(1)
}

/// Every cell of the grid over `tree`'s bounds; refused, before anything is
/// listed, when there are more than `max_cells` of them ([`max_cells`]): a
/// `--cell-size` of 1e-9 listed cells until 7.5 GB were used.
pub fn all_cells(tree: &Tree, cell_size: f64, max_cells: u64) -> anyhow::Result<Vec<[i64; 3]>> {
    let n = (tree.bounds().extent() / cell_size).ceil().max(DVec3::ONE);
    // In f64, which neither overflows nor wraps (n is finite: cell_size > 0).
    let count = n.x * n.y * n.z;
    anyhow::ensure!(
        count <= max_cells as f64,
        "cells {} wide give {} far fields ({} x {} x {}), more than the {max_cells} the memory there is holds while they are built; give a larger cell size (at least {})",
        Short(cell_size),
        Short(count),
        Short(n.x),
        Short(n.y),
        Short(n.z),
        Short(cell_size * (count / max_cells as f64).cbrt() * (1.0 + 1e-6))
    );
    let mut cells = Vec::with_capacity(count as usize);
    for z in 0..n.z as i64 {
        for y in 0..n.y as i64 {
            for x in 0..n.x as i64 {
                cells.push([x, y, z]);
            }
        }
    }
    Ok(cells)
}

/// The box of the cell at grid coordinates `g` (as [`cells_along`] and
/// [`all_cells`] give them) of the grid of `cell_size` over `tree`'s bounds.
pub fn cell_box(tree: &Tree, cell_size: f64, g: [i64; 3]) -> Aabb3d {
    grid(tree, cell_size).cell_box(g)
}

fn grid(tree: &Tree, cell_size: f64) -> FarFieldIndex {
    FarFieldIndex {
        origin: tree.bounds().min.to_array(),
        cell_size,
        triangle_budget: 0,
        resolution: 0,
        mesh_error_px: 0.0,
        grid_step: 0,
        skins: true,
        model_signature: 0,
        cells: Vec::new(),
    }
}

/// The index of a build with `options` of `scene` (whose tree is `tree`),
/// with no cell yet.
pub fn new_index(scene: &Scene, tree: &Tree, options: &BuildOptions) -> FarFieldIndex {
    let mut index = grid(tree, options.cell_size);
    index.triangle_budget = options.triangle_budget;
    index.resolution = options.capture.resolution;
    index.mesh_error_px = options.capture.mesh_error_px;
    index.grid_step = options.capture.grid_step;
    index.skins = options.capture.skins;
    index.model_signature = scene.pose_hash();
    index
}

/// Builds the far field of the cell at grid coordinates `g` of `index`:
/// its entry (as segment `segment`) and its bytes. The bytes depend on the
/// model and the options alone (the build time is in the entry), so a cell
/// built on any machine is the same cell.
pub fn build_cell(
    scene: &Scene,
    tree: &Tree,
    renderer: &mut dmu_render::Renderer,
    index: &FarFieldIndex,
    g: [i64; 3],
    segment: u32,
    options: &BuildOptions,
) -> anyhow::Result<(IndexCell, Vec<u8>)> {
    let cell = index.cell_box(g);
    let near_box = cull_box(tree, &cell, options.triangle_budget);
    let (mut field, build) = renderer.capture_far_field(
        scene,
        tree,
        scene,
        FarFieldRegion {
            cell,
            near_box,
            excluded: &BTreeSet::new(),
        },
        &options.capture,
    )?;
    let build_ms = std::mem::take(&mut field.build_ms);
    let bytes = field.encode();
    let entry = IndexCell {
        grid: g,
        segment,
        near_box: [near_box.min.to_array(), near_box.max.to_array()],
        near_triangles: triangles_touching(tree, &near_box),
        far_triangles: build.triangles,
        bytes: bytes.len() as u64,
        build_ms,
    };
    Ok((entry, bytes))
}

/// Writes `index` and its cells' bytes (`blobs`, in the index's order) into
/// `store`, replacing any far fields it had (temp file, fsync, rename; on
/// object storage, a put conditional on the version read).
pub fn write(
    store: &Store,
    index: &FarFieldIndex,
    blobs: impl IntoIterator<Item = anyhow::Result<Vec<u8>>>,
) -> anyhow::Result<()> {
    let index_bytes = serde_json::to_vec(index)?;
    dmu_store::write_far_fields(store, &index_bytes, blobs.into_iter().map(|b| b.map(Some)))?
        .commit()?;
    Ok(())
}

/// Builds the far fields of `cells` and writes them into `store` (replacing
/// any it had), calling `progress` after each cell. Returns the index.
pub fn build(
    store: &Store,
    scene: &Scene,
    tree: &Tree,
    renderer: &mut dmu_render::Renderer,
    cells: &[[i64; 3]],
    options: &BuildOptions,
    progress: &mut dyn FnMut(&IndexCell),
) -> anyhow::Result<FarFieldIndex> {
    let mut index = new_index(scene, tree, options);
    let mut encoded = Vec::with_capacity(cells.len());
    for (segment, &g) in (0u32..).zip(cells) {
        let (entry, bytes) = build_cell(scene, tree, renderer, &index, g, segment, options)?;
        progress(&entry);
        index.cells.push(entry);
        encoded.push(bytes);
    }
    write(store, &index, encoded.into_iter().map(Ok))?;
    Ok(index)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 48: `dmu farfield build --cell-size 1e-9` listed every grid
    /// cell with no cap (7.5 GB in 15 s). The count is now checked in f64
    /// before anything is listed, against the cells whose far fields fit.
    #[test]
    fn issue_48_the_grid_is_capped_before_it_is_listed() {
        let scene = dmu_samples::grid(2, 10.0, 4.0, 64);
        let tree = Tree::build(&scene, Default::default());
        let extent = tree.bounds().extent();
        let cells = all_cells(&tree, extent.max_element() / 2.0, 1_000).unwrap();
        let n = (extent / (extent.max_element() / 2.0))
            .ceil()
            .max(DVec3::ONE);
        assert_eq!(cells.len() as f64, n.x * n.y * n.z, "every cell, once");
        let err = all_cells(&tree, 1e-9, max_cells(8 << 30, 512))
            .unwrap_err()
            .to_string();
        assert!(err.contains("larger cell size") && err.len() < 300, "{err}");
        // At the cap exactly: allowed.
        let at_cap = cells.len() as u64;
        assert!(all_cells(&tree, extent.max_element() / 2.0, at_cap).is_ok());
        assert!(all_cells(&tree, extent.max_element() / 2.0, at_cap - 1).is_err());
        // 8 GiB hold tens of thousands of 512 px far fields, not billions.
        assert!((10_000..100_000).contains(&max_cells(8 << 30, 512)));
    }

    /// A far field of the grid cell `cell` showing `seen`: blank images, no
    /// meshes (enough for the set's bookkeeping; no GPU needed).
    fn blank(cell: Aabb3d, seen: Vec<u32>) -> FarField {
        let r = *dmu_render::FAR_FIELD_RESOLUTIONS.start();
        let texels = 6 * (r * r) as usize;
        FarField {
            center: cell.center(),
            cell,
            near_box: cell,
            resolution: r,
            tan_half: 1.0,
            vertices: Vec::new(),
            indices: Vec::new(),
            face_starts: [0; 7],
            color: vec![0; 4 * texels],
            parts: vec![0; texels],
            seen,
            excluded: Vec::new(),
            mesh_error_px: 1.0,
            build_ms: 0.0,
        }
    }

    /// A store of a small grid with blank far fields of two cells, opened
    /// as a set.
    fn blank_set() -> (tempfile::TempDir, FarFieldSet, FarFieldIndex) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grid.dmu");
        let scene = dmu_samples::grid(2, 10.0, 4.0, 64);
        dmu_store::write_scene(&scene, &path, Default::default()).unwrap();
        let tree = Tree::build(&scene, Default::default());
        let mut index = grid(&tree, 5.0);
        index.resolution = *dmu_render::FAR_FIELD_RESOLUTIONS.start();
        index.mesh_error_px = 1.0;
        index.model_signature = scene.pose_hash();
        let mut blobs = Vec::new();
        for (i, g) in [[0, 0, 0], [1, 0, 0]].into_iter().enumerate() {
            let cell = index.cell_box(g);
            blobs.push(blank(cell, vec![0]).encode());
            index.cells.push(IndexCell {
                grid: g,
                segment: i as u32,
                near_box: [cell.min.to_array(), cell.max.to_array()],
                near_triangles: 0,
                far_triangles: 0,
                bytes: 0,
                build_ms: 0.0,
            });
        }
        let store = Store::open(&path).unwrap();
        let json = serde_json::to_vec(&index).unwrap();
        dmu_store::write_far_fields::<dmu_store::StoreError>(
            &store,
            &json,
            blobs.into_iter().map(|b| Ok(Some(b))),
        )
        .unwrap()
        .commit()
        .unwrap();
        let store = Arc::new(Store::open(&path).unwrap());
        let set = FarFieldSet::open(&store, &scene).unwrap().unwrap();
        (dir, set, index)
    }

    #[test]
    fn a_far_field_captured_again_replaces_the_one_of_its_cell() {
        let (_dir, mut set, index) = blank_set();
        let eye = index.cell_box([0, 0, 0]).center();
        assert!(set.has_cell_at(eye));
        assert!(!set.has_cell_at(index.cell_box([5, 5, 5]).center()));
        let stored = set.wait_for(eye).unwrap().expect("loaded");
        let moved = BTreeSet::from([0]);
        assert!(stored.is_stale(&moved));
        // Captured again without part 0: its cell's copy is replaced.
        let mut again = blank(stored.cell, Vec::new());
        again.excluded = vec![0];
        let again = Arc::new(again);
        assert_eq!(set.replace(again.clone()), Some(0));
        let now = set.for_eye(eye).unwrap().expect("in memory");
        assert!(Arc::ptr_eq(&now, &again));
        assert!(!now.is_stale(&moved));
        let in_memory = set.loaded();
        assert!(
            in_memory
                .iter()
                .any(|(c, f)| *c == 0 && Arc::ptr_eq(f, &again))
        );
        // A box that is no built cell's replaces nothing.
        let elsewhere = blank(index.cell_box([5, 5, 5]), Vec::new());
        assert_eq!(set.replace(Arc::new(elsewhere)), None);
        let mut shifted = blank(stored.cell, Vec::new());
        shifted.cell.max.x += 1.0;
        assert_eq!(set.replace(Arc::new(shifted)), None);
    }

    #[test]
    fn an_index_with_a_resolution_out_of_range_is_refused() {
        let (_dir, _set, mut index) = blank_set();
        index.resolution = 0;
        let err = FarFieldIndex::decode(&serde_json::to_vec(&index).unwrap()).unwrap_err();
        assert!(err.to_string().contains("resolution 0"), "{err}");
        index.resolution = 128;
        index.mesh_error_px = -1.0;
        assert!(FarFieldIndex::decode(&serde_json::to_vec(&index).unwrap()).is_err());
    }

    #[test]
    fn auto_keeps_the_faster_way_between_probes() {
        let mut auto = FarAuto::default();
        assert!(auto.now().contains("measuring"));
        let mut drawn = Vec::new();
        for frame in 0..(2 * FAR_AUTO_PROBE_EVERY) as usize {
            let with = auto.next_frame();
            drawn.push(with);
            // Faster with the far field in the first probe, without in the second.
            let first = frame < FAR_AUTO_PROBE_EVERY as usize;
            auto.after(if with == first { 5.0 } else { 9.0 }, frame);
        }
        let per = FAR_AUTO_PROBE_EVERY as usize;
        assert_eq!(drawn[..6], [false, false, false, true, true, true]);
        assert!(drawn[6..per].iter().all(|&d| d));
        assert_eq!(drawn[per..per + 6], [false, false, false, true, true, true]);
        assert!(drawn[per + 6..].iter().all(|&d| !d));
        assert_eq!(auto.changes().len(), 2, "{:?}", auto.changes());
        assert!(auto.changes()[1].starts_with(&format!("frame {}: far field off", per + 5)));
        assert!(!auto.uses_far());
        assert_eq!(auto.last(), Some((5.0, 9.0)));
        assert!(
            auto.now().starts_with("far field off by auto"),
            "{}",
            auto.now()
        );
    }
}
