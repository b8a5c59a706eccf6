//! Clearance and collision on the dmu cell tree: hard clashes, contacts and soft
//! (clearance) clashes of moved parts, the time of first impact along a motion,
//! and the replay of recorded manipulations.
//!
//! Design choices:
//! - **Broad phase through the tree**: each moved chunk's world box, inflated by
//!   the clearance, gathers the chunk instances near it
//!   ([`Tree::entries_in_box`](dmu_tree::Tree::entries_in_box)), so the cost
//!   follows what is near the moved part, not the size of the plant. Only pairs
//!   involving a moved part are tested.
//! - **Narrow phase per chunk pair** over dmu-tree's per-chunk BVHs (the same
//!   ones picking uses, built on first use and shared by every instance): the
//!   two chunks' BVHs are traversed together, nearer node pairs first, node
//!   pairs farther apart than the best distance so far pruned; node boxes and
//!   triangles are carried into the pair frame once per chunk pair and reused
//!   as the traversal revisits them. Measured on `dmu bench collide` (a
//!   10k-triangle part dragged over the 10M plant), each step kept because it
//!   paid: see docs/measurements.md.
//! - **Temporal coherence.** Consecutive steps differ by millimetres, so each
//!   part pair's nearest triangle pair is remembered and tried first at the
//!   next check: its real distance shrinks the search at once.
//! - **Contact settled cheaply, exactly.** Once a pair at distance 0 is held
//!   (a part resting on a floor), only penetration can change the answer: a
//!   triangle pair is tested for penetration only: faces flat on each other
//!   facing each other are settled by their plane distances, others by the
//!   first separating axis within the tolerance. Each shortcut gives the
//!   answer the full test gives (a test compares them).
//! - **f64 where it matters.** Both parts are placed in a frame with world axes
//!   and its origin at the first part's translation, the offset between them
//!   formed in f64 before any geometry is touched; the triangle pairs the BVHs
//!   hand over are compared in f64 ([`triangle_clash`]). parry's own queries would
//!   form the relative pose in f32 (`pos1.inv_mul(pos2)`), where 10^7 mm from
//!   the origin a 0.5 mm gap rounds to contact, and run GJK in f32, where
//!   touching faces come out as random hits and misses.
//! - **Three kinds, one tolerance.** Hard (penetrating), contact (touching within
//!   the contact tolerance), soft (closer than the clearance). Touching is a
//!   kind of its own so that exactly modelled contact (a flange on a flange)
//!   reads the same every time instead of flickering between hard and soft.
//! - **Surfaces and solids.** A `TriMesh` is a hollow surface; penetration is
//!   decided on triangle pairs (crossing deeper than the tolerance, or coplanar
//!   faces facing the same way and overlapping: the coincident faces of two
//!   solids on the same side). A part wholly inside a *closed* part (every edge
//!   shared by an even number of triangles) is found by ray parity from the
//!   inner part's first vertex, for every pair where one part's box holds the
//!   other's: an index over whole-part boxes finds the parts that could
//!   swallow a moved part however far their chunks are from it (a pump deep in
//!   a hall of fifty wall chunks), and a closed moved part is tested against
//!   the parts inside its box. Open meshes never contain.
//! - **Continuous check by conservative advancement** on the same f64 distance
//!   ([`Checker::sweep`]): exact for rotations as for translations, so a thin
//!   plate crossed in one step is found. [`replay`] sweeps by default only
//!   the steps where a part moves more than its own thickness
//!   ([`SweepMode::Auto`]), the steps a discrete check can jump across, and
//!   says so ([`SweepDecision`]), so short steps keep the discrete check's speed.
//! - **No allocation per check once warm**: a [`Checker`] keeps its scratch
//!   buffers and the caller keeps its [`Report`].
//!
//! Conventions: model units throughout (millimetres for the built-in plant);
//! world poses f64, part geometry f32 in the part's frame, as in `dmu-scene`.
//! The contact tolerance of a pair is [`DEFAULT_CONTACT_TOLERANCE`] (1e-6) times
//! the larger part's scale (its world size, or the magnitude of its local
//! coordinates if larger): surfaces closer than that touch, crossings shallower
//! than that are contact, not penetration. Triangles wind counter-clockwise seen
//! from outside; mirrored parts (negative determinant) are re-wound. A clash's
//! `normal` points the way to move part `b` away from part `a`.
//!
//! ```
//! use dmu_collide::{Checker, ClashKind, Report, Settings};
//! use dmu_geom::glam::{DAffine3, DVec3};
//! use dmu_tree::{Tree, TreeOptions};
//!
//! // Boxes of side 4 on a lattice of pitch 10.
//! let mut scene = dmu_samples::grid(2, 10.0, 4.0, 2048);
//! let mut tree = Tree::build(&scene, TreeOptions::default());
//! let mut checker = Checker::new(&scene);
//! let mut report = Report::default();
//!
//! // Move one box to 0.5 mm from its neighbour (whose face is at x = 8).
//! let part = scene.find_part("box_0_0_0").unwrap();
//! tree.move_part(&mut scene, part, DAffine3::from_translation(DVec3::new(5.5, 0.0, 0.0)));
//! checker.check(&scene, &tree, &[part], &Settings::with_clearance(1.0), &mut report);
//! let clash = report.clashes[0];
//! assert_eq!(report.clashes.len(), 1);
//! assert_eq!((clash.kind, scene.part_name(clash.b)), (ClashKind::Soft, "box_1_0_0"));
//! assert!((clash.distance - 0.5).abs() < 1e-12);
//!
//! // Pushed against it, the faces touch: contact, not noise.
//! tree.move_part(&mut scene, part, DAffine3::from_translation(DVec3::new(6.0, 0.0, 0.0)));
//! checker.check(&scene, &tree, &[part], &Settings::with_clearance(1.0), &mut report);
//! assert_eq!(report.clashes[0].kind, ClashKind::Contact);
//! ```

mod check;
mod contain;
mod enclose;
mod finding;
mod narrow;
mod record;
mod sweep;
mod triangle;

pub use check::{
    AllowList, Checker, Clash, ClashKind, DEFAULT_CONTACT_TOLERANCE, Impact, Report, Separation,
    Settings,
};
pub use finding::{Finding, FindingKind};
pub use record::{
    RecordError, RecordLine, RecordedMove, Step, StepOutcome, Summary, parse_record, read_record,
    record_part_name, replay, write_record,
};
pub use sweep::{MAX_ADVANCEMENT_STEPS, Motion, SweepDecision, SweepMode};
pub use triangle::{TriangleClash, triangle_clash, triangle_distance};
