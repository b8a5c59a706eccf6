//! The narrow phase: a parry3d `TriMesh` per chunk (built on first use, shared
//! by every instance of the chunk), two of them traversed together, their
//! triangle pairs compared in f64 in a frame centred on the first part.

use std::sync::OnceLock;

use dmu_geom::{Aabb3d, Aabb3f};
use dmu_scene::{ChunkId, PartId, Scene};
use glam::{DAffine3, DVec3, Vec3};
use parry3d::partitioning::BvhNode;
use parry3d::shape::TriMesh;

use crate::triangle::{TriangleClash, triangle_clash};

/// The lazily built triangle meshes of a scene's chunks.
#[derive(Debug)]
pub(crate) struct ChunkShapes {
    slots: Vec<OnceLock<TriMesh>>,
}

impl ChunkShapes {
    pub fn new(chunks: usize) -> Self {
        Self {
            slots: (0..chunks).map(|_| OnceLock::new()).collect(),
        }
    }

    /// Chunks whose mesh has been built so far.
    pub fn built(&self) -> usize {
        self.slots.iter().filter(|s| s.get().is_some()).count()
    }

    /// The chunk's mesh in part-local f32 coordinates, triangle `i` being the
    /// chunk's `i`-th triangle.
    pub fn get(&self, scene: &Scene, chunk: ChunkId) -> &TriMesh {
        self.slots[chunk.index()].get_or_init(|| {
            let g = scene
                .chunk_geometry(chunk)
                .expect("collision needs the geometry loaded");
            let vertices = g.positions.to_vec();
            let indices = g
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect();
            TriMesh::new(vertices, indices).expect("a chunk has at least one triangle")
        })
    }
}

/// Where a part sits in the frame of a pair: world axes, origin at the first
/// part's world translation. Offsets between parts are formed in f64 before any
/// geometry is touched, so a 0.05 mm gap 10 km from the origin stays 0.05 mm.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placement {
    /// Part-local to pair frame.
    pub to_pair: DAffine3,
    /// The transform mirrors: triangle windings flip, so they are reordered to
    /// keep outward normals outward.
    pub mirrored: bool,
}

impl Placement {
    /// `world` seen from a pair frame whose origin is at `origin` (world).
    pub fn new(world: &DAffine3, origin: DVec3) -> Self {
        Self {
            to_pair: DAffine3 {
                matrix3: world.matrix3,
                translation: world.translation - origin,
            },
            mirrored: world.matrix3.determinant() < 0.0,
        }
    }

    pub fn triangle(&self, t: [Vec3; 3]) -> [DVec3; 3] {
        let [a, b, c] = t.map(|v| self.to_pair.transform_point3(v.as_dvec3()));
        if self.mirrored { [a, c, b] } else { [a, b, c] }
    }

    pub fn node_box(&self, node: &BvhNode) -> Aabb3d {
        Aabb3f::new(node.mins(), node.maxs()).transformed(&self.to_pair)
    }
}

/// Squared distance between two boxes (0 when they overlap).
pub(crate) fn box_gap_squared(a: &Aabb3d, b: &Aabb3d) -> f64 {
    (b.min - a.max)
        .max(a.min - b.max)
        .max(DVec3::ZERO)
        .length_squared()
}

/// What the narrow phase has found so far for one pair of parts.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PairSearch {
    /// Triangles closer than this are contact; penetration beyond it is hard.
    pub tolerance: f64,
    /// Only triangle pairs within this distance matter; it shrinks to the best
    /// distance found (but never below `tolerance`, where penetration is sought).
    pub limit: f64,
    /// The nearest (or the first penetrating) triangle pair, in the pair frame.
    pub best: Option<TriangleClash>,
}

impl PairSearch {
    pub fn new(tolerance: f64, max_distance: f64) -> Self {
        Self {
            tolerance,
            limit: max_distance.max(tolerance),
            best: None,
        }
    }

    /// A penetrating pair was found: nothing more to look for.
    pub fn done(&self) -> bool {
        self.best.is_some_and(|b| b.penetrating)
    }

    fn offer(&mut self, clash: TriangleClash) {
        if clash.penetrating || self.best.is_none_or(|b| clash.distance < b.distance) {
            self.best = Some(clash);
            self.limit = clash.distance.max(self.tolerance);
        }
    }
}

/// Compares two chunks, placed in a common pair frame, triangle pair by
/// triangle pair as the two BVHs are traversed together; node pairs farther
/// apart than the search's limit are pruned.
pub(crate) fn chunk_pair(
    mesh_a: &TriMesh,
    place_a: &Placement,
    mesh_b: &TriMesh,
    place_b: &Placement,
    search: &mut PairSearch,
) {
    // The traversal's check can only read: the limit lives in a cell.
    let limit = std::cell::Cell::new(search.limit);
    let close = |n1: &BvhNode, n2: &BvhNode| {
        let l = limit.get();
        box_gap_squared(&place_a.node_box(n1), &place_b.node_box(n2)) <= l * l
    };
    for (i, j) in mesh_a.bvh().leaf_pairs(mesh_b.bvh(), close) {
        let ta = mesh_a.triangle(i);
        let tb = mesh_b.triangle(j);
        let a = place_a.triangle([ta.a, ta.b, ta.c]);
        let b = place_b.triangle([tb.a, tb.b, tb.c]);
        if let Some(clash) = triangle_clash(&a, &b, search.tolerance, search.limit) {
            search.offer(clash);
            limit.set(search.limit);
            if search.done() {
                return;
            }
        }
    }
}

/// The contact tolerance of a part pair: the larger of the two parts'.
pub(crate) fn pair_tolerance(scene: &Scene, a: PartId, b: PartId, relative: f64) -> f64 {
    part_tolerance(scene, a, relative).max(part_tolerance(scene, b, relative))
}

/// The contact tolerance of a part: `relative` times the larger of its world
/// size and the magnitude of its local coordinates, the two scales at which its
/// f32 vertices and f64 transform carry rounding.
pub(crate) fn part_tolerance(scene: &Scene, part: PartId, relative: f64) -> f64 {
    let bounds = scene.part_mesh(part).bounds;
    if bounds.is_empty() {
        return 0.0;
    }
    let m = scene.part_world(part).matrix3;
    let stretch = m
        .x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length());
    let local = bounds.min.abs().max(bounds.max.abs()).max_element();
    let size = bounds.extent().length();
    relative * stretch * f64::from(local.max(size))
}
