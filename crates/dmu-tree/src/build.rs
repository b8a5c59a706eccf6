//! Top-down binned-SAH build over chunk world boxes, parallel with rayon.

use dmu_geom::Aabb3d;
use dmu_scene::{ChunkId, PartId, Scene};

use crate::chunk_bvh::ChunkBvhCache;
use crate::tree::{Cell, Entry, Kind, NONE, Node, Tree, TreeOptions, UpdateStats};

/// Ranges smaller than this are built on the current thread.
const PARALLEL_MIN: usize = 512;

/// A subtree as built, before it is flattened into the node array.
enum Built {
    Leaf(Vec<u32>, Aabb3d),
    Internal(Box<Built>, Box<Built>, Aabb3d),
}

impl Tree {
    /// Builds the tree over every chunk of every part at the parts' current
    /// transforms.
    pub fn build(scene: &Scene, options: TreeOptions) -> Tree {
        assert!(
            options.cell_triangles > 0 && options.sah_bins >= 2,
            "invalid tree options {options:?}"
        );
        let mut entries = Vec::with_capacity(scene.chunk_instance_count() as usize);
        let mut part_entries = Vec::with_capacity(scene.parts().len());
        for part in scene.part_ids() {
            let first = entries.len() as u32;
            let mesh = scene.part_mesh(part);
            for chunk in mesh.chunk_ids() {
                entries.push(Entry {
                    part,
                    chunk,
                    bounds: scene.chunk_world_bounds(part, chunk),
                    triangles: scene.chunk(chunk).triangle_count(),
                    cell: NONE,
                });
            }
            part_entries.push(first..entries.len() as u32);
        }
        let mut tree = Tree {
            options,
            nodes: Vec::new(),
            free_nodes: Vec::new(),
            cells: Vec::new(),
            free_cells: Vec::new(),
            root: NONE,
            entries,
            part_entries,
            bvhs: ChunkBvhCache::new(scene.chunks().len()),
            stats: UpdateStats::default(),
            search_scratch: Vec::new(),
            log: crate::changes::ChangeLog::new(),
        };
        let mut ids: Vec<u32> = (0..tree.entries.len() as u32).collect();
        let built = build_range(&tree.entries, &mut ids, &options);
        tree.root = tree.flatten(built, NONE);
        tree.log.restart();
        tree
    }

    /// Rebuilds from the entries' current boxes (what a move would cost without
    /// incremental update); keeps the chunk BVH cache.
    pub fn rebuild(&mut self) {
        let mut ids: Vec<u32> = (0..self.entries.len() as u32).collect();
        let built = build_range(&self.entries, &mut ids, &self.options);
        self.nodes.clear();
        self.free_nodes.clear();
        self.cells.clear();
        self.free_cells.clear();
        self.root = self.flatten(built, NONE);
        self.log.restart();
    }

    fn flatten(&mut self, built: Built, parent: u32) -> u32 {
        match built {
            Built::Leaf(ids, bounds) => {
                let node = self.alloc_node(bounds, parent, Kind::Free);
                let cell = self.alloc_cell(node, ids);
                self.nodes[node as usize].kind = Kind::Leaf(cell);
                node
            }
            Built::Internal(left, right, bounds) => {
                let node = self.alloc_node(bounds, parent, Kind::Free);
                let l = self.flatten(*left, node);
                let r = self.flatten(*right, node);
                self.nodes[node as usize].kind = Kind::Internal([l, r]);
                node
            }
        }
    }

    pub(crate) fn alloc_node(&mut self, bounds: Aabb3d, parent: u32, kind: Kind) -> u32 {
        let node = Node {
            bounds,
            parent,
            kind,
        };
        let id = match self.free_nodes.pop() {
            Some(i) => {
                self.nodes[i as usize] = node;
                i
            }
            None => {
                self.nodes.push(node);
                self.nodes.len() as u32 - 1
            }
        };
        self.touch_node(id);
        id
    }

    pub(crate) fn free_node(&mut self, node: u32) {
        self.nodes[node as usize] = Node {
            bounds: Aabb3d::EMPTY,
            parent: NONE,
            kind: Kind::Free,
        };
        self.free_nodes.push(node);
        self.touch_node(node);
    }

