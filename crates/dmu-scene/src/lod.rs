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

use glam::{DMat3, DVec3, Vec3};

use crate::ChunkGeometry;
use crate::nearest::{Grid, farthest_from_surface};

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
/// surface, or `floor` if that is more. Two kinds of piece (connected
/// through shared vertices) count otherwise, as what they show on screen:
/// - one the simplifier may prune (within the target of its vertices'
///   average) counts its box's diagonal: it shows at most its size;
/// - one that vanished (no kept triangle touches it, as a rod collapsed to
///   its axis does) counts the farthest its vertices lie from its principal
///   axis: the strip of pixels it leaves is that wide (a rod's radius; a
///   plate's half width), not as far as the next surface kept happens to be.
pub fn simplified_error(
    positions: &[[f32; 3]],
    indices: &[u32],
    kept: &[u32],
    target_error: f32,
    floor: f32,
) -> f32 {
    Pieces::of(positions, indices).error(kept, target_error, floor)
}

/// [`simplify_to_error`] aiming at `aim`, its mangled pieces mended (a piece
/// with a vertex farther than `limit` from what is kept, as a thin plate
/// whose two faces the simplifier folds onto each other and then wears
/// away, is simplified again on its own aiming at `mend_aim`, or kept whole
/// where that mangles it too: one bad piece costs its own triangles, not a
/// finer simplification of everything), and the error the result claims
/// ([`simplified_error`], at least `margin` times meshoptimizer's
/// estimate). The pieces are found once for both.
pub fn simplify_mended(
    positions: &[[f32; 3]],
    indices: &[u32],
    aim: f32,
    limit: f32,
    mend_aim: f32,
    margin: f32,
) -> (Vec<u32>, f32) {
    let (mut kept, estimate) = simplify_to_error(positions, indices, aim);
    let pieces = Pieces::of(positions, indices);
    pieces.mend(positions, indices, &mut kept, aim, limit, mend_aim);
    let error = pieces.error(&kept, aim, margin * estimate);
    (kept, error)
}

/// The pieces of a mesh (triangles connected through shared vertices) and
/// their shapes.
struct Pieces {
    points: Vec<Vec3>,
    /// Per vertex, its piece (numbered in order of their first vertex;
    /// unused vertices `u32::MAX`).
    of: Vec<u32>,
    /// The used vertices, piece by piece.
    members: Vec<u32>,
    /// Per piece.
    shapes: Vec<Shape>,
}

impl Pieces {
    fn of(positions: &[[f32; 3]], indices: &[u32]) -> Self {
        let points: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
        let mut parent: Vec<u32> = (0..points.len() as u32).collect();
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
        let mut used = vec![false; points.len()];
        for &v in indices {
            used[v as usize] = true;
        }
        let mut number = vec![u32::MAX; points.len()];
        let mut of = vec![u32::MAX; points.len()];
        let mut count = 0;
        for v in 0..points.len() as u32 {
            if used[v as usize] {
                let r = root(&mut parent, v) as usize;
                if number[r] == u32::MAX {
                    number[r] = count;
                    count += 1;
                }
                of[v as usize] = number[r];
            }
        }
        let mut members: Vec<u32> = (0..points.len() as u32)
            .filter(|&v| used[v as usize])
            .collect();
        members.sort_by_key(|&v| of[v as usize]);
        let mut pieces = Pieces {
            points,
            of,
            members,
            shapes: Vec::new(),
        };
        pieces.shapes = pieces
            .each()
            .map(|members| Shape::of(&pieces.points, members))
            .collect();
        pieces
    }

    /// Each piece's vertices, in piece order.
    fn each(&self) -> impl Iterator<Item = &[u32]> {
        self.members
            .chunk_by(|a, b| self.of[*a as usize] == self.of[*b as usize])
    }

