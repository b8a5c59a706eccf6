//! Queries: nearest and all ray hits, parts in a box, frustum traversal.

use dmu_geom::{Aabb3d, Containment, Frustum, Plane, Ray3d, RayBoxTest3d, RayTriTest3d};
use dmu_scene::{ChunkId, PartId, Scene};
use glam::DVec3;

use crate::stack::{Stack, reach};
use crate::tree::{CellId, EntryId, Kind, Tree};

/// A ray hit on a triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The part hit.
    pub part: PartId,
    /// Its chunk.
    pub chunk: ChunkId,
    /// Triangle index within the part's mesh.
    pub triangle: u32,
    /// Ray parameter: the hit is at `origin + t * dir` (the distance for a unit `dir`).
    pub t: f64,
    /// World point, f64.
    pub point: DVec3,
    /// Unit world normal of the triangle, facing the ray's origin.
    pub normal: DVec3,
}

/// A hit as reports print it, named from the scene: the one definition of the
/// fields of `dmu pick --json`, the viewer's pick report and the Python
/// module's `pick` (serialized with serde, so they cannot drift apart).
///
/// The fields are in alphabetical order, the order serde_json's `Value` (a
/// sorted map) prints them in: a report serialized straight (`dmu pick
/// --rays --json`) and one serialized through a `Value` (`--ray --json`)
/// are the same bytes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HitReport<'a> {
    /// Distance from the ray's origin, world units, whatever the direction's length.
    pub distance: f64,
    /// Always `true` (a miss is reported as `{"hit": false}` or `None`).
    pub hit: bool,
    /// Unit world normal, facing the ray's origin.
    pub normal: [f64; 3],
    /// The part's name.
    pub part: &'a str,
    /// The part's id.
    pub part_id: u32,
    /// The part's full assembly path.
    pub path: String,
    /// World point.
    pub point: [f64; 3],
    /// What the source file says of the part (an IFC element's `GlobalId`
    /// and `IfcClass`, a STEP product's name, a glTF node's `extras`), keys
    /// in order.
    pub properties: std::collections::BTreeMap<&'a str, &'a str>,
    /// Triangle index within the part's mesh.
    pub triangle: u32,
}

impl<'a> HitReport<'a> {
    /// The report of `hit` on a ray whose direction is `ray_length` long.
    pub fn new(scene: &'a Scene, hit: &Hit, ray_length: f64) -> Self {
        Self {
            hit: true,
            part: scene.part_name(hit.part),
            part_id: hit.part.0,
            path: scene.part_path(hit.part),
            triangle: hit.triangle,
            distance: hit.t * ray_length,
            point: hit.point.to_array(),
            normal: hit.normal.to_array(),
            properties: scene.node_properties(scene.part(hit.part).node).collect(),
        }
    }
}

/// What a frustum visitor is told about a node.
#[derive(Clone, Copy, Debug)]
pub struct FrustumNode {
    /// World box of the node.
    pub bounds: Aabb3d,
    /// How the box meets the frustum (never `Outside`: those are skipped).
    pub containment: Containment,
    /// The cell, when the node is a leaf.
    pub cell: Option<CellId>,
    /// The node's slot in the tree (what the renderer's mirror numbers after
    /// the entries).
    pub slot: u32,
}

impl Tree {
    /// The nearest hit of a world ray on a visible part, exact: the f64 ray goes to
    /// each part's local frame and a per-chunk BVH finds the triangle. Hidden parts
    /// are skipped.
    pub fn pick(&self, scene: &Scene, ray: &Ray3d) -> Option<Hit> {
        self.pick_kept(scene, ray, &[])
    }

    /// [`Tree::pick`] of each ray, in order, on rayon's threads (the
    /// current pool's). Every chunk BVH a ray needs is built on first use.
    pub fn pick_many(&self, scene: &Scene, rays: &[Ray3d]) -> Vec<Option<Hit>> {
        use rayon::prelude::*;
        rays.par_iter().map(|ray| self.pick(scene, ray)).collect()
    }

