//! Which meshes bound solids with their fronts outside: the meshes whose back
//! faces a renderer may cull without changing what an eye outside them sees.

use glam::Vec3;

/// How far apart two seam vertices may lie and still be one, relative to
/// the mesh's largest coordinate: some hundred times f32 rounding there.
const SEAM_TOLERANCE: f32 = 1e-5;
/// Seams wider than this many vertices are not searched: not solid.
const MAX_SEAM_VERTICES: usize = 4096;

/// Whether the indexed triangle list `indices` over `positions` bounds solids
/// with outward windings:
/// - welded by position, every edge is walked as often in one direction as
///   in the other: no border, windings consistent across every edge. CAD
///   tessellations repeat a vertex per normal along sharp edges (equal
///   positions), and pieces placed apart round their common seam each its
///   own way, so the ends of edges left unmatched are welded again within
///   a hundred-thousandth of the mesh's largest coordinate;
/// - every connected piece encloses a volume of at least zero (an inward
///   winding, as of a cavity's own shell, encloses a negative one).
///
/// Seen from outside such a mesh, a ray reaches a back face only after
/// entering the solid through a front face of the same mesh, so culling back
/// faces hides nothing that was visible. An eye inside the material sees
/// through it instead of seeing its inner side, and a cut (section planes)
/// exposes the inside: renderers draw cut meshes without culling.
///
/// False for a mesh without triangles. Indices must be in range (as
/// [`crate::chunk_mesh`] requires).
pub fn is_solid(positions: &[Vec3], indices: &[u32]) -> bool {
    if indices.len() < 3 {
        return false;
    }
    // Weld equal positions (-0 as 0).
    let key = |i: usize| (positions[i] + Vec3::ZERO).to_array().map(f32::to_bits);
    let mut by_position: Vec<u32> = (0..positions.len() as u32).collect();
    by_position.sort_unstable_by_key(|&i| key(i as usize));
    let mut weld = vec![0u32; positions.len()];
    let mut welded = 0;
    for (k, &i) in by_position.iter().enumerate() {
        if k > 0 && key(i as usize) != key(by_position[k - 1] as usize) {
            welded += 1;
        }
        weld[i as usize] = welded;
    }
    let welded = welded as usize + 1;
    let mut at = vec![Vec3::ZERO; welded];
    for (i, &w) in weld.iter().enumerate() {
        at[w as usize] = positions[i];
    }
    let mut pieces = Pieces::new(welded);
    let open = unmatched_ends(indices, &weld, &mut pieces);
    if !open.is_empty() {
        // Weld the seams: the ends of unmatched edges lying together. Merging
        // vertices never unmatches an edge, so this only closes gaps.
        if open.len() > MAX_SEAM_VERTICES {
            return false;
        }
        let reach = positions
            .iter()
            .fold(0f32, |m, p| m.max(p.abs().max_element()));
        let tolerance = reach * SEAM_TOLERANCE;
        let mut seams = Pieces::new(welded);
        for (k, &a) in open.iter().enumerate() {
            for &b in &open[k + 1..] {
                if at[a as usize].distance(at[b as usize]) <= tolerance {
                    seams.join(a, b);
                }
            }
        }
        for w in &mut weld {
            *w = seams.root(*w);
        }
        pieces = Pieces::new(welded);
        if !unmatched_ends(indices, &weld, &mut pieces).is_empty() {
            return false;
        }
    }
    // Six times each piece's signed volume, about a point of the mesh so
    // that rounding scales with its size, not with where it sits.
    let origin = positions[indices[0] as usize].as_dvec3();
    let mut volume = vec![0.0f64; welded];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize].as_dvec3() - origin);
        volume[pieces.root(weld[t[0] as usize]) as usize] += a.dot(b.cross(c));
    }
    volume.iter().all(|&v| v >= 0.0)
}

/// The welded vertices that end an edge walked more often one way than the
/// other (none for a closed, consistently wound mesh), sorted; joins the
/// ends of every edge in `pieces`.
fn unmatched_ends(indices: &[u32], weld: &[u32], pieces: &mut Pieces) -> Vec<u32> {
    // Each edge as (low, high) with +1 walked upwards, -1 down.
    let mut edges: Vec<(u64, i32)> = Vec::with_capacity(indices.len());
    for t in indices.chunks_exact(3) {
        let w = [t[0], t[1], t[2]].map(|i| weld[i as usize]);
        for (a, b) in [(w[0], w[1]), (w[1], w[2]), (w[2], w[0])] {
            if a != b {
                let (lo, hi, dir) = if a < b { (a, b, 1) } else { (b, a, -1) };
                edges.push(((u64::from(lo) << 32) | u64::from(hi), dir));
                pieces.join(a, b);
            }
        }
    }
    edges.sort_unstable_by_key(|&(k, _)| k);
    let mut ends: Vec<u32> = edges
        .chunk_by(|x, y| x.0 == y.0)
        .filter(|run| run.iter().map(|&(_, d)| d).sum::<i32>() != 0)
        .flat_map(|run| [(run[0].0 >> 32) as u32, run[0].0 as u32])
        .collect();
    ends.sort_unstable();
    ends.dedup();
    ends
}

/// Union-find over welded vertices: the connected pieces of a mesh.
struct Pieces {
    parent: Vec<u32>,
}