    /// Per piece, whether a triangle of `kept` touches it.
    fn touched(&self, kept: &[u32]) -> Vec<bool> {
        let mut touched = vec![false; self.shapes.len()];
        for &v in kept {
            touched[self.of[v as usize] as usize] = true;
        }
        touched
    }

    /// [`simplified_error`] of `kept`.
    fn error(&self, kept: &[u32], target_error: f32, floor: f32) -> f32 {
        let touched = self.touched(kept);
        let mut large = Vec::new();
        let mut error = floor;
        for ((members, shape), touched) in self.each().zip(&self.shapes).zip(touched) {
            if shape.radius <= target_error {
                error = error.max(shape.diagonal);
            } else if !touched {
                error = error.max(shape.off_axis);
            } else {
                large.extend(members.iter().map(|&v| self.points[v as usize]));
            }
        }
        match kept.is_empty() {
            true => error,
            false => farthest_from_surface(&large, &self.points, kept, error),
        }
    }

    /// Mends the pieces of `indices` (into `positions`, these pieces') that
    /// a simplification to `target_error` mangled in `kept` (see
    /// [`simplify_mended`]; not one [`simplified_error`] counts by its
    /// size). Returns the pieces mended.
    fn mend(
        &self,
        positions: &[[f32; 3]],
        indices: &[u32],
        kept: &mut Vec<u32>,
        target_error: f32,
        limit: f32,
        aim: f32,
    ) -> usize {
        if kept.is_empty() {
            return 0;
        }
        let touched = self.touched(kept);
        let grid = Grid::new(&self.points, kept);
        let limit = f64::from(limit);
        let bad: Vec<bool> = (self.each().zip(&self.shapes).zip(touched))
            .map(|((members, shape), touched)| {
                shape.radius > target_error
                    && (if touched {
                        members.iter().any(|&v| {
                            grid.distance_beyond(self.points[v as usize].as_dvec3(), limit) > limit
                        })
                    } else {
                        f64::from(shape.off_axis) > limit
                    })
            })
            .collect();
        let mended = bad.iter().filter(|&&b| b).count();
        if mended == 0 {
            return 0;
        }
        let of = |t: &[u32]| self.of[t[0] as usize] as usize;
        let mut out: Vec<u32> = kept
            .chunks_exact(3)
            .filter(|t| !bad[of(t)])
            .flatten()
            .copied()
            .collect();
        // Each bad piece's triangles, compacted, simplified on their own.
        let mut by_piece: Vec<Vec<u32>> = vec![Vec::new(); self.shapes.len()];
        for t in indices.chunks_exact(3).filter(|t| bad[of(t)]) {
            by_piece[of(t)].extend_from_slice(t);
        }
        for triangles in by_piece.into_iter().filter(|t| !t.is_empty()) {
            let mut local: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
            let mut sub: Vec<[f32; 3]> = Vec::new();
            let remapped: Vec<u32> = triangles
                .iter()
                .map(|&v| {
                    *local.entry(v).or_insert_with(|| {
                        sub.push(positions[v as usize]);
                        sub.len() as u32 - 1
                    })
                })
                .collect();
            let (alone, _) = simplify_to_error(&sub, &remapped, aim);
            let error = simplified_error(&sub, &remapped, &alone, aim, 0.0);
            let global: Vec<u32> = local.iter().fold(vec![0; sub.len()], |mut g, (&v, &l)| {
                g[l as usize] = v;
                g
            });
            match f64::from(error) <= limit {
                true => out.extend(alone.iter().map(|&l| global[l as usize])),
                false => out.extend_from_slice(&triangles),
            }
        }
        *kept = out;
        mended
    }
}

/// A piece's extents, as [`simplified_error`] counts them.
struct Shape {
    /// The farthest its vertices lie from their average (meshoptimizer
    /// prunes a piece whose radius so measured is under its error).
    radius: f32,
    /// Its box's diagonal.
    diagonal: f32,
    /// The farthest its vertices lie from the line through their average
    /// along their principal direction (rounded up).
    off_axis: f32,
}

