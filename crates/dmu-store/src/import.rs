//! Streaming import of glTF into a store: each mesh is chunked, written and
//! dropped as it is decoded; the skeleton and the tree come from chunk boxes.

use std::path::Path;

use dmu_scene::{ImportReport, StreamOptions, import_gltf_streaming};
use dmu_tree::{Tree, TreeOptions};

use crate::error::StoreError;
use crate::write::{StoreSummary, StoreWriter, WriteOptions};

/// Settings of [`import_gltf`].
#[derive(Clone, Copy)]
pub struct ImportOptions<'a> {
    /// Maximum triangles per chunk.
    pub chunk_triangles: u32,
    /// Peak memory to stay within. The parsed glTF JSON and the scene's
    /// structure are needed whole (they grow with the node count, not with the
    /// geometry); decoding batches get half of what remains after an estimate
    /// of them, the other half is headroom for the allocator and the writer.
    pub memory_budget_bytes: u64,
    /// How geometry is written.
    pub write: WriteOptions,
    /// Called with (meshes done, meshes total).
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
}

impl std::fmt::Debug for ImportOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImportOptions")
            .field("chunk_triangles", &self.chunk_triangles)
            .field("memory_budget_bytes", &self.memory_budget_bytes)
            .field("write", &self.write)
            .finish_non_exhaustive()
    }
}

/// What an import made.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ImportSummary {
    /// The store written.
    pub store: StoreSummary,
    /// What the glTF import skipped or repaired.
    pub report: ImportReport,
    /// Parts.
    pub parts: u64,
    /// Triangles, instances counted.
    pub triangles: u64,
    /// Triangles stored once per mesh.
    pub unique_triangles: u64,
    /// Cells of the tree built from the chunk boxes.
    pub cells: u64,
    /// Bytes each decoding batch was allowed.
    pub batch_bytes: u64,
    /// Estimated bytes of what is held whole whatever the budget: the parsed
    /// JSON and the scene's structure. Over the budget, the budget cannot hold.
    pub fixed_bytes: u64,
}

/// Imports a .glb or .gltf file into a store at `output`, never holding more
/// than a batch of meshes' geometry (see [`ImportOptions::memory_budget_bytes`]).
/// The store replaces `output` only once complete.
pub fn import_gltf(
    input: &Path,
    output: &Path,
    options: &ImportOptions<'_>,
) -> Result<ImportSummary, StoreError> {
    let json_bytes = json_size(input).map_err(|source| StoreError::Io {
        path: input.to_owned(),
        source,
    })?;
    // Measured on the 100M-triangle plant: the JSON parsed twice (a value tree,
    // then typed) peaks near ten times its size, and the skeleton of its nodes is
    // about a third of it again.
    let fixed = json_bytes.saturating_mul(14);
    let batch_bytes = (options.memory_budget_bytes.saturating_sub(fixed) / 2).max(16 << 20);
    let mut writer = StoreWriter::create(output, options.write)?;
    let stream = StreamOptions {
        chunk_triangles: options.chunk_triangles,
        batch_bytes,
        progress: options.progress,
    };
    let import_error = |source| StoreError::Import {
        path: input.to_owned(),
        source,
    };
    let (skeleton, report) = import_gltf_streaming::<Wrapped>(input, &stream, &mut |_, mesh| {
        writer.add_mesh(&mesh).map_err(Wrapped::Store)
    })
    .map_err(|e| match e {
        Wrapped::Store(e) => e,
        Wrapped::Import(e) => import_error(e),
    })?;
    let tree = Tree::build(&skeleton, TreeOptions::default());
    let store = writer.finish(&skeleton)?.commit()?;
    Ok(ImportSummary {
        store,
        report,
        parts: skeleton.parts().len() as u64,
        triangles: skeleton.triangle_count(),
        unique_triangles: skeleton.unique_triangle_count(),
        cells: tree.cell_count() as u64,
        batch_bytes,
        fixed_bytes: fixed,
    })
}

/// The two failures of a streaming import: reading the glTF, writing the store.
enum Wrapped {
    Import(dmu_scene::ImportError),
    Store(StoreError),
}

impl From<dmu_scene::ImportError> for Wrapped {
    fn from(e: dmu_scene::ImportError) -> Self {
        Wrapped::Import(e)
    }
}

/// Bytes of the glTF JSON: the GLB's JSON chunk, or the whole .gltf file.
fn json_size(path: &Path) -> std::io::Result<u64> {
    use std::io::Read as _;
    let mut head = [0u8; 20];
    let mut file = dmu_scene::open_regular_file(path)?;
    let len = file.metadata()?.len();
    let n = file.read(&mut head)?;
    Ok(if n == 20 && head.starts_with(b"glTF") {
        u64::from(u32::from_le_bytes([head[12], head[13], head[14], head[15]]))
    } else {
        len
    })
}
