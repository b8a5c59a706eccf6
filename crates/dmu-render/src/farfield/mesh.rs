//! A face's depth as a mesh: a grid over its texels, skins or holes across
//! depth discontinuities, simplified in (pixel x, pixel y, parallax) space.

use glam::{DVec3, DVec4};

use super::{BACKGROUND, FACES, FarFieldBuild, FarFieldOptions, SKIN_RATIO, face_camera};

/// How the faces were captured: `resolution` pixels a side, the tangent of
/// their half angle, the near plane, and the pixels of parallax per unit of
/// inverse depth (the cell's corner seen from its centre).
#[derive(Clone, Copy, Debug)]
pub(super) struct Lens {
    pub resolution: u32,
    pub tan_half: f64,
    pub near: f64,
    pub parallax_scale: f64,
}

/// The six faces' depths as one mesh: vertices (relative to the centre,
/// their face in `w`), indices, and where each face's indices start;
/// counts the grids' triangles in `build`.
pub(super) fn mesh_faces(
    depths: &[Vec<f32>],
    options: &FarFieldOptions,
    lens: Lens,
    build: &mut FarFieldBuild,
) -> (Vec<[f32; 4]>, Vec<u32>, [u32; 7]) {
    let mut vertices = Vec::new();
    let mut indices = Vec::new();
    let mut face_starts = [0u32; 7];
    for (face, depth) in depths.iter().enumerate() {
        let grid = face_grid(face, depth, options, lens);
        build.grid_triangles += grid.indices.len() as u64 / 3;
        let (kept, _) =
            dmu_scene::simplify_to_error(&grid.warped, &grid.indices, options.mesh_error_px as f32);
        // Keep the referenced vertices only.
        let mut remap = vec![u32::MAX; grid.relative.len()];
        for i in kept {
            let slot = &mut remap[i as usize];
            if *slot == u32::MAX {
                *slot = vertices.len() as u32;
                let p = grid.relative[i as usize];
                vertices.push([p[0], p[1], p[2], face as f32]);
            }
            indices.push(*slot);
        }
        face_starts[face + 1] = indices.len() as u32;
    }
    (vertices, indices, face_starts)
}

/// One face's depth as a grid mesh: positions relative to the centre, the
/// same in (pixel x, pixel y, parallax in pixels) for the simplifier, and
/// the triangles.
struct FaceGrid {
    relative: Vec<[f32; 3]>,
    warped: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

fn face_grid(face: usize, depth: &[f32], options: &FarFieldOptions, lens: Lens) -> FaceGrid {
    let Lens {
        resolution: r,
        tan_half,
        near,
        parallax_scale,
    } = lens;
    let step = options.grid_step.clamp(1, r);
    let unproject = face_camera(DVec3::ZERO, face, tan_half, near)
        .view_proj()
        .inverse();
    let axis = FACES[face].0;
    let samples: Vec<u32> = (0..r)
        .step_by(step as usize)
        .chain((!(r - 1).is_multiple_of(step)).then_some(r - 1))
        .collect();
    let n = samples.len();
    let mut slot = vec![u32::MAX; n * n];
    let mut grid = FaceGrid {
        relative: Vec::new(),
        warped: Vec::new(),
        indices: Vec::new(),
    };
    // A sample that hit nothing lies on a background far behind the
    // farthest that did, so thin parts between samples and silhouettes
    // against the sky still get a surface to be textured onto.
    let at = |x: u32, y: u32, d: f64| {
        let ndc = DVec4::new(
            (f64::from(x) + 0.5) / f64::from(r) * 2.0 - 1.0,
            1.0 - (f64::from(y) + 0.5) / f64::from(r) * 2.0,
            d,
            1.0,
        );
        let p = unproject * ndc;
        p.truncate() / p.w
    };
    let farthest = samples
        .iter()
        .flat_map(|&y| samples.iter().map(move |&x| (x, y)))
        .map(|(x, y)| depth[(y * r + x) as usize])
        .filter(|&d| d > 0.0)
        .fold(f32::MAX, f32::min);
    if farthest == f32::MAX {
        return grid;
    }
    let background = at(0, 0, f64::from(farthest)).dot(axis) * BACKGROUND;
    let mut distance = vec![0.0f64; n * n];
    for (j, &y) in samples.iter().enumerate() {
        for (i, &x) in samples.iter().enumerate() {
            let d = depth[(y * r + x) as usize];
            let p = if d > 0.0 {
                at(x, y, f64::from(d))
            } else {
                let p = at(x, y, 1.0);
                p * (background / p.dot(axis))
            };
            let along = p.dot(axis);
            slot[j * n + i] = grid.relative.len() as u32;
            distance[j * n + i] = along;
            grid.relative.push(p.as_vec3().to_array());
            grid.warped.push([
                x as f32,
                y as f32,
                (parallax_scale / along.max(1e-30)) as f32,
            ]);
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let k = [
                j * n + i,
                j * n + i + 1,
                (j + 1) * n + i,
                (j + 1) * n + i + 1,
            ];
            if k.iter().any(|&k| slot[k] == u32::MAX) {
                continue;
            }
            if !options.skins {
                let d = k.map(|k| distance[k]);
                let (lo, hi) = d
                    .iter()
                    .fold((f64::MAX, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
                if hi > SKIN_RATIO * lo {
                    continue;
                }
            }
            let [a, b, c, d] = k.map(|k| slot[k]);
            grid.indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    grid
}