impl Shape {
    fn of(points: &[Vec3], members: &[u32]) -> Self {
        let at = |v: &u32| points[*v as usize].as_dvec3();
        let centre = members.iter().map(at).sum::<DVec3>() / members.len() as f64;
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let mut covariance = DMat3::ZERO;
        for p in members.iter().map(at) {
            (lo, hi) = (lo.min(p), hi.max(p));
            let d = p - centre;
            covariance += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        }
        // The principal direction by power iteration, from the box's
        // longest side.
        let extent = hi - lo;
        let mut axis = DVec3::AXES[extent.max_position()];
        for _ in 0..32 {
            let next = covariance * axis;
            if next.length_squared() <= f64::MIN_POSITIVE {
                break;
            }
            axis = next.normalize();
        }
        let (mut radius, mut off_axis) = (0.0f64, 0.0f64);
        for p in members.iter().map(at) {
            let d = p - centre;
            radius = radius.max(d.length());
            off_axis = off_axis.max((d - axis * d.dot(axis)).length());
        }
        let up = |x: f64| {
            let r = x as f32;
            if f64::from(r) < x { r.next_up() } else { r }
        };
        Shape {
            radius: radius as f32,
            diagonal: up(extent.length()),
            off_axis: up(off_axis),
        }
    }
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

