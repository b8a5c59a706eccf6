//! The dmu dynamic cell tree: one axis-aligned box tree over every part's chunks
//! that the renderer culls with, the loader prioritises with, and picking and
//! collision search; moving a part updates it locally instead of rebuilding it.
//!
//! Design choices:
//! - Leaves are **cells** holding chunk instances grouped by part (MMDr thesis
//!   3.1.6), bounded by a triangle budget (Interviews3D: 1k-8k), so any triangle
//!   found maps back to its part. Triangles are never split; child boxes may overlap.
//! - Built top-down with binned SAH (areas weighted by triangles), in parallel.
//! - Every move advances the tree's [`Revision`] and logs the nodes, cells
//!   and entries it changed ([`Tree::changes_since`]), so a mirror of the tree
//!   (the renderer's) updates in time proportional to the move.
//! - `move_part` touches only the part's chunks: "better to update than to
//!   rebuild" (Interviews3D). Chunks that leave their cell are re-inserted by
//!   branch and bound on the SAH cost increase; cells split and merge to stay in
//!   budget; bounded rotations on the touched paths keep long sessions efficient.
//! - World boxes are f64 and come from each chunk's local box through the part's
//!   absolute transform, so any sequence of moves ending at the original
//!   transform restores the original boxes exactly.
//! - Picking is exact: the f64 ray goes to the part's frame and a per-chunk BVH
//!   (built with obvhs on first use, shared by instances) is traversed with robust
//!   f64 slab and watertight triangle tests.
//!
//! Conventions: as `dmu-geom` (right-handed, model units, f64 world, f32 local).
//!
//! ```
//! use dmu_geom::{Ray3d, glam::{DAffine3, DVec3}};
//! use dmu_tree::{Tree, TreeOptions};
//!
//! let mut scene = dmu_samples::grid(3, 10.0, 4.0, 2048);
//! let mut tree = Tree::build(&scene, TreeOptions::default());
//! let ray = Ray3d::new(DVec3::new(0.0, 0.0, -100.0), DVec3::Z);
//! let hit = tree.pick(&scene, &ray).unwrap();
//! assert_eq!(scene.part_name(hit.part), "box_0_0_0");
//! assert_eq!(hit.t, 98.0);
//!
//! let part = scene.find_part("box_0_0_0").unwrap();
//! tree.move_part(&mut scene, part, DAffine3::from_translation(DVec3::new(500.0, 0.0, 0.0)));
//! let hit = tree.pick(&scene, &ray).unwrap();
//! assert_eq!(scene.part_name(hit.part), "box_0_0_1");
//! tree.validate_against(&scene).unwrap();
//! ```

mod build;
mod changes;
mod chunk_bvh;
mod overlap;
mod query;
mod smallest;
mod stack;
mod tree;
mod update;
mod validate;
mod visible;

pub use changes::{Change, Changes, NodeId, NodeKind, Revision};
pub use chunk_bvh::{BvhNode, ChunkBvh, ChunkBvhCache, LocalHit};
pub use query::{
    FrustumNode, Hit, HitReport, chunk_touches_box, pick_brute_force, triangle_box_overlap,
};
pub use tree::{CellId, Entry, EntryId, Tree, TreeOptions, UpdateStats};
pub use validate::InvariantError;
pub use visible::{EntryVisibility, VisibleNodes};