    /// The nearest hit of a world ray on what a section keeps: hits on the
    /// negative side of any of `section`'s planes (cut away, not drawn) are
    /// passed through, as the eye sees through them. No planes: [`Tree::pick`].
    pub fn pick_kept(&self, scene: &Scene, ray: &Ray3d, section: &[Plane]) -> Option<Hit> {
        self.pick_loaded(scene, ray, section).0
    }

    /// [`Tree::pick_kept`] over the parts whose mesh is loaded (a store's
    /// skeleton loads meshes on demand), and the chunk instances whose mesh
    /// is not loaded that the ray meets before that hit (all it meets when
    /// there is none), nearest first. With none, the hit is exact; else
    /// loading their meshes and picking again may find a nearer one.
    pub fn pick_loaded(
        &self,
        scene: &Scene,
        ray: &Ray3d,
        section: &[Plane],
    ) -> (Option<Hit>, Vec<EntryId>) {
        let mut best: Option<Found> = None;
        let mut unloaded = Vec::new();
        self.ray_search(
            scene,
            ray,
            &mut |hit| {
                let point = ray.at(hit.t);
                let kept = section.iter().all(|p| p.signed_distance(point) >= 0.0);
                if kept && best.is_none_or(|b| hit.t < b.t) {
                    best = Some(hit);
                }
                best.map_or(f64::INFINITY, |b| b.t)
            },
            &mut |entry, t| unloaded.push((t, entry)),
        );
        let limit = best.map_or(f64::INFINITY, |b| b.t);
        unloaded.retain(|&(t, _)| t < limit);
        unloaded.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.0.cmp(&b.1.0)));
        let best = best.map(|f| f.hit(scene, ray));
        (best, unloaded.into_iter().map(|(_, e)| e).collect())
    }

    /// Every hit of a world ray on visible parts, nearest first. A ray through
    /// the shared edge or vertex of triangles of one part hits each of them at the
    /// same point: such hits (same part, `t` equal to 1e-12 relative) count once.
    pub fn pick_all(&self, scene: &Scene, ray: &Ray3d) -> Vec<Hit> {
        let mut hits = Vec::new();
        self.ray_search(
            scene,
            ray,
            &mut |hit| {
                hits.push(hit.hit(scene, ray));
                f64::INFINITY
            },
            &mut |_, _| {},
        );
        hits.sort_by(|a, b| {
            a.part
                .cmp(&b.part)
                .then(a.t.total_cmp(&b.t))
                .then(a.triangle.cmp(&b.triangle))
        });
        hits.dedup_by(|b, a| a.part == b.part && (b.t - a.t).abs() <= 1e-12 * a.t.abs().max(1.0));
        hits.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.part.cmp(&b.part)));
        hits
    }

    /// Nearest-first traversal: depth first, the nearer child first.
    /// `found` gets each hit and returns the farthest `t` still of interest (the
    /// hit's own `t` for the nearest hit, infinity for all hits); nodes that
    /// start beyond it are skipped. Chunk instances whose mesh is not
    /// loaded are not searched: `unloaded` gets each with the `t` at which
    /// the ray enters its box.
    fn ray_search(
        &self,
        scene: &Scene,
        ray: &Ray3d,
        found: &mut dyn FnMut(Found) -> f64,
        unloaded: &mut dyn FnMut(EntryId, f64),
    ) {
        if !(ray.origin.is_finite() && ray.dir.is_finite()) || ray.dir == DVec3::ZERO {
            return;
        }
        let test = RayBoxTest3d::new(ray);
        let mut t_max = f64::INFINITY;
        let enter = |n: u32, t_max: f64| {
            test.hit(&self.nodes[n as usize].bounds, reach(t_max))
                .map(|h| h.0)
        };
        // Depth first, the nearer child first; a subtree waits on the stack
        // with the distance at which the ray enters it, and is dropped once
        // a hit is nearer.
        let mut stack = Stack::new();
        if let Some(t) = enter(self.root, t_max) {
            stack.push((self.root, t));
        }
        while let Some((node, t)) = stack.pop() {
            if t > reach(t_max) {
                continue;
            }
            match self.nodes[node as usize].kind {
                Kind::Internal([a, b]) => match (enter(a, t_max), enter(b, t_max)) {
                    (Some(ta), Some(tb)) if ta <= tb => {
                        stack.push((b, tb));
                        stack.push((a, ta));
                    }
                    (Some(ta), Some(tb)) => {
                        stack.push((a, ta));
                        stack.push((b, tb));
                    }
                    (Some(ta), None) => stack.push((a, ta)),
                    (None, Some(tb)) => stack.push((b, tb)),
                    (None, None) => {}
                },
                Kind::Leaf(cell) => {
                    // The entries' boxes first: the part's pose and frame are
                    // fetched only for entries the ray meets. A cell keeps each
                    // part's entries together, so its frame is made once.
                    let mut frame: Option<(PartId, Option<PartFrame>)> = None;
                    for &e in &self.cells[cell as usize].entries {
                        let entry = &self.entries[e as usize];
                        let Some((t_enter, _)) = test.hit(&entry.bounds, reach(t_max)) else {
                            continue;
                        };
                        let part = entry.part;
                        if frame.as_ref().is_none_or(|(p, _)| *p != part) {
                            frame = Some((part, PartFrame::new(scene, part, ray)));
                        }
                        let Some((_, Some(f))) = &frame else {
                            continue;
                        };
                        if !f.loaded {
                            unloaded(EntryId(e), t_enter);
                            continue;
                        }
                        self.bvhs
                            .for_each_hit(scene, entry.chunk, &f.local, t_max, &mut |h| {
                                let hit = Found {
                                    part,
                                    chunk: entry.chunk,
                                    triangle: h.triangle,
                                    t: h.t,
                                };
                                t_max = t_max.min(found(hit));
                                t_max
                            });
                    }
                }
                Kind::Free => unreachable!("free node in the tree"),
            }
        }
    }

    /// Visible parts with at least one triangle touching `query` (boundaries count),
    /// sorted by id. Exact: triangles are tested against the box in world f64.
    pub fn parts_in_box(&self, scene: &Scene, query: &Aabb3d) -> Vec<PartId> {
        let mut parts = Vec::new();
        let mut stack = vec![self.root];
        while let Some(node) = stack.pop() {
            let n = &self.nodes[node as usize];
            if !n.bounds.overlaps(query) {
                continue;
            }
            match n.kind {
                Kind::Internal(c) => stack.extend(c),
                Kind::Leaf(cell) => {
                    for (part, entries) in self.cell_groups(CellId(cell)) {
                        if scene.part(part).hidden || parts.last() == Some(&part) {
                            continue;
                        }
                        let hit = entries.iter().any(|&e| {
                            let entry = &self.entries[e as usize];
                            entry.bounds.overlaps(query)
                                && chunk_touches_box(scene, part, entry.chunk, query)
                        });
                        if hit {
                            parts.push(part);
                        }
                    }
                }
                Kind::Free => unreachable!("free node in the tree"),
            }
        }
        parts.sort_unstable();
        parts.dedup();
        parts
    }

    /// Visits nodes that meet the frustum, parents before children; `visit`
    /// returns whether to descend. Subtrees entirely inside are still visited
    /// (the renderer and loader want the cells), with `Inside` passed down without
    /// further plane tests.
    pub fn visit_frustum(&self, frustum: &Frustum, visit: &mut dyn FnMut(&FrustumNode) -> bool) {
        let mut stack = vec![(self.root, Containment::Intersecting)];
        while let Some((node, parent)) = stack.pop() {
            let n = &self.nodes[node as usize];
            let containment = match parent {
                Containment::Inside => Containment::Inside,
                _ => frustum.test_aabb(&n.bounds),
            };
            if containment == Containment::Outside || n.bounds.is_empty() {
                continue;
            }
            let cell = match n.kind {
                Kind::Leaf(c) => Some(CellId(c)),
                _ => None,
            };
            if visit(&FrustumNode {
                bounds: n.bounds,
                containment,
                cell,
                slot: node,
            }) && let Kind::Internal(children) = n.kind
            {
                stack.extend(children.map(|c| (c, containment)));
            }
        }
    }
}