    /// A closed box from `lo` to `hi` whose faces are grids of `n` x `n`
    /// quads, its vertices welded (appended to `positions` and `indices`).
    fn tessellated_box(
        lo: Vec3,
        hi: Vec3,
        n: u32,
        positions: &mut Vec<[f32; 3]>,
        indices: &mut Vec<u32>,
    ) {
        let mut welded: std::collections::HashMap<[u32; 3], u32> = Default::default();
        let mut vertex = |p: Vec3, positions: &mut Vec<[f32; 3]>| {
            *welded
                .entry(p.to_array().map(f32::to_bits))
                .or_insert_with(|| {
                    positions.push(p.to_array());
                    positions.len() as u32 - 1
                })
        };
        let size = hi - lo;
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for side in [0.0f32, 1.0] {
                let at = |i: u32, j: u32| {
                    let mut p = lo;
                    p[axis] += side * size[axis];
                    p[u] += size[u] * i as f32 / n as f32;
                    p[v] += size[v] * j as f32 / n as f32;
                    p
                };
                for i in 0..n {
                    for j in 0..n {
                        let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
                            .map(|p| vertex(p, positions));
                        let quad = match side == 0.0 {
                            true => [q[0], q[2], q[1], q[0], q[3], q[2]],
                            false => [q[0], q[1], q[2], q[0], q[2], q[3]],
                        };
                        indices.extend(quad);
                    }
                }
            }
        }
    }

    /// The farthest any vertex of `indices` lies from the surface of `kept`
    /// (brute force, f64).
    fn farthest_brute(positions: &[[f32; 3]], vertices: &[u32], kept: &[u32]) -> f64 {
        let p = |i: u32| Vec3::from(positions[i as usize]).as_dvec3();
        vertices
            .iter()
            .map(|&v| {
                kept.chunks_exact(3)
                    .map(|t| {
                        let c = [p(t[0]), p(t[1]), p(t[2])];
                        p(v).distance(dmu_geom::closest_point_on_triangle(p(v), c))
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_vanished_rod_counts_its_radius_and_a_vanished_plate_its_width() {
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        // A large box kept, a rod and a plate metres away from it.
        tessellated_box(
            Vec3::ZERO,
            Vec3::splat(1000.0),
            1,
            &mut positions,
            &mut indices,
        );
        let kept = indices.clone();
        let mut with_rod = indices.clone();
        let rod = Vec3::new(5000.0, 0.0, 0.0);
        tessellated_box(
            rod,
            rod + Vec3::new(10.0, 10.0, 4200.0),
            1,
            &mut positions,
            &mut with_rod,
        );
        let mut with_plate = indices.clone();
        let plate = Vec3::new(0.0, 5000.0, 0.0);
        tessellated_box(
            plate,
            plate + Vec3::new(700.0, 700.0, 14.0),
            4,
            &mut positions,
            &mut with_plate,
        );
        // The rod's strip is as wide as its cross-section: its vertices lie
        // 5 * sqrt(2) from its axis (analytic).
        let rod_error = simplified_error(&positions, &with_rod, &kept, 1.0, 0.0);
        assert!((rod_error - 50f32.sqrt()).abs() < 1e-3, "{rod_error}");
        // A plate gone leaves a hole as wide as itself, at least half its
        // width from any line through it.
        let plate_error = simplified_error(&positions, &with_plate, &kept, 1.0, 0.0);
        assert!(plate_error >= 350.0, "{plate_error}");
        // Kept, both count their distance to what is kept: none.
        assert_eq!(
            simplified_error(&positions, &with_rod, &with_rod, 1.0, 0.0),
            0.0
        );
    }

    /// A flange: a closed ring `thickness` thick along x, between radii
    /// `inner` and `outer` about `centre`, of `segments` (welded vertices;
    /// appended to `positions` and `indices`).
    fn flange(
        centre: Vec3,
        (inner, outer, thickness): (f32, f32, f32),
        segments: u32,
        positions: &mut Vec<[f32; 3]>,
        indices: &mut Vec<u32>,
    ) {
        let base = positions.len() as u32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            for (x, r) in [
                (0.0, inner),
                (0.0, outer),
                (thickness, outer),
                (thickness, inner),
            ] {
                positions.push((centre + Vec3::new(x, r * phi.cos(), r * phi.sin())).to_array());
            }
        }
        let at = |s: u32, k: u32| base + 4 * (s % segments) + k;
        for s in 0..segments {
            // The ring's four faces: back, outer, front, inner.
            for k in 0..4 {
                let (a, b) = (k, (k + 1) % 4);
                indices.extend([at(s, a), at(s + 1, a), at(s + 1, b)]);
                indices.extend([at(s, a), at(s + 1, b), at(s, b)]);
            }
        }
    }

    #[test]
    fn mended_pieces_lie_within_their_limit_of_what_is_kept() {
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        // Pipe flanges, rings 12 mm wide and 10 mm thick, beside a block, as
        // the plant's: the simplifier wears a ring away to nothing, whose
        // vertices then lie as far as the block from what is kept.
        tessellated_box(
            Vec3::ZERO,
            Vec3::splat(800.0),
            6,
            &mut positions,
            &mut indices,
        );
        let mut pieces = Vec::new();
        for k in 0..8 {
            let start = indices.len();
            let centre = Vec3::new(1000.0 + 40.0 * k as f32, 300.0, 300.0);
            flange(
                centre,
                (138.0, 150.0, 10.0),
                69,
                &mut positions,
                &mut indices,
            );
            pieces.push(indices[start..].to_vec());
        }
        let aim = 25.0;
        let limit = 4.0 * aim;
        let (mut kept, _) = simplify_to_error(&positions, &indices, aim);
        let worst = |kept: &[u32]| {
            pieces
                .iter()
                .map(|p| farthest_brute(&positions, p, kept))
                .fold(0.0, f64::max)
        };
        let before = worst(&kept);
        let mended = Pieces::of(&positions, &indices).mend(
            &positions,
            &indices,
            &mut kept,
            aim,
            limit,
            aim / 4.0,
        );
        let after = worst(&kept);
        println!("{mended} pieces mended: the farthest vertex {before:.1} -> {after:.1}");
        assert!(
            before > f64::from(limit),
            "the simplifier mangled none: {before}"
        );
        assert!(mended > 0);
        assert!(after <= f64::from(limit), "{after}");
        // What simplified_error claims bounds it.
        assert!(f64::from(simplified_error(&positions, &indices, &kept, aim, 0.0)) >= after);
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
