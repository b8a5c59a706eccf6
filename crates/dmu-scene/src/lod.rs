//! Simplified levels of a chunk, drawn instead of it where the difference is
//! smaller than a pixel or two.
//!
//! Each level keeps the chunk's vertices and indexes a subset of them
//! (meshoptimizer's edge-collapse simplifier), so on the GPU a level costs only
//! its indices. Levels are simplified from the full chunk each time (not from
//! the level before), so errors do not add up, with the chunk's open borders
//! locked: neighbouring chunks of a mesh still meet at every level. Small
//! disconnected pieces (bolts, nuts) may vanish from a coarse level; their loss
//! is inside the reported error.

use glam::Vec3;

use crate::ChunkGeometry;
use crate::nearest::farthest_from_surface;

/// At most this many levels after the full chunk.
pub const MAX_LOD_LEVELS: usize = 7;

/// Chunks with fewer triangles get no levels: too little to gain.
pub const MIN_LOD_TRIANGLES: usize = 64;

/// The chain stops before a level would aim below this many triangles.
const FEWEST_TRIANGLES: usize = 16;

/// meshoptimizer's error is a quadric estimate, not a bound: on a sphere the
/// surface strayed 1.33 (half the triangles) to 1.82 (a sixteenth) times the
/// estimate (the test below), on the plant's chunks up to 23 times (a pipe
/// elbow's level, `dmu-store`'s levels test). Levels claim at least this
/// multiple of it, and at least the measured distance from every vertex of
/// the chunk to the level's surface.
const ERROR_MARGIN: f32 = 2.0;

/// One simplified level.
#[derive(Clone, Debug, PartialEq)]
pub struct LodLevel {
    /// Chunk-local indices, three per triangle, into the chunk's vertices.
    pub indices: Vec<u32>,
    /// How far the simplified surface may lie from the full one, in the
    /// chunk's local units: the farthest any vertex of the chunk lies from
    /// the level's surface (measured), or meshoptimizer's estimate with a
    /// margin where that is more. The other way, the level's surface from the
    /// chunk's, is only estimated (on the plant's chunks it never strayed
    /// farther than the vertices did).
    pub error: f32,
}

/// The simplified levels of `geometry`, coarser each time: about half the
/// triangles of the one before, down to a few dozen. A level that would keep
/// more than 3/4 of the one before (the simplifier is stuck on locked
/// borders or features) ends the chain, and so does one that would bring the
/// levels' triangles together past the chunk's own: a chunk with its levels
/// holds at most twice its indices, the bound a store's residency budget
/// counts before reading it. Chunks under [`MIN_LOD_TRIANGLES`] get none.
pub fn lod_levels(geometry: &ChunkGeometry<'_>) -> Vec<LodLevel> {
    let triangles = geometry.indices.len() / 3;
    let mut levels: Vec<LodLevel> = Vec::new();
    if triangles < MIN_LOD_TRIANGLES {
        return levels;
    }
    let positions: Vec<[f32; 3]> = geometry.positions.iter().map(Vec3::to_array).collect();
    let options = meshopt::SimplifyOptions::LockBorder
        | meshopt::SimplifyOptions::ErrorAbsolute
        | meshopt::SimplifyOptions::Prune;
    let mut previous = triangles;
    let mut total = 0;
    while levels.len() < MAX_LOD_LEVELS && previous / 2 >= FEWEST_TRIANGLES {
        let target = previous / 2;
        let mut error = 0.0f32;
        let indices = meshopt::simplify_decoder(
            geometry.indices,
            &positions,
            3 * target,
            f32::MAX,
            options,
            Some(&mut error),
        );
        let kept = indices.len() / 3;
        total += kept;
        if kept == 0 || 4 * kept > 3 * previous || total > triangles || !error.is_finite() {
            break;
        }
        // A coarser level never claims less error than a finer one.
        let error = farthest_from_surface(
            geometry.positions,
            geometry.positions,
            &indices,
            ERROR_MARGIN * error,
        );
        let error = levels.last().map_or(error, |l| l.error.max(error));
        levels.push(LodLevel { indices, error });
        previous = kept;
    }
    levels
}

/// Simplifies a mesh (any triangles, several pieces welded or not) until its
/// error would pass `target_error` (in the positions' units), pruning pieces
/// smaller than that: the kept triangles' indices into `positions` and
/// meshoptimizer's error estimate for them (not a bound: measure it with
/// [`simplified_error`], as [`lod_levels`] does its own). For merged
/// stand-ins of many chunks, whose borders need not be kept.
pub fn simplify_to_error(
    positions: &[[f32; 3]],
    indices: &[u32],
    target_error: f32,
) -> (Vec<u32>, f32) {
    if indices.is_empty() {
        return (Vec::new(), 0.0);
    }
    let options = meshopt::SimplifyOptions::ErrorAbsolute | meshopt::SimplifyOptions::Prune;
    let mut error = 0.0f32;
    let kept = meshopt::simplify_decoder(
        indices,
        positions,
        0,
        target_error,
        options,
        Some(&mut error),
    );
    (
        kept,
        if error.is_finite() {
            error
        } else {
            target_error
        },
    )
}

/// The error [`simplify_to_error`]'s `kept` triangles claim for `indices`
/// (into `positions`) simplified to `target_error`, measured as
/// [`lod_levels`]' is: the farthest any input vertex lies from the kept
/// surface, or `floor` if that is more. A vertex of a piece the simplifier
/// may prune (connected through shared vertices, its box's diagonal under
/// the target) counts that diagonal instead: a piece that vanishes shows at
/// most its size.
pub fn simplified_error(
    positions: &[[f32; 3]],
    indices: &[u32],
    kept: &[u32],
    target_error: f32,
    floor: f32,
) -> f32 {
    let points: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
    let (large, small) = pieces_by_size(&points, indices, target_error);
    match kept.is_empty() {
        // Everything pruned: every piece was under the target.
        true => floor.max(small),
        false => farthest_from_surface(&large, &points, kept, floor.max(small)),
    }
}