/// A visible part as a ray search sees it: the ray in its frame, and
/// whether its mesh is loaded.
struct PartFrame {
    loaded: bool,
    local: Ray3d,
}

impl PartFrame {
    /// `None` for a hidden part.
    fn new(scene: &Scene, part: PartId, ray: &Ray3d) -> Option<Self> {
        if scene.part(part).hidden {
            return None;
        }
        Some(Self {
            loaded: scene.part_mesh(part).is_loaded(),
            local: ray.to_local(&scene.part_world(part)),
        })
    }
}

/// A hit as a ray search finds it; the world point and normal are made
/// only for the hits kept ([`Found::hit`]).
#[derive(Clone, Copy, Debug)]
struct Found {
    part: PartId,
    chunk: ChunkId,
    /// Within the part's mesh.
    triangle: u32,
    t: f64,
}

impl Found {
    /// The world hit of `ray`.
    fn hit(self, scene: &Scene, ray: &Ray3d) -> Hit {
        let [a, b, c] = scene.triangle_local(scene.part(self.part).mesh, self.chunk, self.triangle);
        let normal_matrix = scene.part_world(self.part).matrix3.inverse().transpose();
        let n = (normal_matrix * (b - a).cross(c - a).as_dvec3()).normalize_or_zero();
        Hit {
            part: self.part,
            chunk: self.chunk,
            triangle: self.triangle,
            t: self.t,
            point: ray.at(self.t),
            normal: if n.dot(ray.dir) > 0.0 { -n } else { n },
        }
    }
}

