//! Per-chunk triangle BVHs, built on first use and shared by every instance of
//! the chunk: the one bounding-volume hierarchy over a chunk's triangles, for
//! exact picking here and for collision and containment in dmu-collide. obvhs
//! builds them (PLOC); traversal is the caller's, in f64: picking with
//! dmu-geom's robust slab and watertight triangle tests, so rays along faces
//! and edges and axis-parallel rays are answered exactly.

use std::sync::OnceLock;
use std::time::Duration;

use dmu_geom::{Aabb3f, Ray3d, RayBoxTest3d, RayTriTest3d};
use dmu_scene::{ChunkId, Scene};
use glam::{Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::bvh2::Bvh2;
use obvhs::triangle::Triangle;

use crate::stack::{Stack, reach};

/// Chunks of at most this many triangles are tested without a BVH.
const BRUTE_FORCE_MAX: u32 = 16;

/// A node of a [`ChunkBvh`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhNode {
    /// Encloses the node's triangles, in the chunk's part-local coordinates.
    pub bounds: Aabb3f,
    /// Triangles of a leaf; 0 for an inner node.
    pub count: u32,
    /// A leaf's first entry in [`ChunkBvh::triangles`]; an inner node's first
    /// child (the second is at `first + 1`).
    pub first: u32,
}

/// A chunk's BVH: node 0 is the root.
#[derive(Debug)]
pub struct ChunkBvh {
    nodes: Vec<BvhNode>,
    triangles: Vec<u32>,
}

impl ChunkBvh {
    /// The nodes; node 0 is the root.
    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    /// The leaves' triangles, as offsets from the chunk's first triangle.
    pub fn triangles(&self) -> &[u32] {
        &self.triangles
    }
}

/// The lazily built BVHs of all chunks of a scene (chunks of at most 16
/// triangles have none: they are tested whole).
#[derive(Debug)]
pub struct ChunkBvhCache {
    slots: Vec<OnceLock<Option<ChunkBvh>>>,
}

/// A triangle hit inside one chunk: mesh-relative triangle index and parameter.
#[derive(Clone, Copy, Debug)]
pub struct LocalHit {
    pub triangle: u32,
    pub t: f64,
}

impl ChunkBvhCache {
    /// No BVH built yet, for a scene of `chunks` chunks.
    pub fn new(chunks: usize) -> Self {
        Self {
            slots: (0..chunks).map(|_| OnceLock::new()).collect(),
        }
    }

    /// Chunks whose BVH has been built.
    pub fn built(&self) -> usize {
        self.slots.iter().filter(|s| s.get().is_some()).count()
    }

    /// The chunk's BVH, built on first use; `None` for a chunk small enough to
    /// test whole. Panics when the chunk's geometry is not loaded.
    pub fn get(&self, scene: &Scene, chunk: ChunkId) -> Option<&ChunkBvh> {
        self.slots[chunk.index()]
            .get_or_init(|| build(scene, chunk))
            .as_ref()
    }

    /// Calls `visit` with every triangle of `chunk` whose BVH leaf the local ray
    /// reaches before `t_max`, nearer subtrees first; `visit` returns the new
    /// `t_max` (to shrink the search for the nearest hit) or the old one (to
    /// see every hit). Panics when the chunk's geometry is not loaded.
    pub fn for_each_hit(
        &self,
        scene: &Scene,
        chunk: ChunkId,
        local: &Ray3d,
        mut t_max: f64,
        visit: &mut dyn FnMut(LocalHit) -> f64,
    ) {
        let c = scene.chunk(chunk);
        let tri_test = RayTriTest3d::new(local);
        let mut test = |t: u32, corners: [Vec3; 3], t_max: f64| {
            let [a, b, d] = corners.map(Vec3::as_dvec3);
            match tri_test.hit(a, b, d, 0.0, t_max) {
                Some(h) => visit(LocalHit {
                    triangle: c.triangles.start + t,
                    t: h.t,
                }),
                None => t_max,
            }
        };
        let geometry = scene
            .chunk_geometry(chunk)
            .expect("picking a chunk whose geometry is loaded");
        let corners = |t: u32| {
            let i = 3 * t as usize;
            [0, 1, 2].map(|k| geometry.positions[geometry.indices[i + k] as usize])
        };
        let Some(bvh) = self.get(scene, chunk) else {
            for t in 0..c.triangle_count() {
                t_max = test(t, corners(t), t_max);
            }
            return;
        };
        let box_test = RayBoxTest3d::new(local);
        let enter = |n: u32, t_max: f64| {
            box_test
                .hit(&bvh.nodes[n as usize].bounds.as_dvec(), reach(t_max))
                .map(|(t, _)| t)
        };
        // Subtrees still to see, with the distance at which the ray enters them.
        let mut stack = Stack::new();
        let mut node = enter(0, t_max).map(|_| 0);
        loop {
            if let Some(n) = node {
                let BvhNode { count, first, .. } = bvh.nodes[n as usize];
                if count == 0 {
                    node = match (enter(first, t_max), enter(first + 1, t_max)) {
                        (Some(a), Some(b)) => {
                            let (near, far, t_far) = if a <= b {
                                (first, first + 1, b)
                            } else {
                                (first + 1, first, a)
                            };
                            stack.push((far, t_far));
                            Some(near)
                        }
                        (Some(_), None) => Some(first),
                        (None, Some(_)) => Some(first + 1),
                        (None, None) => None,
                    };
                    continue;
                }
                let leaf = first as usize..(first + count) as usize;
                for &t in &bvh.triangles[leaf] {
                    t_max = test(t, corners(t), t_max);
                }
            }
            node = loop {
                match stack.pop() {
                    None => return,
                    Some((n, t)) if t <= reach(t_max) => break Some(n),
                    Some(_) => {}
                }
            };
        }
    }
}

fn build(scene: &Scene, chunk: ChunkId) -> Option<ChunkBvh> {
    let c = scene.chunk(chunk);
    if c.triangle_count() <= BRUTE_FORCE_MAX {
        return None;
    }
    let tris: Vec<Triangle> = c
        .triangles
        .clone()
        .map(|t| {
            let [v0, v1, v2] = scene.triangle_local(c.mesh, chunk, t).map(Vec3A::from);
            Triangle { v0, v1, v2 }
        })
        .collect();
    let mut build_time = Duration::ZERO;
    let bvh: Bvh2 =
        obvhs::bvh2::builder::build_bvh2(&tris, BvhBuildParams::very_fast_build(), &mut build_time);
    let nodes = bvh
        .nodes
        .iter()
        .map(|n| BvhNode {
            bounds: Aabb3f::new(n.aabb().min.into(), n.aabb().max.into()),
            count: n.prim_count,
            first: n.first_index,
        })
        .collect();
    Some(ChunkBvh {
        nodes,
        triangles: bvh.primitive_indices,
    })
}
