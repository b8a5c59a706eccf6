//! Containment: a part swallowed whole by a closed part has no triangle near the
//! outer surface, so the triangle tests see no clash; a ray-parity test tells.

use std::sync::OnceLock;

use dmu_geom::Ray3d;
use dmu_scene::{MeshId, PartId, Scene};
use dmu_tree::ChunkBvhCache;
use glam::DVec3;

/// Three fixed directions with no simple ratio between components, so a ray
/// from a modelled point rarely runs through an edge or a vertex; the majority
/// of their three parities decides.
const DIRECTIONS: [DVec3; 3] = [
    DVec3::new(0.321_4, 0.543_1, 0.776_2),
    DVec3::new(-0.612_7, 0.271_9, -0.742_3),
    DVec3::new(0.137_3, -0.911_1, 0.388_7),
];

/// Per mesh, whether it is closed: every edge, with vertices welded by exact
/// position, is shared by an even number of triangles. Only then does ray
/// parity mean inside or outside. Computed on first use.
#[derive(Debug)]
pub(crate) struct Closedness {
    slots: Vec<OnceLock<bool>>,
}

impl Closedness {
    pub fn new(meshes: usize) -> Self {
        Self {
            slots: (0..meshes).map(|_| OnceLock::new()).collect(),
        }
    }

    pub fn is_closed(&self, scene: &Scene, mesh: MeshId) -> bool {
        *self.slots[mesh.index()].get_or_init(|| mesh_is_closed(scene, mesh))
    }
}

fn mesh_is_closed(scene: &Scene, mesh: MeshId) -> bool {
    let m = scene.mesh(mesh);
    // +0.0 turns -0.0 into 0.0, so both weld.
    let key = |v: glam::Vec3| [v.x + 0.0, v.y + 0.0, v.z + 0.0].map(f32::to_bits);
    let mut edges = Vec::with_capacity(m.indices.len());
    for c in m.chunk_ids() {
        let chunk = scene.chunk(c);
        for t in chunk.triangles.clone() {
            let v = scene.triangle_local(mesh, c, t).map(key);
            for i in 0..3 {
                let (p, q) = (v[i], v[(i + 1) % 3]);
                if p != q {
                    edges.push(if p < q { (p, q) } else { (q, p) });
                }
            }
        }
    }
    if edges.is_empty() {
        return false;
    }
    edges.sort_unstable();
    edges.chunk_by(|x, y| x == y).all(|run| run.len() % 2 == 0)
}

/// Whether world point `p` lies inside closed part `outer`: the majority of three
/// ray parities against its triangles, in its local frame in f64. Hits at the
/// same distance (a ray through a shared edge) count once.
pub(crate) fn point_inside(
    scene: &Scene,
    bvhs: &ChunkBvhCache,
    outer: PartId,
    p: DVec3,
    hits: &mut Vec<f64>,
) -> bool {
    let world = scene.part_world(outer);
    let inside = DIRECTIONS
        .iter()
        .filter(|&&dir| {
            let local = Ray3d::new(p, dir).to_local(&world);
            hits.clear();
            for chunk in scene.part_mesh(outer).chunk_ids() {
                bvhs.for_each_hit(scene, chunk, &local, f64::INFINITY, &mut |hit| {
                    hits.push(hit.t);
                    f64::INFINITY
                });
            }
            hits.sort_by(f64::total_cmp);
            hits.dedup_by(|x, y| (*x - *y).abs() <= 1e-12 * y.abs().max(1.0));
            hits.len() % 2 == 1
        })
        .count();
    inside >= 2
}