/// The nearest hit's `t` of a world ray by testing every triangle of every
/// visible part whose mesh is loaded, in the part's frame, with the same
/// watertight test as [`Tree::pick`], and no tree and no BVH: the oracle
/// that `dmu bench pick` and the tests hold picks to, exactly.
pub fn pick_brute_force(scene: &Scene, ray: &Ray3d) -> Option<f64> {
    let mut best: Option<f64> = None;
    let parts = scene
        .part_ids()
        .filter(|&p| !scene.part(p).hidden && scene.part_mesh(p).is_loaded());
    for part in parts {
        let test = RayTriTest3d::new(&ray.to_local(&scene.part_world(part)));
        let mesh = scene.part(part).mesh;
        for chunk in scene.mesh(mesh).chunk_ids() {
            for t in scene.chunk(chunk).triangles.clone() {
                let [a, b, c] = scene.triangle_local(mesh, chunk, t).map(|v| v.as_dvec3());
                if let Some(h) = test.hit(a, b, c, 0.0, best.unwrap_or(f64::INFINITY)) {
                    best = Some(h.t);
                }
            }
        }
    }
    best
}

/// Whether any triangle of the chunk, in world f64, touches the box.
pub fn chunk_touches_box(scene: &Scene, part: PartId, chunk: ChunkId, query: &Aabb3d) -> bool {
    let world = scene.part_world(part);
    let c = scene.chunk(chunk);
    let center = query.center();
    let half = query.extent() * 0.5;
    c.triangles.clone().any(|t| {
        let tri = scene
            .triangle_local(c.mesh, chunk, t)
            .map(|v| world.transform_point3(v.as_dvec3()) - center);
        triangle_box_overlap(tri, half)
    })
}

/// Separating-axis test of a triangle against a box centred at the origin with
/// half extents `h` (Akenine-Möller 2001); touching counts as overlapping.
pub fn triangle_box_overlap(v: [DVec3; 3], h: DVec3) -> bool {
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    // The box's face normals.
    for axis in 0..3 {
        let (lo, hi) = (
            v[0][axis].min(v[1][axis]).min(v[2][axis]),
            v[0][axis].max(v[1][axis]).max(v[2][axis]),
        );
        if lo > h[axis] || hi < -h[axis] {
            return false;
        }
    }
    // The triangle's normal.
    let n = e[0].cross(e[1]);
    let r = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
    let d = n.dot(v[0]);
    if d.abs() > r {
        return false;
    }
    // Nine edge cross products.
    for edge in e {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            let a = axis.cross(edge);
            if a == DVec3::ZERO {
                continue;
            }
            let p = v.map(|p| a.dot(p));
            let r = h.x * a.x.abs() + h.y * a.y.abs() + h.z * a.z.abs();
            if p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r {
                return false;
            }
        }
    }
    true
}
