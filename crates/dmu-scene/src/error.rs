//! Error types of the scene crate.

use std::path::PathBuf;

/// Errors about a scene's contents.
#[derive(Debug, thiserror::Error, PartialEq)]
#[non_exhaustive]
pub enum SceneError {
    /// No part has that name, path or id.
    #[error("unknown part {key:?} (give a part name, its full path, or #id)")]
    UnknownPart {
        /// What was asked for.
        key: String,
    },
    /// Several parts share that name.
    #[error("part name {key:?} is ambiguous: {count} parts have it, e.g. {}; give the full path or #id", candidates.join(", "))]
    AmbiguousPart {
        /// What was asked for.
        key: String,
        /// A few of the matches, as `#id path`.
        candidates: Vec<String>,
        /// How many parts matched.
        count: usize,
    },
    /// A broken structural invariant (a bug, reported by `validate`).
    #[error("invalid scene: {what}")]
    Invalid {
        /// Which invariant, where.
        what: String,
    },
}

/// Errors while reading a glTF file. Each names the file element at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// The file (or an external buffer) could not be read.
    #[error("cannot read {}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Not a glTF file, or its JSON or GLB container is malformed.
    #[error("malformed glTF: {message}")]
    Malformed {
        /// The parser's message.
        message: String,
    },
    /// The file requires an extension dmu cannot read.
    #[error("unsupported required glTF extension {name} (dmu reads {})", crate::gltf_import::SUPPORTED_REQUIRED.join(", "))]
    UnsupportedExtension {
        /// The extension's name.
        name: String,
    },
    /// A reference, offset or length points outside what exists.
    #[error("invalid glTF: {what}")]
    Invalid {
        /// What, where (JSON path style, e.g. `accessors[3].bufferView`).
        what: String,
    },
    /// A node's world transform (the product of the transforms from the root down
    /// to it), or the world box of its part, is not finite: finite values whose
    /// product overflows (e.g. 1e200 scales on a parent and a child).
    #[error(
        "node {node} ({path}): its {what} is not finite or beyond ±1e15 model units (the transforms down to it overflow)"
    )]
    NonFiniteWorld {
        /// Node index in the file.
        node: usize,
        /// The node's path in the assembly (names joined by `/`).
        path: String,
        /// "world transform" or "world box".
        what: &'static str,
    },
    /// A vertex position is NaN or infinite.
    #[error(
        "mesh {mesh} ({mesh_name:?}) primitive {primitive}: POSITION accessor {accessor} has a non-finite value at vertex {vertex}"
    )]
    NonFinitePosition {
        /// Mesh index.
        mesh: usize,
        /// Mesh name.
        mesh_name: String,
        /// Primitive index within the mesh.
        primitive: usize,
        /// Accessor index.
        accessor: usize,
        /// Vertex index.
        vertex: usize,
    },
    /// A primitive's index refers past the vertex count.
    #[error(
        "mesh {mesh} ({mesh_name:?}) primitive {primitive}: index accessor {accessor} element {position} is {index}, but there are only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// Mesh index.
        mesh: usize,
        /// Mesh name.
        mesh_name: String,
        /// Primitive index within the mesh.
        primitive: usize,
        /// Accessor index.
        accessor: usize,
        /// Position of the bad element in the accessor.
        position: usize,
        /// The bad index.
        index: u32,
        /// Vertices the primitive has.
        vertex_count: usize,
    },
}

/// Errors while writing a glTF file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// Writing or renaming failed; the previous file, if any, is untouched.
    #[error("cannot write {}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The scene does not fit the format (GLB is limited to 4 GiB).
    #[error("scene too large for {format}: {bytes} bytes")]
    TooLarge {
        /// `glb` or `gltf`.
        format: &'static str,
        /// Bytes it would take.
        bytes: u64,
    },
}
