//! Error types of the store.

use std::path::PathBuf;

/// Errors while reading, writing or importing a store. Each names the file and
/// what in it is at fault; none of them is ever a panic.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StoreError {
    /// Reading, writing, syncing or renaming failed; a store being written is
    /// left as it was before (writes go to a temporary file renamed at the end).
    #[error("cannot access {}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a dmu store at all.
    #[error("{} is not a dmu store: it looks like {found}", path.display())]
    NotAStore {
        /// The path.
        path: PathBuf,
        /// What it looks like instead (e.g. "binary glTF; import it with `dmu import`").
        found: String,
    },
    /// A store of a format version this build cannot read.
    #[error(
        "{} is a dmu store of format version {found}; this dmu reads versions {oldest} to {supported} (re-import the model)",
        path.display(),
        oldest = crate::format::OLDEST_READABLE_VERSION
    )]
    UnsupportedVersion {
        /// The path.
        path: PathBuf,
        /// The file's version.
        found: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// A store written with the other byte order.
    #[error("{} was written big-endian; dmu stores are little-endian", path.display())]
    ByteOrder {
        /// The path.
        path: PathBuf,
    },
    /// The file is shorter than its header says: an interrupted copy or download.
    #[error("{} is truncated: {what} needs {expected} bytes, the file has {actual}", path.display())]
    Truncated {
        /// The path.
        path: PathBuf,
        /// What did not fit.
        what: String,
        /// Bytes needed.
        expected: u64,
        /// Bytes present.
        actual: u64,
    },
    /// A segment's bytes do not match the checksum recorded for them.
    #[error(
        "{} is corrupt: {segment} fails its checksum (stored {stored:#018x}, computed {computed:#018x})",
        path.display()
    )]
    Checksum {
        /// The path.
        path: PathBuf,
        /// Which segment ("header", "table of contents", "skeleton", "chunk #12",
        /// "the far-field index", "far-field cell #3").
        segment: String,
        /// The checksum recorded.
        stored: u64,
        /// The checksum of the bytes.
        computed: u64,
    },
    /// The structure is inconsistent although checksums pass (a writer bug or a
    /// crafted file).
    #[error("{} is corrupt: {what}", path.display())]
    Corrupt {
        /// The path.
        path: PathBuf,
        /// What is wrong, where.
        what: String,
    },
    /// The glTF input of an import is unreadable.
    #[error("importing {}", path.display())]
    Import {
        /// The glTF file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: dmu_scene::ImportError,
    },
    /// Writing glTF failed.
    #[error("writing {}", path.display())]
    Export {
        /// The output file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: dmu_scene::ExportError,
    },
    /// A rewrite of a store on object storage (a save, new far fields)
    /// refused because someone else saved the object after it was read:
    /// nothing was overwritten, and the new store is kept in a local file.
    #[error(
        "{}: someone else saved it after it was opened (its version changed); nothing was overwritten, and this save is kept in {}",
        path.display(),
        kept.display()
    )]
    RemoteConflict {
        /// The object's address.
        path: PathBuf,
        /// The local file holding the store that was not saved.
        kept: PathBuf,
    },
    /// A STEP or IFC file the converter could not read (see [`crate::cad`]).
    #[error("{}: {what}", path.display())]
    Convert {
        /// The file.
        path: PathBuf,
        /// What went wrong, one line.
        what: String,
    },
    /// An input that is neither a store nor glTF by its name or its first bytes.
    #[error("{}: unknown file type (dmu reads .glb, .gltf, .dmu, .step, .stp and .ifc)", path.display())]
    UnknownInputFormat {
        /// The file.
        path: PathBuf,
    },
    /// An output whose extension names no format dmu writes.
    #[error(
        "{}: unknown output format (the extension picks it: .dmu for a store, .glb or .gltf for glTF)",
        path.display()
    )]
    UnknownOutputFormat {
        /// The output file.
        path: PathBuf,
    },
    /// A blob asked for (a far-field cell or a level-of-detail node: read,
    /// or kept by a [`BlobWriter`](crate::BlobWriter)) that the store does
    /// not have.
    #[error("{} has no {what} #{blob}: it has {blobs}", path.display())]
    NoSuchBlob {
        /// The store.
        path: PathBuf,
        /// What the blob is ("far-field cell": [`crate::BlobSet::blob_name`]).
        what: &'static str,
        /// The blob asked for.
        blob: u64,
        /// The blobs of its set the store has (0 without the set).
        blobs: u64,
    },
    /// Saving edits: the scene's structure differs from the store's (only
    /// transforms and visibility may change).
    #[error("the scene does not match {}: {what}", path.display())]
    SceneMismatch {
        /// The store.
        path: PathBuf,
        /// The first difference found.
        what: String,
    },
}

/// A residency manager's accounting is off, found by
/// [`Residency::validate`](crate::Residency::validate): a bug in the manager.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
#[error("{what}")]
pub struct ResidencyError {
    /// What disagrees, where (e.g. "chunk 7: state Loading disagrees with its geometry").
    pub what: String,
}

/// Errors of a walk through a store ([`walk`](crate::walk),
/// [`walk_with`](crate::walk_with)).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WalkError {
    /// A frame of the path is not a camera (eye on the target, up along the
    /// view, a field of view out of range).
    #[error(
        "frame {frame} is not a camera ({camera}): the eye must differ from the target, up must not lie along the view, the field of view must be between 0 and 180 degrees, and every number finite"
    )]
    NotACamera {
        /// The frame's index.
        frame: usize,
        /// The frame as given: eye, target, up and field of view.
        camera: String,
    },
    /// The caller's `draw` failed on a frame.
    #[error("{}: {source}", frame.map_or("an opening frame".to_string(), |i| format!("frame {i}")))]
    Draw {
        /// The frame's index; none for an opening frame
        /// ([`crate::WalkOptions::opening_frames`]).
        frame: Option<usize>,
        /// What `draw` returned.
        #[source]
        source: crate::walk::DrawError,
    },
    /// The residency manager's accounting was off at the end of the walk.
    #[error(transparent)]
    Residency(#[from] ResidencyError),
}

/// An error and its causes on one line, as the command line prints them
/// (`StoreError`'s own message names the file, its causes say why).
pub fn one_line(e: &dyn std::error::Error) -> String {
    let mut line = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        line += &format!(": {c}");
        cause = c.source();
    }
    line
}
