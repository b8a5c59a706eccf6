//! How far points lie from a triangle surface, exactly, through a uniform
//! grid of the triangles' boxes: what makes a simplified level's error a
//! measured distance rather than the simplifier's estimate.

use dmu_geom::closest_point_on_triangle;
use glam::{DVec3, IVec3, Vec3};

/// Cells per axis at most: a chunk's few thousand triangles need no more.
const MAX_CELLS: i32 = 16;

/// The farthest any of `points` lies from the surface of `indices` (three per
/// triangle, into `positions`), where that is beyond `floor`; else `floor`.
/// Each point's distance to its nearest triangle is found in f64, the largest
/// rounded up to f32 (a bound stays a bound); infinite without triangles.
///
/// Only whether a point lies beyond the largest distance so far (at first
/// `floor`) matters, so a point's search ends at the first triangle within
/// it: most points of a simplified level lie on it or near it.
pub(crate) fn farthest_from_surface(
    points: &[Vec3],
    positions: &[Vec3],
    indices: &[u32],
    floor: f32,
) -> f32 {
    let grid = Grid::new(positions, indices);
    let farthest = points.iter().fold(f64::from(floor), |farthest, &p| {
        grid.distance_beyond(p.as_dvec3(), farthest).max(farthest)
    });
    let rounded = farthest as f32;
    if f64::from(rounded) < farthest {
        rounded.next_up()
    } else {
        rounded
    }
}

/// Triangles binned by the cells their boxes overlap (compressed rows).
pub(crate) struct Grid {
    triangles: Vec<[DVec3; 3]>,
    min: DVec3,
    cell: DVec3,
    cells: IVec3,
    /// Cell `i`'s triangles are `members[starts[i]..starts[i + 1]]`.
    starts: Vec<u32>,
    members: Vec<u32>,
}

impl Grid {
    pub(crate) fn new(positions: &[Vec3], indices: &[u32]) -> Self {
        let triangles: Vec<[DVec3; 3]> = indices
            .chunks_exact(3)
            .map(|t| [0, 1, 2].map(|k| positions[t[k] as usize].as_dvec3()))
            .collect();
        let (min, max) = triangles
            .iter()
            .flatten()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        let per_axis = ((triangles.len() as f64).cbrt().ceil() as i32).clamp(1, MAX_CELLS);
        let cells = IVec3::splat(per_axis);
        let cell = ((max - min) / cells.as_dvec3()).max(DVec3::splat(f64::MIN_POSITIVE));
        let mut grid = Grid {
            triangles,
            min,
            cell,
            cells,
            starts: vec![0; (cells.element_product() + 1) as usize],
            members: Vec::new(),
        };
        // Count, then fill: two passes over the triangles' cell ranges.
        for pass in 0..2 {
            for t in 0..grid.triangles.len() {
                let [a, b, c] = grid.triangles[t];
                let lo = grid.cell_of(a.min(b).min(c));
                let hi = grid.cell_of(a.max(b).max(c));
                for z in lo.z..=hi.z {
                    for y in lo.y..=hi.y {
                        for x in lo.x..=hi.x {
                            let i = grid.index(IVec3::new(x, y, z));
                            if pass == 0 {
                                grid.starts[i + 1] += 1;
                            } else {
                                grid.members[grid.starts[i] as usize] = t as u32;
                                grid.starts[i] += 1;
                            }
                        }
                    }
                }
            }
            if pass == 0 {
                for i in 1..grid.starts.len() {
                    grid.starts[i] += grid.starts[i - 1];
                }
                grid.members = vec![0; *grid.starts.last().unwrap_or(&0) as usize];
            } else {
                // Filling advanced each start to the next cell's: shift back.
                grid.starts.rotate_right(1);
                grid.starts[0] = 0;
            }
        }
        grid
    }

