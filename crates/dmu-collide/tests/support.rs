//! Test shapes with known distances, scenes of them, and a brute-force oracle
//! over every part pair and every triangle pair, independent of tree and BVHs.

use dmu_collide::{ClashKind, Settings, triangle_clash};
use dmu_scene::{MaterialId, MeshData, PartId, Scene, SceneBuilder, compute_normals};
use glam::{DAffine3, DVec3, Vec3};

/// A closed box centred on the origin with half extents `h`, outward
/// counter-clockwise faces, 8 shared corners.
pub fn box_mesh(h: Vec3) -> (Vec<Vec3>, Vec<u32>) {
    let positions: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        })
        .collect();
    #[rustfmt::skip]
    let indices = vec![
        0, 2, 1, 1, 2, 3, // -z
        4, 5, 6, 5, 7, 6, // +z
        0, 1, 4, 1, 5, 4, // -y
        2, 6, 3, 3, 6, 7, // +y
        0, 4, 2, 2, 4, 6, // -x
        1, 3, 5, 3, 7, 5, // +x
    ];
    (positions, indices)
}

/// A closed box like [`box_mesh`] with each face cut into `n` x `n` squares
/// (`12 n^2` triangles): with small chunks, a closed part of many chunks. The
/// grid coordinates of each axis are computed once, so the faces' shared edges
/// weld exactly and the mesh is closed.
pub fn tessellated_box_mesh(h: Vec3, n: u32) -> (Vec<Vec3>, Vec<u32>) {
    let steps = |h: f32| -> Vec<f32> {
        (0..=n)
            .map(|i| -h + 2.0 * h * (i as f32 / n as f32))
            .collect()
    };
    let axes = [steps(h.x), steps(h.y), steps(h.z)];
    let (mut positions, mut indices) = (Vec::new(), Vec::new());
    // Each face: the fixed axis and its side; (u, v) span the face so that
    // u x v points outwards.
    for (fixed, u, v) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] {
        for (side, (u, v)) in [(n as usize, (u, v)), (0, (v, u))] {
            let first = positions.len() as u32;
            for j in 0..=n as usize {
                for i in 0..=n as usize {
                    let mut p = [0.0; 3];
                    p[fixed] = axes[fixed][side];
                    p[u] = axes[u][i];
                    p[v] = axes[v][j];
                    positions.push(Vec3::from_array(p));
                }
            }
            let at = |i: u32, j: u32| first + j * (n + 1) + i;
            for j in 0..n {
                for i in 0..n {
                    let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                    indices.extend([a, b, c, a, c, d]);
                }
            }
        }
    }
    (positions, indices)
}

/// A closed prism approximating a cylinder: axis along z, centred on the origin,
/// `sides` vertices on each rim at angles `2πk/sides` (so with an even count
/// there are rim vertices at +x and -x, exactly at ±radius), fan-triangulated caps.
pub fn cylinder_mesh(radius: f32, height: f32, sides: u32) -> (Vec<Vec3>, Vec<u32>) {
    let z = height * 0.5;
    let mut positions = Vec::new();
    for k in 0..sides {
        let a = std::f64::consts::TAU * f64::from(k) / f64::from(sides);
        let (x, y) = (
            (a.cos() * f64::from(radius)) as f32,
            (a.sin() * f64::from(radius)) as f32,
        );
        // cos and sin of 0 and π are exactly ±1 and 0 only up to rounding.
        let (x, y) = if k == 0 {
            (radius, 0.0)
        } else if 2 * k == sides {
            (-radius, 0.0)
        } else {
            (x, y)
        };
        positions.push(Vec3::new(x, y, -z));
        positions.push(Vec3::new(x, y, z));
    }
    let bottom = positions.len() as u32;
    positions.push(Vec3::new(0.0, 0.0, -z));
    let top = bottom + 1;
    positions.push(Vec3::new(0.0, 0.0, z));
    let mut indices = Vec::new();
    for k in 0..sides {
        let (b0, t0) = (2 * k, 2 * k + 1);
        let (b1, t1) = (2 * ((k + 1) % sides), 2 * ((k + 1) % sides) + 1);
        indices.extend([b0, b1, t1, b0, t1, t0]);
        indices.extend([bottom, b1, b0]);
        indices.extend([top, t0, t1]);
    }
    (positions, indices)
}

/// A part to put in a scene.
pub struct Shape {
    pub name: String,
    pub mesh: (Vec<Vec3>, Vec<u32>),
    pub world: DAffine3,
}

impl Shape {
    pub fn new(name: &str, mesh: (Vec<Vec3>, Vec<u32>), world: DAffine3) -> Self {
        Self {
            name: name.into(),
            mesh,
            world,
        }
    }
}

/// A scene with one part per shape, in order (part `i` is shape `i`).
pub fn scene_of(shapes: &[Shape], chunk_triangles: u32) -> Scene {
    let mut b = SceneBuilder::new("test", chunk_triangles);
    let material = b.add_material("m", [1.0; 4]);
    for s in shapes {
        let mesh = b.add_mesh(&mesh_data(&s.name, &s.mesh.0, &s.mesh.1, material));
        let node = b.add_node(SceneBuilder::ROOT, s.name.clone(), s.world);
        b.add_part(node, mesh);
    }
    b.finish()
}

