//! Flat contact settled a node pair at a time: where every triangle of a BVH
//! node lies in one plane facing one way (the bottom of a pump, the top of a
//! floor), and two such nodes lie flat on each other facing each other, no
//! triangle pair of theirs can penetrate (see
//! [`triangle_penetration`](crate::triangle)), so a part resting on a floor
//! does not cost a triangle test per touching pair once contact is known.

use std::sync::OnceLock;

use dmu_geom::Aabb3d;
use dmu_scene::{ChunkId, Scene};
use dmu_tree::BvhNode;
use glam::DVec3;

use crate::narrow::Placement;
use crate::triangle::unit_normal;

/// Normals of one node's triangles agree to this (unit vectors' difference):
/// exactly coplanar modelled faces, not faces that merely look flat.
const SAME_NORMAL: f64 = 1e-12;

/// The plane every triangle of a node lies in (within 1e-10 of the chunk's
/// size), facing along `normal`: part-local, `normal · p = offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct NodePlane {
    normal: DVec3,
    offset: f64,
}

impl NodePlane {
    /// This plane under a rigid placement (see [`Placement::rigid`]).
    pub fn placed(&self, place: &Placement) -> Self {
        let normal = place.to_pair.matrix3 * self.normal;
        Self {
            normal,
            offset: self.offset + normal.dot(place.to_pair.translation),
        }
    }

    /// The largest distance of a point of `bounds` from the plane.
    fn reach(&self, bounds: &Aabb3d) -> f64 {
        (self.normal.dot(bounds.center()) - self.offset).abs()
            + self.normal.abs().dot(bounds.extent() * 0.5)
    }
}

/// Whether two flat nodes (planes and boxes placed in the pair frame) lie on
/// each other facing each other, each box within a quarter of `tolerance` of
/// the other's plane: then every pair of their triangles is flat within half
/// the tolerance and faces the other way, which cannot penetrate.
pub(crate) fn flat_on_each_other(
    (plane_a, box_a): (&NodePlane, &Aabb3d),
    (plane_b, box_b): (&NodePlane, &Aabb3d),
    tolerance: f64,
) -> bool {
    plane_a.normal.dot(plane_b.normal) < -0.5
        && plane_a.reach(box_b) <= 0.25 * tolerance
        && plane_b.reach(box_a) <= 0.25 * tolerance
}

/// Per chunk, per BVH node, its plane if it is flat; computed on first use.
#[derive(Debug)]
pub(crate) struct ChunkPlanes {
    slots: Vec<OnceLock<Vec<Option<NodePlane>>>>,
}

impl ChunkPlanes {
    pub fn new(chunks: usize) -> Self {
        Self {
            slots: (0..chunks).map(|_| OnceLock::new()).collect(),
        }
    }

    /// The planes of `nodes` (the chunk's BVH, or its one leaf) of `chunk`,
    /// whose leaf entries map to triangle offsets by `offset`.
    pub fn get(
        &self,
        scene: &Scene,
        chunk: ChunkId,
        nodes: &[BvhNode],
        offset: impl Fn(u32) -> u32,
    ) -> &[Option<NodePlane>] {
        self.slots[chunk.index()].get_or_init(|| planes(scene, chunk, nodes, offset))
    }
}

fn planes(
    scene: &Scene,
    chunk: ChunkId,
    nodes: &[BvhNode],
    offset: impl Fn(u32) -> u32,
) -> Vec<Option<NodePlane>> {
    let g = scene
        .chunk_geometry(chunk)
        .expect("collision needs the geometry loaded");
    let close = 1e-10 * f64::from(scene.chunk(chunk).bounds.extent().length());
    let triangle = |t: u32| {
        let i = 3 * t as usize;
        [0, 1, 2].map(|k| g.positions[g.indices[i + k] as usize].as_dvec3())
    };
    // Children before parents: a pre-order walk, reversed.
    let mut order = Vec::with_capacity(nodes.len());
    let mut stack = vec![0u32];
    while let Some(i) = stack.pop() {
        order.push(i);
        let n = nodes[i as usize];
        if n.count == 0 {
            stack.extend([n.first, n.first + 1]);
        }
    }
    let mut planes = vec![None; nodes.len()];
    for &i in order.iter().rev() {
        let n = nodes[i as usize];
        planes[i as usize] = if n.count == 0 {
            let (l, r) = (planes[n.first as usize], planes[n.first as usize + 1]);
            l.zip(r).and_then(|(l, r): (NodePlane, NodePlane)| {
                ((l.normal - r.normal).length() <= SAME_NORMAL
                    && (l.offset - r.offset).abs() <= close)
                    .then_some(l)
            })
        } else {
            leaf_plane(
                (n.first..n.first + n.count).map(|e| triangle(offset(e))),
                close,
            )
        };
    }
    planes
}

/// The plane of a leaf's triangles, if they all lie in one facing one way.
fn leaf_plane(mut triangles: impl Iterator<Item = [DVec3; 3]>, close: f64) -> Option<NodePlane> {
    let first = triangles.next()?;
    let normal = unit_normal(&first)?;
    let plane = NodePlane {
        normal,
        offset: normal.dot(first[0]),
    };
    let on = |t: &[DVec3; 3]| {
        t.iter()
            .all(|v| (normal.dot(*v) - plane.offset).abs() <= close)
    };
    (on(&first)
        && triangles.all(|t| {
            unit_normal(&t).is_some_and(|n| (n - normal).length() <= SAME_NORMAL) && on(&t)
        }))
    .then_some(plane)
}
