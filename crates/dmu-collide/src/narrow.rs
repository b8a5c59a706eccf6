//! The narrow phase: the chunks' BVHs (dmu-tree's, built on first use and
//! shared by every instance of a chunk) traversed together, their node boxes
//! and triangles carried into a frame centred on the first part in f64 once per
//! chunk pair and reused as the traversal revisits them, their triangle pairs
//! compared in f64.

use dmu_geom::Aabb3d;
use dmu_scene::{ChunkId, PartId, Scene};
use dmu_tree::{BvhNode, ChunkBvhCache};
use glam::{DAffine3, DVec3, Vec3};

use crate::triangle::{Placed, TriangleClash, placed_clash, triangle_penetration};

/// Where a part sits in the frame of a pair: world axes, origin at the first
/// part's world translation. Offsets between parts are formed in f64 before any
/// geometry is touched, so a 0.05 mm gap 10 km from the origin stays 0.05 mm.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placement {
    /// Part-local to pair frame.
    pub to_pair: DAffine3,
    /// The transform mirrors: triangle windings flip, so they are reordered to
    /// keep outward normals outward.
    pub mirrored: bool,
}

impl Placement {
    /// `world` seen from a pair frame whose origin is at `origin` (world).
    pub fn new(world: &DAffine3, origin: DVec3) -> Self {
        Self {
            to_pair: DAffine3 {
                matrix3: world.matrix3,
                translation: world.translation - origin,
            },
            mirrored: world.matrix3.determinant() < 0.0,
        }
    }

    pub fn triangle(&self, t: [Vec3; 3]) -> [DVec3; 3] {
        let [a, b, c] = t.map(|v| self.to_pair.transform_point3(v.as_dvec3()));
        if self.mirrored { [a, c, b] } else { [a, b, c] }
    }
}

/// One side of a chunk pair: the chunk's BVH (a single leaf for a chunk too
/// small to have one), its geometry, and its node boxes and triangles carried
/// into the pair frame on first use, marked valid by a stamp that changes with
/// every chunk pair, so nothing is cleared between pairs.
#[derive(Debug, Default)]
pub(crate) struct PlacedChunk {
    stamp: u32,
    boxes: Vec<(u32, Aabb3d)>,
    triangles: Vec<(u32, Placed)>,
}

impl PlacedChunk {
    /// Invalidates what the last chunk pair placed and makes room for a chunk
    /// of `nodes` nodes and `triangles` triangles.
    fn begin(&mut self, nodes: usize, triangles: usize) {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.boxes.iter_mut().for_each(|b| b.0 = 0);
            self.triangles.iter_mut().for_each(|t| t.0 = 0);
            self.stamp = 1;
        }
        if self.boxes.len() < nodes {
            self.boxes.resize(nodes, (0, Aabb3d::EMPTY));
        }
        if self.triangles.len() < triangles {
            self.triangles
                .resize(triangles, (0, Placed::new([DVec3::ZERO; 3])));
        }
    }
}

/// Scratch for [`chunk_pair`]: the two placed sides and the traversal stack.
#[derive(Debug, Default)]
pub(crate) struct PairScratch {
    a: PlacedChunk,
    b: PlacedChunk,
    stack: Vec<(u32, u32)>,
}

/// A chunk as the traversal sees it.
struct Side<'a> {
    nodes: &'a [BvhNode],
    /// Leaf entries to triangle offsets; `None`: the offset itself (one leaf).
    order: Option<&'a [u32]>,
    positions: &'a [Vec3],
    indices: &'a [u32],
    place: &'a Placement,
}

impl Side<'_> {
    fn node_box(&self, placed: &mut PlacedChunk, n: u32) -> Aabb3d {
        let slot = &mut placed.boxes[n as usize];
        if slot.0 != placed.stamp {
            *slot = (
                placed.stamp,
                self.nodes[n as usize]
                    .bounds
                    .transformed(&self.place.to_pair),
            );
        }
        slot.1
    }

    /// The offset in the chunk of the triangle at leaf entry `entry`.
    fn offset(&self, entry: u32) -> u32 {
        self.order.map_or(entry, |o| o[entry as usize])
    }

    fn triangle<'p>(&self, placed: &'p mut PlacedChunk, t: u32) -> &'p Placed {
        let slot = &mut placed.triangles[t as usize];
        if slot.0 != placed.stamp {
            let local = local_triangle(self.positions, self.indices, t);
            *slot = (placed.stamp, Placed::new(self.place.triangle(local)));
        }
        &slot.1
    }
}