    /// A new cell at `node` holding `ids` (sorted here by part and chunk).
    pub(crate) fn alloc_cell(&mut self, node: u32, mut ids: Vec<u32>) -> u32 {
        let entries = &self.entries;
        ids.sort_unstable_by_key(|&e| {
            sort_key(entries[e as usize].part, entries[e as usize].chunk)
        });
        let triangles = ids.iter().map(|&e| entries[e as usize].triangles).sum();
        let cell = match self.free_cells.pop() {
            Some(c) => c,
            None => {
                self.cells.push(Cell::default());
                self.cells.len() as u32 - 1
            }
        };
        for &e in &ids {
            self.entries[e as usize].cell = cell;
        }
        self.cells[cell as usize] = Cell {
            node,
            entries: ids,
            triangles,
        };
        self.touch_cell(cell);
        cell
    }

    pub(crate) fn free_cell(&mut self, cell: u32) {
        self.cells[cell as usize] = Cell {
            node: NONE,
            entries: Vec::new(),
            triangles: 0,
        };
        self.free_cells.push(cell);
        self.touch_cell(cell);
    }
}

pub(crate) fn sort_key(part: PartId, chunk: ChunkId) -> u64 {
    (u64::from(part.0) << 32) | u64::from(chunk.0)
}

fn build_range(entries: &[Entry], ids: &mut [u32], options: &TreeOptions) -> Built {
    let bounds = ids
        .iter()
        .fold(Aabb3d::EMPTY, |b, &e| b.union(entries[e as usize].bounds));
    let triangles: u64 = ids
        .iter()
        .map(|&e| u64::from(entries[e as usize].triangles))
        .sum();
    if triangles <= u64::from(options.cell_triangles) || ids.len() <= 1 {
        return Built::Leaf(ids.to_vec(), bounds);
    }
    let mid = sah_partition(entries, ids, options.sah_bins);
    let (left, right) = ids.split_at_mut(mid);
    let (l, r) = if left.len() + right.len() >= PARALLEL_MIN {
        rayon::join(
            || build_range(entries, left, options),
            || build_range(entries, right, options),
        )
    } else {
        (
            build_range(entries, left, options),
            build_range(entries, right, options),
        )
    };
    Built::Internal(Box::new(l), Box::new(r), bounds)
}

/// Partitions `ids` (at least two) by the best binned-SAH plane over all three
/// axes, weighting each side's area by its triangles, and returns the size of the
/// left part (never 0 or `ids.len()`). Falls back to a median split when all
/// centroids coincide.
pub(crate) fn sah_partition(entries: &[Entry], ids: &mut [u32], bins: usize) -> usize {
    debug_assert!(ids.len() >= 2);
    let centroid = |e: u32| entries[e as usize].bounds.center();
    let cbounds = ids.iter().fold(Aabb3d::EMPTY, |b, &e| b.grown(centroid(e)));
    let extent = cbounds.extent();
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, last bin on the left)
    let mut bin_bounds = vec![Aabb3d::EMPTY; bins];
    let mut bin_tris = vec![0u64; bins];
    let mut bin_count = vec![0usize; bins];
    let bin_of = |c: f64, axis: usize| -> usize {
        let f = (c - cbounds.min[axis]) / extent[axis] * bins as f64;
        (f as usize).min(bins - 1)
    };
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        bin_bounds.fill(Aabb3d::EMPTY);
        bin_tris.fill(0);
        bin_count.fill(0);
        for &e in ids.iter() {
            let b = bin_of(centroid(e)[axis], axis);
            bin_bounds[b] = bin_bounds[b].union(entries[e as usize].bounds);
            bin_tris[b] += u64::from(entries[e as usize].triangles).max(1);
            bin_count[b] += 1;
        }
        // Right-to-left sweep of suffix costs, then left-to-right.
        let mut suffix = vec![0.0f64; bins];
        let (mut rb, mut rt) = (Aabb3d::EMPTY, 0u64);
        for i in (1..bins).rev() {
            rb = rb.union(bin_bounds[i]);
            rt += bin_tris[i];
            suffix[i] = rb.surface_area() * rt as f64;
        }
        let (mut lb, mut lt, mut lc) = (Aabb3d::EMPTY, 0u64, 0usize);
        for i in 0..bins - 1 {
            lb = lb.union(bin_bounds[i]);
            lt += bin_tris[i];
            lc += bin_count[i];
            if lc == 0 || lc == ids.len() {
                continue;
            }
            let cost = lb.surface_area() * lt as f64 + suffix[i + 1];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, i));
            }
        }
    }
    match best {
        Some((_, axis, last_left)) => {
            let mut left = 0;
            for i in 0..ids.len() {
                if bin_of(centroid(ids[i])[axis], axis) <= last_left {
                    ids.swap(i, left);
                    left += 1;
                }
            }
            left
        }
        None => ids.len() / 2,
    }
}