pub fn mesh_data(
    name: &str,
    positions: &[Vec3],
    indices: &[u32],
    material: MaterialId,
) -> MeshData {
    let mut data = MeshData {
        name: name.into(),
        ..MeshData::default()
    };
    data.push_primitive(
        positions,
        &compute_normals(positions, indices),
        indices,
        material,
    );
    data
}

/// A clash as the oracle sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expected {
    pub a: PartId,
    pub b: PartId,
    pub kind: ClashKind,
    pub distance: f64,
}

/// Every triangle of a part in world f64, re-wound if the part is mirrored.
pub fn world_triangles(scene: &Scene, part: PartId) -> Vec<[DVec3; 3]> {
    let world = scene.part_world(part);
    let mirrored = world.matrix3.determinant() < 0.0;
    let mesh = scene.part_mesh(part);
    let mut out = Vec::new();
    for c in mesh.chunk_ids() {
        for t in scene.chunk(c).triangles.clone() {
            let [a, b, d] = scene
                .triangle_local(scene.part(part).mesh, c, t)
                .map(|v| world.transform_point3(v.as_dvec3()));
            out.push(if mirrored { [a, d, b] } else { [a, b, d] });
        }
    }
    out
}

/// The documented contact tolerance of a part.
pub fn tolerance(scene: &Scene, part: PartId, relative: f64) -> f64 {
    let b = scene.part_mesh(part).bounds;
    let m = scene.part_world(part).matrix3;
    let stretch = m
        .x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length());
    let local = b.min.abs().max(b.max.abs()).max_element();
    relative * stretch * f64::from(local.max(b.extent().length()))
}

/// Möller–Trumbore, f64, both sides, `t > 0`.
fn ray_hits(origin: DVec3, dir: DVec3, v: &[DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let s = origin - v[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let w = dir.dot(q) / det;
    let t = e2.dot(q) / det;
    (u >= 0.0 && w >= 0.0 && u + w <= 1.0 && t > 0.0).then_some(t)
}

/// Whether a point is inside a closed triangle set: majority of three ray parities.
pub fn brute_inside(p: DVec3, triangles: &[[DVec3; 3]]) -> bool {
    let dirs = [
        DVec3::new(0.3214, 0.5431, 0.7762),
        DVec3::new(-0.6127, 0.2719, -0.7423),
        DVec3::new(0.1373, -0.9111, 0.3887),
    ];
    dirs.iter()
        .filter(|&&d| {
            let mut ts: Vec<f64> = triangles.iter().filter_map(|t| ray_hits(p, d, t)).collect();
            ts.sort_by(f64::total_cmp);
            ts.dedup_by(|x, y| (*x - *y).abs() <= 1e-12 * y.abs().max(1.0));
            ts.len() % 2 == 1
        })
        .count()
        >= 2
}

/// Brute force: every moved visible part against every other visible part (a
/// pair of moved parts once), every triangle pair in world f64. `closed[p]`
/// says whether part `p` may contain others. Containment is tested whenever
/// the inner part's box is inside the outer's, however far the inner part is
/// from the outer's chunks.
pub fn oracle(
    scene: &Scene,
    moved: &[PartId],
    settings: &Settings,
    closed: &[bool],
) -> Vec<Expected> {
    let mut out = Vec::new();
    let visible = |p: PartId| !scene.part(p).hidden;
    for a in scene.part_ids().filter(|&p| visible(p)) {
        for b in scene.part_ids().filter(|&p| visible(p)) {
            let pair_wanted = a != b
                && moved.contains(&a)
                && !(moved.contains(&b) && b < a)
                && !settings.allow.allows(a, b);
            if !pair_wanted {
                continue;
            }
            let tol = tolerance(scene, a, settings.contact_tolerance).max(tolerance(
                scene,
                b,
                settings.contact_tolerance,
            ));
            let (ta, tb) = (world_triangles(scene, a), world_triangles(scene, b));
            let mut best = f64::INFINITY;
            let mut hard = false;
            let reach = settings.clearance.max(tol);
            for x in &ta {
                for y in &tb {
                    if let Some(c) = triangle_clash(x, y, tol, reach) {
                        best = best.min(c.distance);
                        hard |= c.penetrating;
                    }
                }
            }
            let contains = |outer: PartId, inner: PartId, tri: &[[DVec3; 3]]| {
                closed[outer.index()]
                    && scene
                        .part_world_bounds(outer)
                        .contains(&scene.part_world_bounds(inner))
                    && brute_inside(
                        scene
                            .part_world(inner)
                            .transform_point3(scene.part_mesh(inner).positions[0].as_dvec3()),
                        tri,
                    )
            };
            hard = hard || contains(b, a, &tb) || contains(a, b, &ta);
            let kind = if hard {
                ClashKind::Hard
            } else if best <= tol {
                ClashKind::Contact
            } else if best < settings.clearance {
                ClashKind::Soft
            } else {
                continue;
            };
            let distance = if hard { 0.0 } else { best };
            out.push(Expected {
                a,
                b,
                kind,
                distance,
            });
        }
    }
    out
}