/// Triangle `t` (offset in its chunk) of chunk geometry, part-local.
fn local_triangle(positions: &[Vec3], indices: &[u32], t: u32) -> [Vec3; 3] {
    let i = 3 * t as usize;
    [0, 1, 2].map(|k| positions[indices[i + k] as usize])
}

/// A triangle of each part of a pair: chunk and offset in the chunk.
pub(crate) type TrianglePair = [(ChunkId, u32); 2];

/// Offers triangle pair `at` (the nearest at the step before) to the search
/// before any traversal: its distance, a real one, shrinks the limit at once,
/// and a part resting where it rested is settled by its first pair.
pub(crate) fn seed(
    scene: &Scene,
    at: TrianglePair,
    (place_a, place_b): (&Placement, &Placement),
    search: &mut PairSearch,
) {
    let placed = |(chunk, t): (ChunkId, u32), place: &Placement| {
        let g = scene
            .chunk_geometry(chunk)
            .expect("collision needs the geometry loaded");
        Placed::new(place.triangle(local_triangle(g.positions, g.indices, t)))
    };
    let (a, b) = (placed(at[0], place_a), placed(at[1], place_b));
    if let Some(clash) = placed_clash(&a, &b, search.tolerance, search.limit) {
        search.offer(clash, at);
    }
}