    /// The cell holding `p`, clamped into the grid.
    fn cell_of(&self, p: DVec3) -> IVec3 {
        ((p - self.min) / self.cell)
            .floor()
            .as_ivec3()
            .clamp(IVec3::ZERO, self.cells - 1)
    }

    fn index(&self, c: IVec3) -> usize {
        (c.x + self.cells.x * (c.y + self.cells.y * c.z)) as usize
    }

    /// Distance from `p` to the nearest triangle when that is beyond
    /// `floor`; else some distance within `floor`. Cells are searched in
    /// growing blocks around `p`'s, until nothing outside the block can be
    /// nearer than the nearest found (a triangle outside lies wholly in cells
    /// beyond one of the block's faces that is not the grid's).
    pub(crate) fn distance_beyond(&self, p: DVec3, floor: f64) -> f64 {
        let centre = self.cell_of(p);
        let floor = floor * floor;
        let mut best = f64::INFINITY;
        for r in 0..=MAX_CELLS {
            let lo = (centre - r).max(IVec3::ZERO);
            let hi = (centre + r).min(self.cells - 1);
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        let c = IVec3::new(x, y, z);
                        if (c - centre).abs().max_element() != r {
                            continue; // searched at a smaller r
                        }
                        let i = self.index(c);
                        for &t in
                            &self.members[self.starts[i] as usize..self.starts[i + 1] as usize]
                        {
                            let q = closest_point_on_triangle(p, self.triangles[t as usize]);
                            best = best.min(q.distance_squared(p));
                            if best <= floor {
                                return best.sqrt();
                            }
                        }
                    }
                }
            }
            let mut outside = f64::INFINITY;
            for k in 0..3 {
                if lo[k] > 0 {
                    outside = outside.min(p[k] - (self.min[k] + f64::from(lo[k]) * self.cell[k]));
                }
                if hi[k] < self.cells[k] - 1 {
                    let face = self.min[k] + f64::from(hi[k] + 1) * self.cell[k];
                    outside = outside.min(face - p[k]);
                }
            }
            if best <= (outside.max(0.0)).powi(2) {
                break;
            }
        }
        best.sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream in [0, 1).
    fn uniform(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*seed >> 40) as f32 / (1u64 << 24) as f32
    }

    #[test]
    fn the_grid_finds_what_brute_force_finds() {
        let mut seed = 7;
        for case in 0..40 {
            let n = 1 + case * 7;
            // Clustered and spread triangles, and flat sets (a zero extent).
            let flat = case % 5 == 0;
            let mut point = |scale: f32| {
                let v = Vec3::new(uniform(&mut seed), uniform(&mut seed), uniform(&mut seed));
                let v = v * scale;
                if flat { v.with_z(0.0) } else { v }
            };
            let positions: Vec<Vec3> = (0..3 * n)
                .map(|i| point(if i % 3 == 0 { 100.0 } else { 10.0 }))
                .collect();
            let positions: Vec<Vec3> = positions
                .chunks_exact(3)
                .flat_map(|t| [t[0], t[0] + t[1], t[0] + t[2]])
                .collect();
            let indices: Vec<u32> = (0..3 * n as u32).collect();
            let points: Vec<Vec3> = (0..50).map(|_| point(150.0) - Vec3::splat(25.0)).collect();
            let grid = Grid::new(&positions, &indices);
            for &p in &points {
                let brute = grid
                    .triangles
                    .iter()
                    .map(|&t| closest_point_on_triangle(p.as_dvec3(), t).distance(p.as_dvec3()))
                    .fold(f64::INFINITY, f64::min);
                for floor in [0.0, brute / 2.0, brute * 2.0] {
                    let found = grid.distance_beyond(p.as_dvec3(), floor);
                    if brute > floor {
                        assert_eq!(found, brute, "case {case}, {p}, floor {floor}");
                    } else {
                        assert!(found <= floor, "case {case}, {p}, floor {floor}: {found}");
                    }
                }
            }
        }
    }
}
