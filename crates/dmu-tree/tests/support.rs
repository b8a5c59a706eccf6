//! Random scenes and brute-force oracles independent of the tree's own tests.

use dmu_geom::{Aabb3d, Ray3d};
use dmu_samples::Rng;
use dmu_scene::{MeshData, PartId, Scene, SceneBuilder};
use dmu_tree::TreeOptions;
use glam::{DAffine3, DQuat, DVec3, Vec3};

/// Tree options with small cells (24 triangles), so that the random test
/// scenes make deep trees of many cells.
pub fn small_cells() -> TreeOptions {
    TreeOptions {
        cell_triangles: 24,
        ..TreeOptions::default()
    }
}

/// A random transform: rotation about a random axis, translation within `reach`
/// of `origin`.
pub fn random_transform(rng: &mut Rng, origin: DVec3, reach: f64) -> DAffine3 {
    let axis = DVec3::new(
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
    )
    .normalize_or(DVec3::Z);
    let rotation = DQuat::from_axis_angle(axis, rng.range(-3.2, 3.2));
    let t = origin
        + DVec3::new(
            rng.range(-reach, reach),
            rng.range(-reach, reach),
            rng.range(-reach, reach),
        );
    DAffine3::from_rotation_translation(rotation, t)
}

/// A random scene: `parts` parts sharing some meshes of random triangles (some
/// flat, some with degenerate triangles), at random transforms near `origin`.
/// Small chunks so meshes split into several.
pub fn random_scene(seed: u64, parts: usize, origin: DVec3) -> Scene {
    random_scene_sized(seed, parts, origin, 30, 6)
}

/// [`random_scene`] with up to `triangles` triangles a mesh, in chunks of
/// `chunk_triangles` (over 16, so picks go through chunk BVHs).
pub fn random_scene_sized(
    seed: u64,
    parts: usize,
    origin: DVec3,
    triangles: u64,
    chunk_triangles: u32,
) -> Scene {
    let mut rng = Rng::new(seed);
    let mut b = SceneBuilder::new("random", chunk_triangles);
    let material = b.add_material("m", [1.0; 4]);
    let meshes: Vec<_> = (0..(parts / 2).max(1))
        .map(|m| {
            let flat = rng.chance(0.2);
            let size = rng.range(0.5, 8.0) as f32;
            let n = 1 + rng.below(triangles) as usize;
            let mut positions = Vec::new();
            for _ in 0..3 * n {
                let mut p = Vec3::new(
                    rng.range(-1.0, 1.0) as f32,
                    rng.range(-1.0, 1.0) as f32,
                    rng.range(-1.0, 1.0) as f32,
                ) * size;
                if flat {
                    p.z = 0.0;
                }
                positions.push(p);
            }
            if rng.chance(0.3) {
                positions[1] = positions[0]; // a degenerate triangle
            }
            let indices: Vec<u32> = (0..3 * n as u32).collect();
            let normals = dmu_scene::compute_normals(&positions, &indices);
            let mut data = MeshData {
                name: format!("mesh{m}"),
                ..MeshData::default()
            };
            data.push_primitive(&positions, &normals, &indices, material);
            b.add_mesh(&data)
        })
        .collect();
    for p in 0..parts {
        let world = random_transform(&mut rng, origin, 20.0);
        let node = b.add_node(SceneBuilder::ROOT, format!("part{p}"), world);
        b.add_part(node, meshes[rng.below(meshes.len() as u64) as usize]);
    }
    b.finish()
}

/// Möller–Trumbore in f64 on world-space vertices.
fn moller_trumbore(ray: &Ray3d, v: [DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let s = ray.origin - v[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let w = ray.dir.dot(q) / det;
    let t = e2.dot(q) / det;
    (u >= 0.0 && w >= 0.0 && u + w <= 1.0 && t >= 0.0).then_some(t)
}

/// Every triangle of every visible part in world f64.
pub fn world_triangles(scene: &Scene) -> Vec<(PartId, [DVec3; 3])> {
    let mut out = Vec::new();
    for part in scene.part_ids().filter(|&p| !scene.part(p).hidden) {
        let world = scene.part_world(part);
        let mesh = scene.part_mesh(part);
        for c in mesh.chunk_ids() {
            for t in scene.chunk(c).triangles.clone() {
                let tri = scene
                    .triangle_local(scene.part(part).mesh, c, t)
                    .map(|v| world.transform_point3(v.as_dvec3()));
                out.push((part, tri));
            }
        }
    }
    out
}

/// Nearest hit over all triangles: (t, part).
pub fn brute_pick(triangles: &[(PartId, [DVec3; 3])], ray: &Ray3d) -> Option<(f64, PartId)> {
    brute_pick_where(triangles, ray, |_| true)
}

/// Nearest hit over all triangles whose hit point `keep` accepts: (t, part).
pub fn brute_pick_where(
    triangles: &[(PartId, [DVec3; 3])],
    ray: &Ray3d,
    keep: impl Fn(DVec3) -> bool,
) -> Option<(f64, PartId)> {
    triangles
        .iter()
        .filter_map(|(p, v)| moller_trumbore(ray, *v).map(|t| (t, *p)))
        .filter(|(t, _)| keep(ray.at(*t)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

/// Whether a triangle meets a box, by clipping it against the six faces
/// (Sutherland–Hodgman); points on a face are kept, so touching counts.
pub fn clip_overlaps(tri: [DVec3; 3], b: &Aabb3d) -> bool {
    let mut poly: Vec<DVec3> = tri.to_vec();
    for axis in 0..3 {
        for (sign, bound) in [(1.0, b.min[axis]), (-1.0, b.max[axis])] {
            let d = |p: DVec3| sign * (p[axis] - bound);
            let mut next = Vec::new();
            for i in 0..poly.len() {
                let (a, c) = (poly[i], poly[(i + 1) % poly.len()]);
                let (da, dc) = (d(a), d(c));
                if da >= 0.0 {
                    next.push(a);
                }
                if (da >= 0.0) != (dc >= 0.0) {
                    let mut p = a + (c - a) * (da / (da - dc));
                    p[axis] = bound;
                    next.push(p);
                }
            }
            if next.is_empty() {
                return false;
            }
            poly = next;
        }
    }
    true
}

/// Visible parts with a triangle meeting the box, by clipping.
pub fn brute_parts_in_box(triangles: &[(PartId, [DVec3; 3])], b: &Aabb3d) -> Vec<PartId> {
    let mut parts: Vec<PartId> = triangles
        .iter()
        .filter(|(_, t)| clip_overlaps(*t, b))
        .map(|(p, _)| *p)
        .collect();
    parts.sort_unstable();
    parts.dedup();
    parts
}

/// A random ray from outside towards the scene's box.
pub fn random_ray(rng: &mut Rng, bounds: &Aabb3d) -> Ray3d {
    let c = bounds.center();
    let r = bounds.extent().length().max(1.0);
    let from = c + DVec3::new(
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
    )
    .normalize_or(DVec3::X)
        * r;
    let to = c + DVec3::new(
        rng.range(-0.5, 0.5),
        rng.range(-0.5, 0.5),
        rng.range(-0.5, 0.5),
    ) * bounds.extent();
    Ray3d::new(from, (to - from).normalize())
}

/// A random box inside the scene's bounds.
pub fn random_box(rng: &mut Rng, bounds: &Aabb3d) -> Aabb3d {
    let e = bounds.extent();
    let a = bounds.min + DVec3::new(rng.unit(), rng.unit(), rng.unit()) * e;
    let size = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * e * 0.3;
    Aabb3d::new(a, a + size)
}
