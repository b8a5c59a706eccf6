//! `grid`: n×n×n axis-aligned boxes, the trivial oracle for tests.

use glam::{DAffine3, DVec3, Vec3};

use dmu_scene::MeshData;
use dmu_scene::{Scene, SceneBuilder};

/// The 24 vertices and 12 triangles of a box from `min` to `max`, with flat
/// outward normals and counter-clockwise outward faces.
pub(crate) fn box_mesh(
    name: &str,
    min: Vec3,
    max: Vec3,
    material: dmu_scene::MaterialId,
) -> MeshData {
    let mut mesh = MeshData {
        name: name.into(),
        ..MeshData::default()
    };
    for axis in 0..3 {
        for positive in [false, true] {
            let mut n = Vec3::ZERO;
            n[axis] = if positive { 1.0 } else { -1.0 };
            // Two tangent axes ordered so (u × v) points along n.
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let (u, v) = if positive { (u, v) } else { (v, u) };
            let corner = |a: bool, b: bool| {
                let mut p = if positive { max } else { min };
                p[u] = if a { max[u] } else { min[u] };
                p[v] = if b { max[v] } else { min[v] };
                p
            };
            let quad = [
                corner(false, false),
                corner(true, false),
                corner(true, true),
                corner(false, true),
            ];
            mesh.push_primitive(&quad, &[n; 4], &[0, 1, 2, 0, 2, 3], material);
        }
    }
    mesh
}

/// `n³` unit-ish boxes of side `size` on a lattice of pitch `spacing`, each its own
/// part instancing one shared box mesh, under one node per layer.
pub fn grid(n: u32, spacing: f64, size: f32, chunk_triangles: u32) -> Scene {
    let mut b = SceneBuilder::new(format!("grid{n}"), chunk_triangles);
    let material = b.add_material("box", [0.6, 0.65, 0.7, 1.0]);
    let half = Vec3::splat(size * 0.5);
    let mesh = b.add_mesh(&box_mesh("box", -half, half, material));
    for z in 0..n {
        let layer = b.add_node(SceneBuilder::ROOT, format!("layer{z}"), DAffine3::IDENTITY);
        for y in 0..n {
            for x in 0..n {
                let at = DVec3::new(f64::from(x), f64::from(y), f64::from(z)) * spacing;
                let node = b.add_node(
                    layer,
                    format!("box_{x}_{y}_{z}"),
                    DAffine3::from_translation(at),
                );
                b.add_part(node, mesh);
            }
        }
    }
    b.finish()
}