impl Pieces {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }

    fn root(&mut self, mut v: u32) -> u32 {
        while self.parent[v as usize] != v {
            let up = self.parent[self.parent[v as usize] as usize];
            self.parent[v as usize] = up;
            v = up;
        }
        v
    }

    fn join(&mut self, a: u32, b: u32) {
        let (a, b) = (self.root(a), self.root(b));
        self.parent[a.max(b) as usize] = a.min(b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Mat3, Quat};
    use proptest::prelude::*;

    /// A box with a vertex per corner and face (as a tessellation with flat
    /// normals has them), counter-clockwise seen from outside.
    fn cube(min: Vec3, max: Vec3) -> (Vec<Vec3>, Vec<u32>) {
        let corner = |i: usize| {
            Vec3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            )
        };
        // Each face's corners counter-clockwise from outside.
        let faces = [
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ];
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for f in faces {
            let base = positions.len() as u32;
            positions.extend(f.map(corner));
            indices.extend([0, 1, 2, 0, 2, 3].map(|i| base + i));
        }
        (positions, indices)
    }

    fn unit() -> (Vec<Vec3>, Vec<u32>) {
        cube(Vec3::ZERO, Vec3::ONE)
    }

    /// The signed volume by the windings, as an independent check of them.
    fn volume(p: &[Vec3], ix: &[u32]) -> f32 {
        ix.chunks_exact(3)
            .map(|t| p[t[0] as usize].dot(p[t[1] as usize].cross(p[t[2] as usize])) / 6.0)
            .sum()
    }

    #[test]
    fn a_box_with_a_vertex_per_face_is_solid() {
        let (p, ix) = unit();
        assert!(
            (volume(&p, &ix) - 1.0).abs() < 1e-6,
            "windings point outwards"
        );
        assert!(is_solid(&p, &ix));
    }

    #[test]
    fn a_box_turned_inside_out_is_not() {
        let (p, mut ix) = unit();
        for t in ix.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
        assert!(!is_solid(&p, &ix));
    }

    #[test]
    fn a_box_with_a_face_missing_is_not() {
        let (p, ix) = unit();
        assert!(!is_solid(&p, &ix[6..]));
        assert!(!is_solid(&p, &ix[..ix.len() - 3]), "one triangle missing");
    }

    #[test]
    fn a_box_with_one_triangle_flipped_is_not() {
        let (p, mut ix) = unit();
        ix.swap(7, 8);
        assert!(!is_solid(&p, &ix));
    }

    #[test]
    fn a_single_sided_sheet_is_not_but_a_sheet_with_both_sides_is() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(!is_solid(&p, &[0, 1, 2]));
        assert!(is_solid(&p, &[0, 1, 2, 0, 2, 1]));
    }

    #[test]
    fn a_box_with_an_inside_out_box_beside_it_is_not() {
        let (mut p, mut ix) = unit();
        let (q, jx) = cube(Vec3::splat(3.0), Vec3::splat(4.0));
        let base = p.len() as u32;
        p.extend(q);
        ix.extend(
            jx.chunks_exact(3)
                .flat_map(|t| [t[0], t[2], t[1]].map(|i| base + i)),
        );
        assert!(!is_solid(&p, &ix));
        // The same two boxes both outward are.
        let (q, jx) = cube(Vec3::splat(3.0), Vec3::splat(4.0));
        let (mut p2, mut ix2) = unit();
        p2.extend(q);
        ix2.extend(jx.iter().map(|&i| base + i));
        assert!(is_solid(&p2, &ix2));
    }

    #[test]
    fn a_seam_rounded_apart_is_welded_but_a_gap_is_not() {
        // The +x face placed on its own: its corners a rounding step away.
        let (p, ix) = cube(Vec3::splat(1000.0), Vec3::splat(1001.0));
        let nudged = |by: f32| -> Vec<Vec3> {
            (p.iter().enumerate())
                .map(|(i, &v)| {
                    if (20..24).contains(&i) {
                        v + Vec3::splat(by)
                    } else {
                        v
                    }
                })
                .collect()
        };
        assert!(is_solid(&nudged(1e-4), &ix), "within 1e-5 of 1001");
        assert!(!is_solid(&nudged(0.05), &ix), "a gap of 5 % of the box");
    }

    #[test]
    fn nothing_is_not_solid() {
        assert!(!is_solid(&[], &[]));
    }

    proptest! {
        /// Near or away from its local origin, turned any way, a box stays
        /// solid, and flipping any one of its triangles, or dropping it,
        /// makes it not (while its thinnest side stays well above the seam
        /// tolerance, a hundred-thousandth of its reach).
        #[test]
        fn boxes_anywhere_and_their_damaged_copies(
            offset in prop::array::uniform3(-100f32..100.0),
            base in 1e-2f32..1e2,
            ratios in prop::array::uniform3(1f32..1e3),
            axis in prop::array::uniform3(-1f32..1.0),
            angle in 0f32..6.3,
            damaged in 0usize..12,
        ) {
            // Sides up to a thousand times each other.
            let size = Vec3::from_array(ratios) * base;
            let (p, ix) = cube(Vec3::ZERO, size);
            let turn = Mat3::from_quat(
                Quat::from_axis_angle(Vec3::from_array(axis).try_normalize().unwrap_or(Vec3::Z), angle),
            );
            // Up to a hundred times its thinnest side from the local origin.
            let shift = Vec3::from_array(offset) * size.min_element();
            let p: Vec<Vec3> = p.iter().map(|&v| turn * v + shift).collect();
            prop_assert!(is_solid(&p, &ix));
            let mut flipped = ix.clone();
            flipped.swap(3 * damaged + 1, 3 * damaged + 2);
            prop_assert!(!is_solid(&p, &flipped));
            let mut dropped = ix.clone();
            dropped.drain(3 * damaged..3 * damaged + 3);
            prop_assert!(!is_solid(&p, &dropped));
        }
    }
}
