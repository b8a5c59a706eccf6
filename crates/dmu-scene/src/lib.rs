//! The dmu scene: a product structure of named parts whose part-local geometry is
//! split into chunks; glTF 2.0 import and export. (The procedural sample models
//! live in `dmu-samples`.)
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
//! use dmu_scene::{DEFAULT_CHUNK_TRIANGLES, MeshData, SceneBuilder};
//! use glam::{DAffine3, DVec3, Vec3};
//!
//! let mut b = SceneBuilder::new("one triangle", DEFAULT_CHUNK_TRIANGLES);
//! let material = b.add_material("grey", [0.5, 0.5, 0.5, 1.0]);
//! let mut mesh = MeshData::default();
//! mesh.push_primitive(&[Vec3::ZERO, Vec3::X, Vec3::Y], &[Vec3::Z; 3], &[0, 1, 2], material);
//! let mesh = b.add_mesh(&mesh);
//! let far = DAffine3::from_translation(DVec3::new(1e6, 0.0, 0.0));
//! let node = b.add_node(SceneBuilder::ROOT, "part", far);
//! b.add_part(node, mesh);
//! let scene = b.finish();
//! assert_eq!(scene.triangle_count(), 1);
//! scene.validate().unwrap();
//! ```

mod atomic;
mod chunking;
mod error;
mod gltf_export;
mod gltf_import;
mod ids;
mod lod;
mod nearest;
pub mod properties;
mod scene;
mod solid;
mod structure;

pub use atomic::{
    AtomicFile, folder_of, open_regular_file, read_regular_file, write_file_atomically,
};
pub use chunking::{
    ChunkData, ChunkedMesh, MeshData, MeshGroup, chunk_mesh, compute_normals, spatial_runs,
};
pub use error::{ExportError, ImportError, SceneError};
pub use gltf_export::export_gltf;
pub use gltf_import::{
    FailedProduct, ImportOptions, ImportReport, SUPPORTED_REQUIRED, import_gltf, import_gltf_slice,
};
pub use gltf_import::{StreamOptions, Streamed, import_gltf_streaming};
pub use ids::{ChunkId, MaterialId, MeshId, NodeId, PartId};
pub use lod::{
    LodLevel, MAX_LOD_LEVELS, MIN_LOD_TRIANGLES, lod_levels, simplified_error, simplify_mended,
    simplify_to_error,
};
pub use properties::Properties;
pub use scene::{
    AssemblyNode, Children, Chunk, ChunkGeometry, DEFAULT_CHUNK_TRIANGLES, MAX_WORLD_COORDINATE,
    Material, Mesh, Part, Scene, SceneBuilder, limits,
};
pub use solid::is_solid;
pub use structure::{ChunkEntry, MeshEntry, NO_PARENT, Names, NodeEntry, PartEntry, Structure};