/// Compares two chunks, placed in a common pair frame, triangle pair by
/// triangle pair as their BVHs are traversed together, nearer node pairs
/// first; node pairs farther apart than the search's limit are pruned.
pub(crate) fn chunk_pair(
    scene: &Scene,
    bvhs: &ChunkBvhCache,
    (ca, place_a): (ChunkId, &Placement),
    (cb, place_b): (ChunkId, &Placement),
    search: &mut PairSearch,
    scratch: &mut PairScratch,
) {
    let single_a = [single_leaf(scene, ca)];
    let single_b = [single_leaf(scene, cb)];
    let a = side(scene, bvhs, ca, place_a, &single_a);
    let b = side(scene, bvhs, cb, place_b, &single_b);
    let PairScratch {
        a: placed_a,
        b: placed_b,
        stack,
    } = scratch;
    placed_a.begin(a.nodes.len(), single_a[0].count as usize);
    placed_b.begin(b.nodes.len(), single_b[0].count as usize);
    let gap = |pa: &mut PlacedChunk, pb: &mut PlacedChunk, i: u32, j: u32| {
        box_gap_squared(&a.node_box(pa, i), &b.node_box(pb, j))
    };
    stack.clear();
    if gap(placed_a, placed_b, 0, 0) <= search.limit * search.limit {
        stack.push((0, 0));
    }
    while let Some((i, j)) = stack.pop() {
        let (na, nb) = (a.nodes[i as usize], b.nodes[j as usize]);
        match (na.count, nb.count) {
            (0, _) | (_, 0) => {
                // Split the inner node with the larger box (or the only one).
                let split_a = nb.count != 0
                    || (na.count == 0 && na.bounds.surface_area() >= nb.bounds.surface_area());
                let pairs = if split_a {
                    [(na.first, j), (na.first + 1, j)]
                } else {
                    [(i, nb.first), (i, nb.first + 1)]
                };
                let gaps = pairs.map(|(x, y)| gap(placed_a, placed_b, x, y));
                let limit2 = search.limit * search.limit;
                // The nearer pair last, so it is popped first.
                let order = if gaps[0] <= gaps[1] { [1, 0] } else { [0, 1] };
                stack.extend(
                    order
                        .into_iter()
                        .filter(|&k| gaps[k] <= limit2)
                        .map(|k| pairs[k]),
                );
            }
            _ => {
                if gap(placed_a, placed_b, i, j) > search.limit * search.limit {
                    continue; // the limit shrank since the pair was pushed
                }
                let box_b = b.node_box(placed_b, j);
                for ea in na.first..na.first + na.count {
                    let oa = a.offset(ea);
                    let ta = a.triangle(placed_a, oa);
                    let reach = |limit: f64| {
                        box_gap_squared(&Aabb3d::new(ta.min, ta.max), &box_b) <= limit * limit
                    };
                    if !reach(search.limit) {
                        continue;
                    }
                    for eb in nb.first..nb.first + nb.count {
                        let ob = b.offset(eb);
                        let tb = b.triangle(placed_b, ob);
                        let clash = if search.best.is_some_and(|b| b.distance == 0.0) {
                            triangle_penetration(ta, tb, search.tolerance)
                        } else {
                            placed_clash(ta, tb, search.tolerance, search.limit)
                        };
                        if let Some(clash) = clash {
                            search.offer(clash, [(ca, oa), (cb, ob)]);
                            if search.done() {
                                return;
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The whole chunk as one leaf: its box and its triangle count.
fn single_leaf(scene: &Scene, chunk: ChunkId) -> BvhNode {
    let c = scene.chunk(chunk);
    BvhNode {
        bounds: c.bounds,
        count: c.triangle_count(),
        first: 0,
    }
}

fn side<'a>(
    scene: &'a Scene,
    bvhs: &'a ChunkBvhCache,
    chunk: ChunkId,
    place: &'a Placement,
    single: &'a [BvhNode; 1],
) -> Side<'a> {
    let g = scene
        .chunk_geometry(chunk)
        .expect("collision needs the geometry loaded");
    let (nodes, order) = match bvhs.get(scene, chunk) {
        Some(bvh) => (bvh.nodes(), Some(bvh.triangles())),
        None => (single.as_slice(), None),
    };
    Side {
        nodes,
        order,
        positions: g.positions,
        indices: g.indices,
        place,
    }
}

/// Squared distance between two boxes (0 when they overlap).
pub(crate) fn box_gap_squared(a: &Aabb3d, b: &Aabb3d) -> f64 {
    (b.min - a.max)
        .max(a.min - b.max)
        .max(DVec3::ZERO)
        .length_squared()
}

/// What the narrow phase has found so far for one pair of parts.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PairSearch {
    /// Triangles closer than this are contact; penetration beyond it is hard.
    pub tolerance: f64,
    /// Only triangle pairs within this distance matter; it shrinks to the best
    /// distance found (but never below `tolerance`, where penetration is sought).
    pub limit: f64,
    /// The nearest (or the first penetrating) triangle pair, in the pair frame.
    pub best: Option<TriangleClash>,
    /// Which triangles `best` is of.
    pub best_at: Option<TrianglePair>,
}

impl PairSearch {
    pub fn new(tolerance: f64, max_distance: f64) -> Self {
        Self {
            tolerance,
            limit: max_distance.max(tolerance),
            best: None,
            best_at: None,
        }
    }

    /// A penetrating pair was found: nothing more to look for.
    pub fn done(&self) -> bool {
        self.best.is_some_and(|b| b.penetrating)
    }

    pub fn offer(&mut self, clash: TriangleClash, at: TrianglePair) {
        if clash.penetrating || self.best.is_none_or(|b| clash.distance < b.distance) {
            self.best = Some(clash);
            self.best_at = Some(at);
            self.limit = clash.distance.max(self.tolerance);
        }
    }
}

/// The contact tolerance of a part pair: the larger of the two parts'.
pub(crate) fn pair_tolerance(scene: &Scene, a: PartId, b: PartId, relative: f64) -> f64 {
    part_tolerance(scene, a, relative).max(part_tolerance(scene, b, relative))
}

/// The contact tolerance of a part: `relative` times the larger of its world
/// size and the magnitude of its local coordinates, the two scales at which its
/// f32 vertices and f64 transform carry rounding.
pub(crate) fn part_tolerance(scene: &Scene, part: PartId, relative: f64) -> f64 {
    let bounds = scene.part_mesh(part).bounds;
    if bounds.is_empty() {
        return 0.0;
    }
    let m = scene.part_world(part).matrix3;
    let stretch = m
        .x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length());
    let local = bounds.min.abs().max(bounds.max.abs()).max_element();
    let size = bounds.extent().length();
    relative * stretch * f64::from(local.max(size))
}