/// The vertices of `indices`' pieces (connected through shared vertices)
/// whose box's diagonal is at least `size`, and the largest diagonal of the
/// smaller pieces.
fn pieces_by_size(positions: &[Vec3], indices: &[u32], size: f32) -> (Vec<Vec3>, f32) {
    let mut parent: Vec<u32> = (0..positions.len() as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let up = parent[parent[v as usize] as usize];
            parent[v as usize] = up;
            v = up;
        }
        v
    }
    for t in indices.chunks_exact(3) {
        let a = root(&mut parent, t[0]);
        for &v in &t[1..] {
            let b = root(&mut parent, v);
            parent[b as usize] = a;
        }
    }
    let mut boxes: std::collections::HashMap<u32, (Vec3, Vec3)> = std::collections::HashMap::new();
    let used: Vec<u32> = {
        let mut used: Vec<u32> = indices.to_vec();
        used.sort_unstable();
        used.dedup();
        used
    };
    for &v in &used {
        let r = root(&mut parent, v);
        let p = positions[v as usize];
        let b = boxes.entry(r).or_insert((p, p));
        *b = (b.0.min(p), b.1.max(p));
    }
    let mut large = Vec::new();
    let mut small = 0.0f32;
    for &v in &used {
        let (lo, hi) = boxes[&root(&mut parent, v)];
        let diagonal = (hi - lo).length();
        if diagonal < size {
            small = small.max(diagonal);
        } else {
            large.push(positions[v as usize]);
        }
    }
    (large, small)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UV sphere of `rings` x `segments` (closed, no borders).
    fn sphere(rings: u32, segments: u32, radius: f32) -> (Vec<Vec3>, Vec<u32>) {
        let mut positions = Vec::new();
        for r in 0..=rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segments {
                let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                positions.push(
                    radius
                        * Vec3::new(
                            theta.sin() * phi.cos(),
                            theta.sin() * phi.sin(),
                            theta.cos(),
                        ),
                );
            }
        }
        let at = |r: u32, s: u32| r * segments + s % segments;
        let mut indices = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                indices.extend([at(r, s), at(r + 1, s), at(r + 1, s + 1)]);
                indices.extend([at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
            }
        }
        (positions, indices)
    }

    /// How far inside the sphere of `radius` about the origin the surface of
    /// `indices` reaches: its vertices lie on the sphere, so this is the
    /// largest distance between the surface and the sphere (analytic).
    fn depth_inside(positions: &[Vec3], indices: &[u32], radius: f32) -> f32 {
        indices
            .chunks_exact(3)
            .map(|t| {
                let corners = [0, 1, 2].map(|k| positions[t[k] as usize].as_dvec3());
                let nearest = dmu_geom::closest_point_on_triangle(glam::DVec3::ZERO, corners);
                radius - nearest.length() as f32
            })
            .fold(0.0, f32::max)
    }

    #[test]
    fn levels_halve_and_their_errors_grow_and_bound_what_moved() {
        let radius = 1000.0;
        let (positions, indices) = sphere(32, 64, radius);
        let normals: Vec<Vec3> = positions.iter().map(|p| p.normalize_or_zero()).collect();
        let geometry = ChunkGeometry {
            positions: &positions,
            normals: &normals,
            indices: &indices,
            levels: None,
        };
        let levels = lod_levels(&geometry);
        let full_depth = depth_inside(&positions, &indices, radius);
        assert!(levels.len() >= 4, "{} levels", levels.len());
        let all: usize = levels.iter().map(|l| l.indices.len()).sum();
        assert!(all <= indices.len(), "{all} level indices");
        let mut previous = indices.len() / 3;
        let mut previous_error = 0.0;
        for (k, level) in levels.iter().enumerate() {
            let kept = level.indices.len() / 3;
            assert!(kept * 4 <= previous * 3, "level {k}: {kept} of {previous}");
            assert!(level.error >= previous_error, "level {k}");
            assert!(
                level
                    .indices
                    .iter()
                    .all(|&i| (i as usize) < positions.len())
            );
            // The level strays from the full mesh by at least its extra
            // depth inside the sphere; the claimed error must cover that.
            let strayed = depth_inside(&positions, &level.indices, radius) - full_depth;
            assert!(
                strayed <= level.error,
                "level {k}: strays {strayed} beyond its error {}",
                level.error
            );
            previous = kept;
            previous_error = level.error;
        }
        // The coarsest has at most an eighth of the triangles, and its error
        // is of the order of the sphere's size: not zero, not wild.
        let last = levels.last().unwrap();
        assert!(
            last.indices.len() * 8 <= indices.len(),
            "{}",
            last.indices.len() / 3
        );
        assert!(
            last.error > 1.0 && last.error < 2.0 * radius,
            "{}",
            last.error
        );
    }

    #[test]
    fn small_chunks_get_no_levels() {
        let (positions, indices) = sphere(4, 6, 1.0);
        assert!(indices.len() / 3 < MIN_LOD_TRIANGLES);
        let normals = vec![Vec3::Z; positions.len()];
        let geometry = ChunkGeometry {
            positions: &positions,
            normals: &normals,
            indices: &indices,
            levels: None,
        };
        assert!(lod_levels(&geometry).is_empty());
    }
}
