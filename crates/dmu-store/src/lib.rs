//! The dmu store: a model in one file of checksummed segments, written
//! streaming, read with positioned reads (`pread`, never a memory map), and a
//! residency manager that keeps the chunk geometry a view needs in memory
//! within a byte budget.
//!
//! Design choices:
//! - One file: a header (magic, version, byte order), segments, and a table of
//!   contents (segment id, kind, offset, length, checksum) at the end, so a
//!   writer streams chunks out as they are made and never seeks back but once
//!   for the header (the SJT layout of the MMDr thesis, 3.1.5).
//! - One segment per chunk's geometry (the unit of loading everywhere) and one
//!   skeleton segment with everything else: materials, the assembly tree and its
//!   f64 transforms, parts, each mesh's chunk table with the chunk boxes, as
//!   flat aligned arrays ([`dmu_scene::Structure`]: a few dozen bytes a node,
//!   part and chunk, names in one string table) written as they are and read
//!   back with `pread` straight into them (format version 2, issue 14;
//!   version 3 adds whether each mesh is solid). The skeleton opens as a
//!   [`dmu_scene::Scene`] whose geometry is not loaded, and the cell tree is
//!   built from it (chunk boxes alone, about 80 ms for 100M triangles) rather
//!   than stored: it is derived data, and rebuilding it cannot disagree with
//!   the transforms.
//! - Each chunk's simplified levels are stored after its indices (format
//!   version 4, issue 42), computed in parallel as chunks are written: drawing
//!   a streamed chunk then costs no simplification. Version-3 stores are still
//!   read (their chunks without levels) and gain levels when rewritten.
//! - Far fields (a textured depth mesh per viewpoint cell, made by the
//!   renderer) are kept beside the geometry as opaque blobs: one far-field
//!   index segment and one segment per cell, read one at a time
//!   ([`Store::far_field_cell`]) and replaced by [`write_far_fields`], which
//!   can keep the cells that are not stale. The level-of-detail hierarchy
//!   (merged, simplified proxies of the tree's upper nodes, made by
//!   `dmu_app::lod`) is a second such set ([`BlobSet::Lod`]: an index and a
//!   blob per node, written streamed by a [`BlobWriter`]). The store does not
//!   know their encoding, so their producer can change it without a new
//!   format version.
//! - Every byte is covered by a checksum (xxh3-64): the header and the table of
//!   contents at open, the skeleton at open, a chunk's segment when first
//!   touched. Every offset and length is checked before use, so a truncated,
//!   corrupt or foreign file gives an error naming what is wrong, never a panic.
//! - Every write goes to a temporary file beside the target, is synced, then
//!   renamed over it: a crash leaves the previous file whole. Saving edits
//!   writes a new skeleton and copies the geometry segments
//!   ([`save_edits`]; its cost is one sequential copy of the file).
//! - Residency: loader threads take requests in priority order (visible last
//!   frame, in the frustum, prefetched from the predicted path, below a pixel;
//!   then by projected area), memory is reserved before a load so the budget is
//!   never exceeded, and eviction is least-recently-used among chunks that are
//!   not in use and not wanted more urgently (MMDr 3.3, MMR 5.2).
//!
//! Conventions: little-endian, segments 16-byte aligned; geometry part-local f32
//! (optionally quantized to 16 bits in the chunk's box), transforms f64, as in
//! `dmu-scene`. Budgets count decoded bytes (24 per vertex, 12 per triangle,
//! and 12 more per triangle for the levels of a version-4 chunk: their bound).
//!
//! ```
//! use std::sync::Arc;
//! use dmu_samples::grid;
//! use dmu_store::{Store, WriteOptions, write_scene};
//!
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("grid.dmu");
//! let scene = grid(3, 10.0, 4.0, 2048);
//! write_scene(&scene, &path, WriteOptions::default()).unwrap();
//!
//! let store = Store::open(&path).unwrap();
//! assert_eq!(store.skeleton().parts().len(), 27);
//! assert!(!store.skeleton().meshes()[0].is_loaded());
//! // The tree needs only the chunk boxes of the skeleton.
//! let tree = dmu_tree::Tree::build(store.skeleton(), Default::default());
//! assert_eq!(tree.entries().len(), 27);
//! // Geometry is read when asked for.
//! let loaded = store.load_scene().unwrap();
//! assert_eq!(loaded.meshes(), scene.meshes());
//! ```

pub mod cad;
mod error;
mod format;
mod geometry;
mod import;
mod open;
mod prefetch;
mod priority;
mod read;
pub mod remote;
mod residency;
mod save;
mod skeleton;
mod streamer;
mod view;
mod walk;
mod write;

pub use error::{ResidencyError, StoreError, WalkError, one_line};
pub use format::{BlobSet, FORMAT_VERSION, OLDEST_READABLE_VERSION, reseal};
pub use geometry::OwnedChunkGeometry;
pub use import::{ImportOptions, ImportSummary, import_file, import_gltf};
pub use open::open_scene;
pub use prefetch::{PrefetchOptions, Prefetcher};
pub use priority::{Class, LoadOrder, Request};
pub use read::{REMOTE_LOADERS, Store, StoreInfo};
pub use residency::{Pacing, RETRY_FIRST, RETRY_MOST, Residency, ResidencyOptions, ResidencyStats};
pub use save::{
    BlobWriter, SavedFormat, prepare_save, save_edits, save_scene, save_scene_with,
    write_far_fields,
};
pub use streamer::{KEEP_VISIBLE_FRAMES, Streamer};
pub use view::{CameraFrame, LodCut, View, Viewport, Wanted, wanted};
pub use walk::{
    DrawError, DrawFrame, Drawn, FrameReport, OPENING_STALL_FRAMES, Opening, WalkOptions,
    WalkReport, WalkTotals, walk, walk_with,
};
pub use write::{PendingStore, StoreSummary, StoreWriter, WriteOptions, write_scene};
