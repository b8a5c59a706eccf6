//! Geometry for the review's exact tools under a memory budget: the model is
//! a store's skeleton (no mesh loaded), so before a pick, a collision check or
//! a distance the meshes it reads are loaded from the store into the scene,
//! and the least recently used ones are dropped again past a byte cap. The
//! renderer's chunks stream separately (the residency manager); this is for
//! the triangles the f64 picks and checks read.

use std::sync::Arc;

use dmu_scene::{ChunkGeometry, MeshId, Scene};
use dmu_store::{Store, StoreError};

/// Meshes loaded into a skeleton scene for picks and checks, within a cap.
#[derive(Debug)]
pub struct OnDemand {
    store: Arc<Store>,
    cap_bytes: u64,
    /// Loaded meshes: id, decoded bytes, the operation that last used it.
    loaded: Vec<(MeshId, u64, u64)>,
    bytes: u64,
    peak_bytes: u64,
    operation: u64,
    loads: u64,
}

impl OnDemand {
    /// Loads from `store` (whose skeleton the scene is), keeping at most
    /// `cap_bytes` of decoded meshes loaded between operations.
    pub fn new(store: Arc<Store>, cap_bytes: u64) -> Self {
        Self {
            store,
            cap_bytes,
            loaded: Vec::new(),
            bytes: 0,
            peak_bytes: 0,
            operation: 0,
            loads: 0,
        }
    }

    /// The store.
    pub fn store(&self) -> &Arc<Store> {
        &self.store
    }

    /// Starts an operation (a pick, a check): meshes it loads or uses are not
    /// dropped until the next one starts.
    pub fn begin(&mut self) {
        self.operation += 1;
    }

    /// Decoded bytes loaded now, and at most so far.
    pub fn bytes(&self) -> (u64, u64) {
        (self.bytes, self.peak_bytes)
    }

    /// Meshes loaded so far (a mesh loaded again counts again).
    pub fn loads(&self) -> u64 {
        self.loads
    }

    /// Loads `meshes` into `scene` (those not loaded yet), then drops the least
    /// recently used meshes of earlier operations while over the cap.
    pub fn ensure(&mut self, scene: &mut Scene, meshes: &[MeshId]) -> Result<(), StoreError> {
        for &mesh in meshes {
            if let Some(entry) = self.loaded.iter_mut().find(|e| e.0 == mesh) {
                entry.2 = self.operation;
                continue;
            }
            if scene.mesh(mesh).is_loaded() {
                // Nothing to load (no triangles).
                continue;
            }
            let chunks = self.store.mesh_geometry(mesh)?;
            let borrowed: Vec<ChunkGeometry<'_>> = chunks.iter().map(|c| c.geometry()).collect();
            scene
                .load_mesh_geometry(mesh, &borrowed)
                .map_err(|e| StoreError::Corrupt {
                    path: self.store.path().to_owned(),
                    what: e.to_string(),
                })?;
            let bytes = chunks.iter().map(|c| c.resident_bytes()).sum();
            self.loaded.push((mesh, bytes, self.operation));
            self.bytes += bytes;
            self.peak_bytes = self.peak_bytes.max(self.bytes);
            self.loads += 1;
        }
        while self.bytes > self.cap_bytes {
            let Some((i, _)) = self
                .loaded
                .iter()
                .enumerate()
                .filter(|(_, e)| e.2 < self.operation)
                .min_by_key(|(_, e)| e.2)
            else {
                break;
            };
            let (mesh, bytes, _) = self.loaded.swap_remove(i);
            scene.unload_mesh_geometry(mesh);
            self.bytes -= bytes;
        }
        Ok(())
    }
}
