//! The dmu scene: a product structure of named parts whose part-local geometry is
//! split into chunks; glTF 2.0 import and export; procedural sample models.
//!
//! Design choices:
//! - A part's world transform is f64 and its geometry f32 in the part's own frame:
//!   CAD coordinates sit far from the origin, where f32 loses millimetres.
//! - Geometry is chunked once, at import: a chunk (at most `chunk_triangles`,
//!   spatially compact) is the unit of loading, drawing, picking and collision
//!   everywhere after. Triangles are never split or duplicated.
//! - Instancing is kept: parts share meshes and differ in transform, as CAD
//!   assemblies share standard parts.
//! - Structure is fixed after building; only part transforms and visibility change,
//!   and transforms are absolute, so any sequence of moves is reversible exactly.
//!
//! Conventions: right-handed, model units (millimetres for the built-in plant),
//! counter-clockwise front faces, linear RGBA colours.
//!
//! ```
//! use dmu_scene::samples::grid;
//! let scene = grid(2, 10.0, 4.0, dmu_scene::DEFAULT_CHUNK_TRIANGLES);
//! assert_eq!(scene.parts().len(), 8);
//! assert_eq!(scene.triangle_count(), 8 * 12);
//! scene.validate().unwrap();
//! ```

mod atomic;
mod chunking;
mod error;
mod gltf_export;
mod gltf_import;
mod ids;
pub mod samples;
mod scene;

pub use atomic::{AtomicFile, write_file_atomically};
pub use chunking::{ChunkData, ChunkedMesh, MeshData, MeshGroup, chunk_mesh, compute_normals};
pub use error::{ExportError, ImportError, SceneError};
pub use gltf_export::export_gltf;
pub use gltf_import::{
    ImportOptions, ImportReport, SUPPORTED_REQUIRED, import_gltf, import_gltf_slice,
};
pub use gltf_import::{StreamOptions, import_gltf_streaming};
pub use ids::{ChunkId, MaterialId, MeshId, NodeId, PartId};
pub use scene::{
    AssemblyNode, Chunk, DEFAULT_CHUNK_TRIANGLES, Material, Mesh, Part, Scene, SceneBuilder,
};
