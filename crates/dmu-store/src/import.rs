//! Streaming import of glTF into a store: the JSON is read as a stream into the
//! structure's flat arrays, each mesh is chunked, written and dropped as it is
//! decoded, and the skeleton is written from the flat arrays as they are.

use std::path::Path;

use dmu_scene::{ImportReport, StreamOptions, import_gltf_streaming};

use crate::cad::{CadOptions, CadSummary, convert, is_cad};
use crate::error::StoreError;
use crate::write::{StoreSummary, StoreWriter, WriteOptions};

/// The smallest decoding batch, whatever the budget leaves.
const MIN_BATCH_BYTES: u64 = 16 << 20;

/// Settings of [`import_gltf`].
#[derive(Clone, Copy)]
pub struct ImportOptions<'a> {
    /// Maximum triangles per chunk.
    pub chunk_triangles: u32,
    /// Peak memory to stay within. The structure (the nodes as flat arrays,
    /// the typed JSON of meshes, accessors and materials) is held whole: it
    /// grows with the node count, not with the geometry; decoding batches get
    /// half of what remains after it (at least 16 MiB), the other half is
    /// headroom for the allocator and the writer.
    pub memory_budget_bytes: u64,
    /// How geometry is written.
    pub write: WriteOptions,
    /// Called with (meshes done, meshes total); for STEP and IFC, first with
    /// (products done, products total) while they are converted.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    /// How STEP and IFC files are converted.
    pub cad: &'a CadOptions,
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
    /// Assembly nodes (the root included).
    pub nodes: u64,
    /// Parts.
    pub parts: u64,
    /// Chunk instances over all parts (what the cell tree holds once opened).
    pub chunk_instances: u64,
    /// Triangles, instances counted.
    pub triangles: u64,
    /// Triangles stored once per mesh.
    pub unique_triangles: u64,
    /// Bytes each decoding batch was allowed.
    pub batch_bytes: u64,
    /// Estimated bytes held beside the batches whatever the budget: the nodes'
    /// flat arrays and the typed JSON of the other members. Over the budget,
    /// the budget cannot hold.
    pub fixed_bytes: u64,
    /// The most bytes the structure's flat arrays held at once (counted).
    pub structure_peak_bytes: u64,
    /// What the converter made of a STEP or IFC file; `None` for glTF.
    pub converted: Option<CadSummary>,
}

/// Imports a glTF, STEP or IFC file (by its extension; see [`crate::cad`])
/// into a store at `output`, as [`import_gltf`] does. A STEP or IFC file is
/// first converted to glTF in a scratch folder beside `output`, removed
/// afterwards; products that could not be tessellated are left out and
/// listed in the summary's report.
pub fn import_file(
    input: &Path,
    output: &Path,
    options: &ImportOptions<'_>,
) -> Result<ImportSummary, StoreError> {
    if !is_cad(input) {
        return import_gltf(input, output, options);
    }
    let converted = convert(
        input,
        dmu_scene::folder_of(output),
        options.cad,
        options.progress,
    )?;
    let mut summary = import_gltf(&converted.glb, output, options).map_err(|e| match e {
        StoreError::Import { source, .. } => StoreError::Import {
            path: input.to_owned(),
            source,
        },
        e => e,
    })?;
    summary.report.failed_products = converted.failed;
    summary.converted = Some(converted.summary);
    Ok(summary)
}

/// Imports a .glb or .gltf file into a store at `output`, never holding more
/// than a batch of meshes' geometry (see [`ImportOptions::memory_budget_bytes`])
/// nor the glTF's JSON as a document. The store replaces `output` only once
/// complete.
pub fn import_gltf(
    input: &Path,
    output: &Path,
    options: &ImportOptions<'_>,
) -> Result<ImportSummary, StoreError> {
    let mut writer = StoreWriter::create(output, options.write)?;
    let stream = StreamOptions {
        chunk_triangles: options.chunk_triangles,
        memory_budget_bytes: options.memory_budget_bytes,
        min_batch_bytes: MIN_BATCH_BYTES,
        progress: options.progress,
    };
    let streamed = import_gltf_streaming::<Wrapped>(input, &stream, &mut |_, mesh| {
        writer.add_mesh(mesh).map_err(Wrapped::Store)
    })
    .map_err(|e| match e {
        Wrapped::Store(e) => e,
        Wrapped::Import(source) => StoreError::Import {
            path: input.to_owned(),
            source,
        },
    })?;
    let structure = &streamed.structure;
    let store = writer.finish(structure)?.commit()?;
    Ok(ImportSummary {
        store,
        report: streamed.report,
        nodes: structure.nodes.len() as u64,
        parts: structure.parts.len() as u64,
        chunk_instances: structure.chunk_instance_count(),
        triangles: structure.triangle_count(),
        unique_triangles: structure.unique_triangle_count(),
        batch_bytes: streamed.batch_bytes,
        fixed_bytes: streamed.fixed_bytes,
        structure_peak_bytes: streamed.structure_peak_bytes,
        converted: None,
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
