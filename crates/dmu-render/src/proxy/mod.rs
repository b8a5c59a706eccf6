//! Merged, simplified stand-ins for whole subtrees of the cell tree
//! (hierarchical LOD): one draw where the subtree's chunk instances would
//! take hundreds.
//!
//! Seen from afar a cell, or a subtree of cells, covers a few hundred pixels
//! but costs one draw per chunk instance, and on a CPU rasterizer each draw
//! costs about as much as a few thousand small triangles. A proxy is the
//! geometry of every chunk instance below a tree node, placed in world space
//! (f32 relative to the node's centre, an f64 origin), merged into one mesh
//! and simplified (meshoptimizer, small pieces pruned) until its error
//! reaches a fraction of the node's diagonal ([`ProxyOptions`]). A cell's
//! proxy is made from its chunks, an inner node's from its children's
//! proxies, so the errors add up the tree and each proxy claims the sum. A
//! frame draws a node's proxy instead of descending where that error
//! projects within the LOD error in pixels, the same bound the chunks' own
//! levels keep.
//!
//! Each vertex keeps its chunk instance's entry id, so materials, selection,
//! clash and hover tints still follow the part. What a proxy shows is its
//! subtree's content when it was made; that content is summed in a
//! signature (entry ids, their parts' transforms and hidden flags), and a
//! proxy whose signature no longer matches its node is stale: never drawn
//! (the frame descends to what is current), remade once its node has been
//! calm for [`CALM_TICKS`] frames, within a time budget per frame.

use std::time::{Duration, Instant};

use bytemuck::{Pod, Zeroable};
use dmu_geom::Aabb3f;
use dmu_scene::Scene;
use dmu_tree::Tree;
use glam::{DVec3, Vec3};

use crate::geometry::{GeometrySource, pack_normal};
use crate::hierarchy::{Hierarchy, NodeKind};

mod stored;

pub use stored::{ChunkLoader, ProxyBlobs, StoredBuild, build_stored};

/// meshoptimizer's error is an estimate, not a bound (`dmu_scene::lod`
/// measured up to 1.82x it on a sphere), and welding and pruning merged CAD
/// pieces stray further: a proxy claims the farthest any vertex it was made
/// of lies from it ([`dmu_scene::simplified_error`] measures it), and at
/// least this multiple of the estimate. With 2 (before the measurement),
/// pixels showing another surface at 1 px of LOD error were 1.2-1.8 % of
/// the image on the 400k plant's viewpoints, with 4 0.5-1.1 % (chunk levels
/// alone: 0.3-0.9 %; test
/// `proxies_draw_far_subtrees_in_few_calls_within_the_pixel_bound`).
const ERROR_MARGIN: f64 = 4.0;

/// A piece of a simplification with a vertex farther than this multiple of
/// its aim is simplified again on its own, and a whole simplification whose
/// measured error is over it is tried again, aiming this many times lower
/// ...
const RETRY_OVER: f32 = 4.0;
/// ... at most this many times.
const RETRIES: usize = 1;

/// Levels between proxies: a proxy is made of the proxies this many levels
/// below (about twice smaller across in a binary tree of boxes), so the
/// errors that add up the tree stay near twice a level's own, and memory
/// goes to a third of the levels.
pub const LEVEL_STEP: u8 = 3;

/// A changed node's proxy is remade once its content has stayed the same for
/// this many frames (a drag changes it every frame: remaking it each time
/// would be wasted).
pub const CALM_TICKS: u64 = 2;

/// How proxies are made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProxyOptions {
    /// The simplification error each proxy aims at, as a fraction of its
    /// node's box diagonal (it claims the error measured for what it was
    /// made of, at least 4 times what the simplifier reports, plus the error
    /// of the proxies it is made of: `ERROR_MARGIN`). With the default
    /// 1/512 a proxy claiming 4 times its aim and its children's as much is
    /// drawn at 1 px of LOD error once its node covers under about 64 px.
    pub error_fraction: f64,
    /// Time a frame may spend remaking stale proxies (at least one is made
    /// when any is due).
    pub refresh_budget: Duration,
}

impl Default for ProxyOptions {
    fn default() -> Self {
        Self {
            error_fraction: 1.0 / 512.0,
            refresh_budget: Duration::from_millis(4),
        }
    }
}

/// A proxy vertex: position relative to the proxy's origin, normal in
/// snorm8, the chunk instance (entry) it came from and its material's colour
/// (rgb), so that a proxy without tinted parts reads no storage per vertex.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct ProxyVertex {
    pub position: [f32; 3],
    pub normal: [i8; 4],
    pub entry: u32,
    pub base: [f32; 3],
}
const _: () = assert!(size_of::<ProxyVertex>() == 32);

/// The stand-in of one tree node's subtree.
#[derive(Clone, Debug)]
pub(crate) struct Proxy {
    /// World point the vertices are relative to (the node box's centre).
    pub origin: DVec3,
    /// Its geometry on the CPU; a stored proxy's is dropped once uploaded
    /// (its parents are never made from it), the counts below stay.
    pub vertices: Vec<ProxyVertex>,
    pub indices: Vec<u32>,
    pub vertex_count: u32,
    pub index_count: u32,
    /// How far the proxy may lie from the subtree's surface, world units.
    pub error: f64,
    /// The content it shows ([`Proxies`]'s signature of its node then).
    signature: u64,
    /// Triangles of the chunk instances it stands for.
    pub source_triangles: u64,
    /// Whether its simplified mesh bounds solids with outward windings
    /// ([`dmu_scene::is_solid`]; so never where it holds an open mesh or a
    /// mirrored part): its back faces may be culled.
    pub solid: bool,
    /// Its triangles in spatially compact runs, which cover `indices` in
    /// order: `hzb` frames test each run's box and draw only those that may
    /// show (at most [`MAX_CLUSTERS`]).
    pub clusters: Vec<Cluster>,
}

/// A run of a proxy's triangles close together ([`Proxy::clusters`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Cluster {
    /// Its indices: `first_index..first_index + index_count` of the proxy's.
    pub first_index: u32,
    pub index_count: u32,
    /// Its vertices' box, relative to the proxy's origin.
    pub bounds: Aabb3f,
}

/// Triangles a proxy's cluster holds at most, where the proxy has at most
/// 32 times as many: about what a chunk at its level holds.
const CLUSTER_TRIANGLES: usize = 128;

/// Clusters a proxy has at most: the bits of a visibility mask.
pub(crate) const MAX_CLUSTERS: usize = 64;

/// Reorders a proxy's triangles (`indices` into `vertices`) into spatially
/// compact clusters ([`dmu_scene::spatial_runs`]), each in its source order
/// and the clusters in the order their first triangles come (in the order
/// the splits made them, frustum frames of the 10M plant, which draw
/// proxies whole, were 4 % slower), and its vertices in the order the
/// clusters first use them; the vertices, the indices and the clusters.
fn cluster(
    vertices: &[ProxyVertex],
    indices: &[u32],
) -> (Vec<ProxyVertex>, Vec<u32>, Vec<Cluster>) {
    let p = |i: u32| Vec3::from(vertices[i as usize].position);
    let mut items: Vec<(u32, Vec3)> = (indices.chunks_exact(3).zip(0..))
        .map(|(t, k)| (k, (p(t[0]) + p(t[1]) + p(t[2])) / 3.0))
        .collect();
    // Runs of at least half the bound: at most MAX_CLUSTERS of them.
    let max = CLUSTER_TRIANGLES.max(items.len().div_ceil(MAX_CLUSTERS / 2));
    let mut runs = dmu_scene::spatial_runs(&mut items, max);
    for run in &runs {
        items[run.clone()].sort_unstable_by_key(|&(k, _)| k);
    }
    // Runs in the order their first triangles come.
    runs.sort_unstable_by_key(|run| items[run.start].0);
    let mut ordered = Vec::with_capacity(indices.len());
    let clusters = runs
        .into_iter()
        .map(|run| {
            let run = &items[run];
            let first_index = ordered.len() as u32;
            let mut bounds = Aabb3f::EMPTY;
            for &(k, _) in run.iter() {
                for &i in &indices[3 * k as usize..3 * k as usize + 3] {
                    ordered.push(i);
                    bounds = bounds.grown(p(i));
                }
            }
            Cluster {
                first_index,
                index_count: ordered.len() as u32 - first_index,
                bounds,
            }
        })
        .collect();
    (first_use_order(vertices, &mut ordered), ordered, clusters)
}

/// The index ranges that draw the clusters of `clusters` in `mask` (bit c:
/// cluster c), neighbours merged.
pub(crate) fn cluster_ranges(clusters: &[Cluster], mask: u64) -> Vec<std::ops::Range<u32>> {
    let mut ranges: Vec<std::ops::Range<u32>> = Vec::new();
    for (c, cluster) in clusters.iter().enumerate() {
        if mask & (1 << c) == 0 {
            continue;
        }
        let range = cluster.first_index..cluster.first_index + cluster.index_count;
        match ranges.last_mut() {
            Some(last) if last.end == range.start => last.end = range.end,
            _ => ranges.push(range),
        }
    }
    ranges
}

impl Proxy {
    /// A proxy of `vertices` and `indices` (counted).
    #[expect(
        clippy::too_many_arguments,
        reason = "every field but the counts, which follow"
    )]
    pub(crate) fn new(
        origin: DVec3,
        vertices: Vec<ProxyVertex>,
        indices: Vec<u32>,
        error: f64,
        signature: u64,
        source_triangles: u64,
        solid: bool,
        clusters: Vec<Cluster>,
    ) -> Self {
        Proxy {
            origin,
            vertex_count: vertices.len() as u32,
            index_count: indices.len() as u32,
            vertices,
            indices,
            error,
            signature,
            source_triangles,
            solid,
            clusters,
        }
    }

    pub(crate) fn triangles(&self) -> u64 {
        u64::from(self.index_count) / 3
    }

    /// Whether its indices fit in 16 bits, as uploaded to the GPU.
    pub(crate) fn short_indices(&self) -> bool {
        self.vertex_count <= u32::from(u16::MAX) + 1
    }

    /// Bytes of its geometry (as uploaded to the GPU).
    pub(crate) fn geometry_bytes(&self) -> u64 {
        let index = if self.short_indices() { 2 } else { 4 };
        u64::from(self.vertex_count) * size_of::<ProxyVertex>() as u64
            + u64::from(self.index_count) * index
    }
}

/// What building or refreshing proxies did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProxyStats {
    /// Nodes with a current proxy.
    pub proxies: u64,
    /// Nodes whose proxy is stale or missing.
    pub stale: u64,
    /// Current proxies that bound solids (their back faces are culled).
    pub solid: u64,
    /// Triangles in all current proxies.
    pub triangles: u64,
    /// Bytes of proxy geometry (on the GPU; proxies made in memory keep a
    /// CPU copy too, a store's do not).
    pub bytes: u64,
    /// Proxies made by the last build or refresh.
    pub made: u64,
    /// Time the last build or refresh took, ms.
    pub ms: f64,
}

/// Proxies of every tree node, kept current with the scene (see the module
/// docs). Made on the CPU alone ([`Proxies::build`]), so an application can
/// make them on a loading thread, then hand them to
/// [`crate::Renderer::set_proxies`].
#[derive(Debug, Default)]
pub struct Proxies {
    pub(crate) options: ProxyOptions,
    /// By mirror node id ([`Hierarchy`]'s numbering: entries, then the
    /// tree's node slots); entries have none.
    pub(crate) nodes: Vec<Option<Box<Proxy>>>,
    /// Current content signature per mirror node.
    signature: Vec<u64>,
    /// Frame tick a node's signature last changed.
    changed: Vec<u64>,
    /// Per part: the hash of its transform and hidden flag.
    part_hash: Vec<u64>,
    /// The tree revision and hidden flags the signatures were summed for.
    seen: Option<(dmu_tree::Revision, Vec<bool>)>,
    /// Frame ticks ([`Proxies::sync`] calls).
    tick: u64,
    /// Per mirror node: whether it gets a proxy ([`Proxies::is_level`]).
    level: Vec<bool>,
    /// Nodes whose proxy changed since the renderer last uploaded them.
    pub(crate) dirty: Vec<u32>,
    /// [`Proxies::stale`] since the signatures or proxies last changed
    /// (`None`: to count again), so a frame does not walk every node.
    stale: std::sync::Mutex<Option<u64>>,
    /// What the last build or refresh did.
    pub(crate) last: ProxyStats,
    /// The store the proxies are read from on demand, if they are stored.
    pub(crate) stored: Option<stored::Stored>,
}

/// A 64-bit mix (splitmix64's finaliser).
fn mix(mut x: u64) -> u64 {
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

impl Proxies {
    /// Proxies of every node of `tree`, from the chunk geometry in `source`
    /// (a node any of whose chunks the source lacks gets none, nor do its
    /// ancestors); `progress` is told (nodes done, nodes).
    pub fn build(
        scene: &Scene,
        tree: &Tree,
        source: &dyn GeometrySource,
        options: ProxyOptions,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Self {
        let start = Instant::now();
        let (h, mut proxies, order) = Self::to_make(scene, tree, options);
        let total = order.len();
        let mut made = 0;
        for (i, &n) in order.iter().enumerate() {
            if proxies.remake(&h, scene, tree, source, n) {
                made += 1;
            }
            if i % 16 == 0 || i + 1 == total {
                progress(i + 1, total);
            }
        }
        proxies.dirty.clear();
        proxies.last = ProxyStats {
            made,
            ms: start.elapsed().as_secs_f64() * 1e3,
            ..proxies.stats()
        };
        proxies
    }

    /// A mirror of `tree`, no proxies yet with their signatures summed, and
    /// the nodes that get one, children before parents: what a build starts
    /// from.
    fn to_make(scene: &Scene, tree: &Tree, options: ProxyOptions) -> (Hierarchy, Self, Vec<u32>) {
        let mut h = Hierarchy::default();
        h.sync(tree);
        let mut proxies = Self {
            options,
            ..Self::default()
        };
        proxies.sync(&h, scene, tree);
        let order = post_order(&h)
            .into_iter()
            .filter(|&n| proxies.is_level(n))
            .collect();
        (h, proxies, order)
    }

    /// What is current now, and what the last build or refresh did.
    pub fn stats(&self) -> ProxyStats {
        let mut s = ProxyStats {
            made: self.last.made,
            ms: self.last.ms,
            ..ProxyStats::default()
        };
        for (n, p) in self.nodes.iter().enumerate() {
            match p {
                Some(p) if p.signature == self.signature[n] => {
                    s.proxies += 1;
                    s.solid += u64::from(p.solid);
                    s.triangles += p.triangles();
                    s.bytes += p.geometry_bytes();
                }
                _ => {}
            }
        }
        s.stale = self.stale();
        s
    }

    /// Nodes whose proxy is stale or missing: made in memory, a level node
    /// without a current proxy (remade once calm); a store's, a level node
    /// whose content has no stored proxy (an edit changed it; frames refine
    /// past it). Counted once after each change, not every frame.
    pub(crate) fn stale(&self) -> u64 {
        let mut cached = self.stale.lock().unwrap_or_else(|e| e.into_inner());
        *cached.get_or_insert_with(|| {
            let level = (0..self.level.len()).filter(|&n| self.level[n]);
            match &self.stored {
                Some(s) => level
                    .filter(|&n| !s.nodes.contains_key(&self.signature[n]))
                    .count() as u64,
                None => level.filter(|&n| self.current(n as u32).is_none()).count() as u64,
            }
        })
    }

    /// Forgets the stale count: signatures or proxies changed.
    fn count_stale_again(&mut self) {
        *self.stale.get_mut().unwrap_or_else(|e| e.into_inner()) = None;
    }

    /// The node's proxy when it shows the node's current content.
    pub(crate) fn current(&self, node: u32) -> Option<&Proxy> {
        let p = self.nodes.get(node as usize)?.as_ref()?;
        (p.signature == self.signature[node as usize]).then_some(p)
    }

    /// Brings the content signatures up to date with the tree and the
    /// scene's transforms and hidden flags (summed again only when the tree's
    /// revision or a hidden flag changed), and advances the frame tick.
    pub(crate) fn sync(&mut self, h: &Hierarchy, scene: &Scene, tree: &Tree) {
        self.tick += 1;
        let hidden_same = self.seen.as_ref().is_some_and(|(r, hidden)| {
            *r == tree.revision()
                && hidden.len() == scene.parts().len()
                && hidden
                    .iter()
                    .zip(scene.parts())
                    .all(|(&a, p)| a == p.hidden)
        });
        if hidden_same {
            return;
        }
        self.part_hash.clear();
        self.part_hash
            .extend(scene.part_ids().map(|p| scene.part_pose_hash(p)));
        let mut signature = vec![0u64; h.len()];
        let mut height = vec![0u8; h.len()];
        for n in post_order(h) {
            if let NodeKind::Internal = h.kind(n) {
                let below = h.children(n).iter().map(|&c| height[c as usize]).max();
                height[n as usize] = below.unwrap_or(0).saturating_add(1);
            }
            signature[n as usize] = match h.kind(n) {
                NodeKind::Entry(e) => {
                    let part = tree.entries()[e.0 as usize].part;
                    // Never 0 (0 is "no content"): an entry's hash is odd.
                    mix(self.part_hash[part.index()] ^ mix(u64::from(e.0))) | 1
                }
                _ => h
                    .children(n)
                    .iter()
                    .fold(0u64, |s, &c| s.wrapping_add(signature[c as usize])),
            };
        }
        self.level = (0..h.len())
            .map(|n| match h.kind(n as u32) {
                NodeKind::Entry(_) | NodeKind::Free => false,
                _ if n as u32 == h.root => true,
                _ => height[n] > 0 && height[n].is_multiple_of(LEVEL_STEP),
            })
            .collect();
        self.changed.resize(h.len(), 0);
        self.nodes.resize_with(h.len(), || None);
        for (n, (&new, old)) in signature.iter().zip(&self.signature).enumerate() {
            if new != *old {
                self.changed[n] = self.tick;
            }
        }
        for n in self.signature.len()..signature.len() {
            self.changed[n] = self.tick;
        }
        self.signature = signature;
        self.count_stale_again();
        self.seen = Some((
            tree.revision(),
            scene.parts().iter().map(|p| p.hidden).collect(),
        ));
    }

    /// Remakes stale proxies whose nodes have been calm for [`CALM_TICKS`],
    /// children first, until the time budget is spent (at least one when any
    /// is due); true when any was made. Stored proxies are not remade: a
    /// store's model is larger than memory, the proxies below a stale one
    /// are mostly not loaded, and looking for what could be made would cost
    /// every frame the model's size; frames refine past a stale one.
    pub(crate) fn refresh(
        &mut self,
        h: &Hierarchy,
        scene: &Scene,
        tree: &Tree,
        source: &dyn GeometrySource,
    ) -> bool {
        if self.stored.is_some() {
            return false;
        }
        let due = |p: &Self, n: u32| {
            let i = n as usize;
            p.level[i]
                && p.nodes[i]
                    .as_ref()
                    .is_none_or(|x| x.signature != p.signature[i])
                && p.tick >= p.changed[i] + CALM_TICKS
        };
        if !(0..self.nodes.len() as u32).any(|n| due(self, n)) {
            return false;
        }
        let start = Instant::now();
        let mut made = 0;
        for n in post_order(h) {
            if !due(self, n) {
                continue;
            }
            if made > 0 && start.elapsed() >= self.options.refresh_budget {
                break;
            }
            if self.remake(h, scene, tree, source, n) {
                made += 1;
            }
        }
        self.last = ProxyStats {
            made,
            ms: start.elapsed().as_secs_f64() * 1e3,
            ..ProxyStats::default()
        };
        made > 0
    }

    /// Whether node `n` gets a proxy: the root, and nodes [`LEVEL_STEP`]
    /// levels apart above the cells (cells themselves hold too little to
    /// simplify), as the tree stood at the last [`Proxies::sync`].
    pub(crate) fn is_level(&self, n: u32) -> bool {
        self.level.get(n as usize).copied().unwrap_or(false)
    }

    /// Makes node `n`'s proxy from its current content: the proxies of the
    /// nearest levels below, and the chunk instances of cells with none
    /// between. False (and no proxy) when a chunk is not in `source` or a
    /// level below has no current proxy.
    fn remake(
        &mut self,
        h: &Hierarchy,
        scene: &Scene,
        tree: &Tree,
        source: &dyn GeometrySource,
        n: u32,
    ) -> bool {
        let made = self.make(h, scene, tree, source, n);
        let some = made.is_some();
        self.nodes[n as usize] = made.map(Box::new);
        self.count_stale_again();
        if some {
            self.dirty.push(n);
        }
        some
    }

    /// Node `n`'s proxy made from its current content, as
    /// [`Proxies::remake`] makes it (`None` where it makes none); changes
    /// nothing, so many can be made at once.
    fn make(
        &self,
        h: &Hierarchy,
        scene: &Scene,
        tree: &Tree,
        source: &dyn GeometrySource,
        n: u32,
    ) -> Option<Proxy> {
        let mut merged = Merged {
            origin: h.bounds(tree, n).center(),
            ..Merged::default()
        };
        let complete = match h.kind(n) {
            NodeKind::Cell(_) => merged.add_cell(h, scene, tree, source, n),
            _ => h
                .children(n)
                .iter()
                .all(|&c| self.gather(h, scene, tree, source, c, &mut merged)),
        };
        if !complete {
            return None;
        }
        let target = self.options.error_fraction * h.bounds(tree, n).extent().length();
        let (vertices, indices, error) = simplify(merged.vertices, &merged.indices, target);
        let positions: Vec<Vec3> = vertices.iter().map(|v| Vec3::from(v.position)).collect();
        let solid = dmu_scene::is_solid(&positions, &indices);
        let (vertices, indices, clusters) = cluster(&vertices, &indices);
        Some(Proxy::new(
            merged.origin,
            vertices,
            indices,
            merged.error + error,
            self.signature[n as usize],
            merged.source_triangles,
            solid,
            clusters,
        ))
    }

    /// Adds what stands below node `c` to `merged`: its proxy at a level,
    /// a cell's chunk instances, or what its children add.
    fn gather(
        &self,
        h: &Hierarchy,
        scene: &Scene,
        tree: &Tree,
        source: &dyn GeometrySource,
        c: u32,
        merged: &mut Merged,
    ) -> bool {
        if self.is_level(c) {
            return match self.current(c) {
                Some(p) => {
                    merged.add_proxy(p);
                    true
                }
                None => false,
            };
        }
        match h.kind(c) {
            NodeKind::Cell(_) => merged.add_cell(h, scene, tree, source, c),
            NodeKind::Internal => h
                .children(c)
                .iter()
                .all(|&g| self.gather(h, scene, tree, source, g, merged)),
            NodeKind::Entry(_) | NodeKind::Free => true,
        }
    }
}

/// A proxy's input being merged.
#[derive(Default)]
struct Merged {
    origin: DVec3,
    vertices: Vec<ProxyVertex>,
    indices: Vec<u32>,
    /// The largest error of the proxies merged.
    error: f64,
    source_triangles: u64,
}

impl Merged {
    /// A cell's chunk instances, in entry order (the same content makes the
    /// same proxy, whatever order the cell took its entries in), placed in
    /// world space relative to the origin; hidden parts left out. False when
    /// the source lacks a chunk.
    fn add_cell(
        &mut self,
        h: &Hierarchy,
        scene: &Scene,
        tree: &Tree,
        source: &dyn GeometrySource,
        cell: u32,
    ) -> bool {
        let mut entries = h.children(cell).to_vec();
        entries.sort_unstable();
        for e in entries {
            let entry = &tree.entries()[e as usize];
            if scene.part(entry.part).hidden {
                continue;
            }
            let Some(g) = source.chunk_geometry(entry.chunk) else {
                return false;
            };
            self.source_triangles += u64::from(entry.triangles);
            let world = scene.part_world(entry.part);
            // Normals through the cofactor matrix (inverse transpose up to
            // scale), as the mesh shader does.
            let m = world.matrix3;
            let cofactor = glam::DMat3::from_cols(
                m.y_axis.cross(m.z_axis),
                m.z_axis.cross(m.x_axis),
                m.x_axis.cross(m.y_axis),
            );
            let base = self.vertices.len() as u32;
            let origin = self.origin;
            let [red, green, blue, _] =
                scene.materials()[scene.chunk(entry.chunk).material.index()].base_color;
            self.vertices
                .extend(g.positions.iter().zip(g.normals).map(|(p, nrm)| {
                    let w = world.transform_point3(p.as_dvec3()) - origin;
                    let nn = (cofactor * nrm.as_dvec3()).normalize_or_zero();
                    ProxyVertex {
                        position: w.as_vec3().to_array(),
                        normal: pack_normal(nn.as_vec3()),
                        entry: e,
                        base: [red, green, blue],
                    }
                }));
            self.indices.extend(g.indices.iter().map(|&i| base + i));
        }
        true
    }

    /// A proxy of a level below, moved to this origin.
    fn add_proxy(&mut self, p: &Proxy) {
        let offset = p.origin - self.origin;
        let base = self.vertices.len() as u32;
        self.vertices.extend(p.vertices.iter().map(|v| {
            ProxyVertex {
                position: (Vec3::from(v.position).as_dvec3() + offset)
                    .as_vec3()
                    .to_array(),
                ..*v
            }
        }));
        self.indices.extend(p.indices.iter().map(|&i| base + i));
        self.error = self.error.max(p.error);
        self.source_triangles += p.source_triangles;
    }
}

/// The mirror's nodes under the root, children before parents.
fn post_order(h: &Hierarchy) -> Vec<u32> {
    let mut order = h.pre_order();
    order.reverse();
    order
}

/// Simplifies a merged mesh until its error reaches `target_error` (world
/// units), pruning pieces smaller than that; the used vertices, the indices
/// into them and the error they claim (measured, see [`ERROR_MARGIN`]).
///
/// CAD chunks repeat a vertex per face at every hard edge (a box has 24), so
/// to the simplifier every face would be a piece of its own that cannot
/// collapse: it simplifies the positions welded (equal positions are one
/// vertex), and each kept triangle's corner then takes, of the vertices
/// welded there, the one whose normal best matches the triangle's, so hard
/// edges keep their shading.
fn simplify(
    vertices: Vec<ProxyVertex>,
    indices: &[u32],
    target_error: f64,
) -> (Vec<ProxyVertex>, Vec<u32>, f64) {
    // Weld: one canonical vertex per distinct position.
    let mut canonical: std::collections::HashMap<[u32; 3], u32> =
        std::collections::HashMap::with_capacity(vertices.len());
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let weld: Vec<u32> = vertices
        .iter()
        .map(|v| {
            let key = v.position.map(f32::to_bits);
            *canonical.entry(key).or_insert_with(|| {
                positions.push(v.position);
                positions.len() as u32 - 1
            })
        })
        .collect();
    // The vertices welded into each canonical one (compressed rows).
    let mut start = vec![0u32; positions.len() + 1];
    for &c in &weld {
        start[c as usize + 1] += 1;
    }
    for i in 0..positions.len() {
        start[i + 1] += start[i];
    }
    let mut members = vec![0u32; vertices.len()];
    let mut fill = start.clone();
    for (v, &c) in weld.iter().enumerate() {
        members[fill[c as usize] as usize] = v as u32;
        fill[c as usize] += 1;
    }
    let welded: Vec<u32> = indices.iter().map(|&i| weld[i as usize]).collect();
    // The simplifier's estimate can be far short of what it did: on merged
    // CAD pieces it wears a thin flange or plate away to nothing, leaving
    // its vertices metres from a proxy aimed at centimetres. Pieces so
    // mangled (a vertex over RETRY_OVER times the aim away) are simplified
    // again on their own, aiming lower, or kept whole; where the measured
    // error is still over RETRY_OVER times the aim, everything runs again
    // aiming lower, and the measured better of the tries is kept.
    let mut aim = target_error as f32;
    let mut best: Option<(Vec<u32>, f32)> = None;
    for _ in 0..=RETRIES {
        let (kept, error) = dmu_scene::simplify_mended(
            &positions,
            &welded,
            aim,
            RETRY_OVER * aim,
            aim / RETRY_OVER,
            ERROR_MARGIN as f32,
        );
        if best.as_ref().is_none_or(|b| error < b.1) {
            best = Some((kept, error));
        }
        if error <= RETRY_OVER * target_error as f32 {
            break;
        }
        aim /= RETRY_OVER;
    }
    let (simplified, error) = best.expect("one try at least");
    // Back to real vertices, keeping only those used, in first-use order.
    let mut out = Vec::with_capacity(simplified.len());
    for t in simplified.chunks_exact(3) {
        let p = |c: u32| Vec3::from(positions[c as usize]);
        let face = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
        for &c in t {
            let candidates = &members[start[c as usize] as usize..start[c as usize + 1] as usize];
            let normal = |v: u32| {
                let n = vertices[v as usize].normal;
                Vec3::new(f32::from(n[0]), f32::from(n[1]), f32::from(n[2]))
            };
            let best = candidates
                .iter()
                .copied()
                .max_by(|&a, &b| {
                    face.dot(normal(a))
                        .abs()
                        .total_cmp(&face.dot(normal(b)).abs())
                })
                .expect("a canonical vertex welds at least one");
            out.push(best);
        }
    }
    (first_use_order(&vertices, &mut out), out, f64::from(error))
}

/// The vertices `indices` use, in the order first used, with `indices`
/// renumbered to match: a CPU rasterizer's vertex cache hits most where a
/// draw's indices stay close together.
fn first_use_order(vertices: &[ProxyVertex], indices: &mut [u32]) -> Vec<ProxyVertex> {
    let mut remap = vec![u32::MAX; vertices.len()];
    let mut kept = Vec::new();
    for i in indices {
        let slot = &mut remap[*i as usize];
        if *slot == u32::MAX {
            *slot = kept.len() as u32;
            kept.push(vertices[*i as usize]);
        }
        *i = *slot;
    }
    kept
}

/// Proxies and the vertex and index buffer of each current one (by mirror node).
#[derive(Debug)]
pub(crate) struct ProxyGpu {
    pub cpu: Proxies,
    /// By mirror node (a map: a store's proxies are loaded a few at a time).
    pub buffers: std::collections::HashMap<u32, ProxyBuffers>,
}

/// A proxy's buffers on the GPU.
#[derive(Debug)]
pub(crate) struct ProxyBuffers {
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    /// 16-bit where its vertices allow ([`Proxy::short_indices`]).
    pub format: wgpu::IndexFormat,
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmu_samples::{PlantOptions, Rng, plant};
    use dmu_scene::PartId;
    use dmu_tree::TreeOptions;
    use glam::DAffine3;

    /// A fresh build on the current state: the brute-force answer.
    fn fresh(scene: &Scene, tree: &Tree) -> Proxies {
        Proxies::build(scene, tree, scene, ProxyOptions::default(), &mut |_, _| {})
    }

    /// A plant of 250,000 triangles and its tree.
    pub(super) fn plant_250k() -> (Scene, Tree) {
        let scene = plant(&PlantOptions {
            triangles: 250_000,
            ..Default::default()
        });
        let tree = Tree::build(&scene, TreeOptions::default());
        (scene, tree)
    }

    fn same(a: &Proxy, b: &Proxy) -> bool {
        a.origin == b.origin
            && a.vertices == b.vertices
            && a.indices == b.indices
            && a.error == b.error
            && a.source_triangles == b.source_triangles
            && a.clusters == b.clusters
    }

    /// Kept current through random moves, hides and frames, every proxy the
    /// renderer would draw is the one a fresh build makes of what its node
    /// holds now; once calm, all of them are there again.
    #[test]
    fn kept_proxies_equal_a_fresh_build_through_moves_and_hides() {
        let mut scene = plant(&PlantOptions {
            triangles: 250_000,
            ..Default::default()
        });
        let mut tree = Tree::build(&scene, TreeOptions::default());
        let mut h = Hierarchy::default();
        h.sync(&tree);
        let mut kept = fresh(&scene, &tree);
        let first = kept.stats();
        assert!(first.proxies > 0 && first.stale == 0, "{first:?}");
        assert!(
            first.triangles > 0 && kept.current(h.root).is_some(),
            "the root has a proxy"
        );
        let mut rng = Rng::new(7);
        let parts = scene.parts().len() as u32;
        for round in 0..12 {
            // A few edits, then frames: some too few to calm down.
            for _ in 0..3 {
                let part = PartId(rng.below(u64::from(parts)) as u32);
                if rng.below(4) == 0 {
                    let hidden = !scene.part(part).hidden;
                    scene.set_part_hidden(part, hidden);
                } else {
                    let by = DVec3::new(
                        rng.range(-20_000.0, 20_000.0),
                        rng.range(-20_000.0, 20_000.0),
                        rng.range(-2_000.0, 2_000.0),
                    );
                    let world = DAffine3::from_translation(by) * scene.part_world(part);
                    tree.move_part(&mut scene, part, world);
                }
            }
            let frames = 1 + round % 4;
            for _ in 0..frames {
                h.sync(&tree);
                kept.sync(&h, &scene, &tree);
                kept.refresh(&h, &scene, &tree, &scene);
            }
            let truth = fresh(&scene, &tree);
            let mut current = 0;
            for n in 0..h.len() as u32 {
                if let Some(p) = kept.current(n) {
                    current += 1;
                    let t = truth.nodes[n as usize]
                        .as_ref()
                        .expect("a fresh build has it");
                    assert!(
                        same(p, t),
                        "round {round}: node {n} differs from a fresh build"
                    );
                }
            }
            println!("round {round}: {current} current, {:?}", kept.stats());
        }
        // Calm: every node's proxy is made again.
        for _ in 0..200 {
            h.sync(&tree);
            kept.sync(&h, &scene, &tree);
            kept.refresh(&h, &scene, &tree, &scene);
        }
        let truth = fresh(&scene, &tree);
        assert_eq!(kept.stats().stale, 0);
        assert_eq!(kept.stats().proxies, truth.stats().proxies);
    }

    /// Proxies are simpler than what they stand for, claim an error no larger
    /// than their aim plus their children's, and keep each vertex's entry one
    /// of their subtree's.
    #[test]
    fn proxies_simplify_within_their_claim_and_keep_entries() {
        let (scene, tree) = plant_250k();
        let mut h = Hierarchy::default();
        h.sync(&tree);
        let proxies = fresh(&scene, &tree);
        let root = proxies.current(h.root).expect("root proxy");
        assert!(
            root.triangles() * 4 < root.source_triangles,
            "{} of {}",
            root.triangles(),
            root.source_triangles
        );
        let mut below = Vec::new();
        for n in 0..h.len() as u32 {
            let Some(p) = proxies.current(n) else {
                continue;
            };
            below.clear();
            h.leaves(n, &mut below);
            below.sort_unstable();
            for v in &p.vertices {
                assert!(below.binary_search(&v.entry).is_ok(), "node {n}");
            }
            assert!(p.indices.iter().all(|&i| (i as usize) < p.vertices.len()));
            // What it was made of: the proxies of the levels below.
            let mut stack = h.children(n).to_vec();
            let mut children_error = 0f64;
            while let Some(c) = stack.pop() {
                match proxies.current(c) {
                    Some(p) => children_error = children_error.max(p.error),
                    None => stack.extend_from_slice(h.children(c)),
                }
            }
            // Errors add up the tree (the bound itself: the test below).
            assert!(p.error >= children_error, "node {n}");
            assert!(p.triangles() <= p.source_triangles, "node {n}");
        }
    }

    /// A proxy's claimed error bounds how far the chunk geometry it stands
    /// for lies from it, by brute force: every vertex of every chunk
    /// instance below (in world space, in f64) is within the error of the
    /// proxy's nearest triangle, but for vertices of pieces (connected
    /// through shared positions in their chunk) no larger than the error,
    /// which may vanish whole, and of thin pieces that vanished (a rod worn
    /// down to its axis), whose vertices lie within the error of their axis.
    #[test]
    fn proxy_errors_bound_the_distance_of_every_vertex_below() {
        let scene = plant(&PlantOptions {
            triangles: 40_000,
            ..Default::default()
        });
        let tree = Tree::build(&scene, TreeOptions::default());
        let mut h = Hierarchy::default();
        h.sync(&tree);
        let proxies = fresh(&scene, &tree);
        let (mut checked, mut worst, mut vanished) = (0u64, 0f64, 0u64);
        let mut leaves = Vec::new();
        for n in 0..h.len() as u32 {
            let Some(p) = proxies.current(n) else {
                continue;
            };
            let triangles: Vec<[DVec3; 3]> = p
                .indices
                .chunks_exact(3)
                .map(|t| {
                    [t[0], t[1], t[2]]
                        .map(|i| p.origin + Vec3::from(p.vertices[i as usize].position).as_dvec3())
                })
                .collect();
            leaves.clear();
            h.leaves(n, &mut leaves);
            for &e in &leaves {
                let entry = &tree.entries()[e as usize];
                let g = scene.chunk_geometry(entry.chunk).expect("loaded");
                let world = scene.part_world(entry.part);
                let points: Vec<DVec3> = g
                    .positions
                    .iter()
                    .map(|v| world.transform_point3(v.as_dvec3()))
                    .collect();
                let piece = piece_sizes(g.positions, g.indices, &points);
                let within = |d: f64| d <= p.error * (1.0 + 1e-5) + 1e-6;
                for (v, &w) in points.iter().enumerate() {
                    let (diagonal, off_axis) = piece[v];
                    if diagonal <= p.error {
                        continue;
                    }
                    let d = triangles
                        .iter()
                        .map(|&t| w.distance(dmu_geom::closest_point_on_triangle(w, t)))
                        .fold(f64::INFINITY, f64::min);
                    checked += 1;
                    if within(d) {
                        worst = worst.max(d / p.error);
                        continue;
                    }
                    // Farther: only a thin piece that vanished may be.
                    vanished += 1;
                    assert!(
                        within(off_axis),
                        "node {n}: a vertex of entry {e} lies {d} from the proxy, which claims {}, and its piece {off_axis} from its axis",
                        p.error
                    );
                }
            }
        }
        println!(
            "{checked} vertices checked; the farthest at {worst:.3} of its proxy's claim; {vanished} farther, of thin pieces within it of their axes"
        );
        assert!(checked > 10_000);
    }

    /// Per vertex of a chunk (part-local `positions` and `indices`, world
    /// `points`), the extent of its piece (the triangles connected to it
    /// through vertices at equal positions) that a proxy may drop it within:
    /// the diagonal of the piece's world box (a piece that small may vanish),
    /// and the farthest its vertices lie from their principal axis (found
    /// here by Jacobi rotations of their covariance; a rod that vanishes
    /// leaves a strip as wide as that).
    fn piece_sizes(positions: &[Vec3], indices: &[u32], points: &[DVec3]) -> Vec<(f64, f64)> {
        let n = positions.len();
        let mut piece: Vec<usize> = (0..n).collect();
        fn find(piece: &mut [usize], v: usize) -> usize {
            if piece[v] != v {
                let r = find(piece, piece[v]);
                piece[v] = r;
            }
            piece[v]
        }
        let mut same: std::collections::HashMap<[u32; 3], usize> = Default::default();
        for (v, p) in positions.iter().enumerate() {
            let first = *same.entry(p.to_array().map(f32::to_bits)).or_insert(v);
            let (a, b) = (find(&mut piece, first), find(&mut piece, v));
            piece[a] = b;
        }
        for t in indices.chunks_exact(3) {
            for k in 1..3 {
                let (a, b) = (
                    find(&mut piece, t[0] as usize),
                    find(&mut piece, t[k] as usize),
                );
                piece[a] = b;
            }
        }
        let mut members: std::collections::HashMap<usize, Vec<DVec3>> = Default::default();
        for (v, &p) in points.iter().enumerate() {
            members.entry(find(&mut piece, v)).or_default().push(p);
        }
        let sizes: std::collections::HashMap<usize, (f64, f64)> = members
            .iter()
            .map(|(&r, ps)| {
                let (lo, hi) = ps
                    .iter()
                    .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                        (lo.min(p), hi.max(p))
                    });
                let mean = ps.iter().sum::<DVec3>() / ps.len() as f64;
                let axis = principal_axis(ps, mean);
                let off_axis = ps
                    .iter()
                    .map(|&p| {
                        let d = p - mean;
                        (d - axis * d.dot(axis)).length()
                    })
                    .fold(0.0, f64::max);
                (r, ((hi - lo).length(), off_axis))
            })
            .collect();
        (0..n).map(|v| sizes[&find(&mut piece, v)]).collect()
    }

    /// The eigenvector of the largest eigenvalue of `points`' covariance
    /// about `mean`, by cyclic Jacobi rotations.
    fn principal_axis(points: &[DVec3], mean: DVec3) -> DVec3 {
        let mut a = [[0.0f64; 3]; 3];
        for p in points {
            let d = (*p - mean).to_array();
            for i in 0..3 {
                for j in 0..3 {
                    a[i][j] += d[i] * d[j];
                }
            }
        }
        let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for _ in 0..50 {
            for (p, q) in [(0, 1), (0, 2), (1, 2)] {
                if a[p][q].abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
                for row in &mut a {
                    let (x, y) = (row[p], row[q]);
                    row[p] = c * x - s * y;
                    row[q] = s * x + c * y;
                }
                let (rp, rq) = (a[p], a[q]);
                a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
                a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
                for row in &mut v {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
        let k = (0..3)
            .max_by(|&i, &j| a[i][i].total_cmp(&a[j][j]))
            .expect("three");
        DVec3::new(v[0][k], v[1][k], v[2][k])
    }

    /// Every proxy's clusters cover its indices in order, each a whole
    /// number of triangles inside its box, at most `MAX_CLUSTERS` of them,
    /// more than one where the proxy holds more than a cluster's bound; the
    /// clustering only reorders triangles; a mask's ranges draw exactly its
    /// clusters' indices.
    #[test]
    fn proxy_clusters_partition_the_triangles_within_their_boxes() {
        let (scene, tree) = plant_250k();
        let proxies = fresh(&scene, &tree);
        let mut rng = Rng::new(7);
        let mut split = 0;
        for p in proxies.nodes.iter().flatten() {
            assert!(p.clusters.len() <= MAX_CLUSTERS);
            let mut next = 0;
            for c in &p.clusters {
                assert_eq!(c.first_index, next);
                assert!(c.index_count > 0 && c.index_count % 3 == 0);
                next += c.index_count;
                for &i in &p.indices[c.first_index as usize..next as usize] {
                    let v = Vec3::from(p.vertices[i as usize].position);
                    assert!(c.bounds.min.cmple(v).all() && v.cmple(c.bounds.max).all());
                }
            }
            assert_eq!(next as usize, p.indices.len());
            if p.triangles() > CLUSTER_TRIANGLES as u64 {
                assert!(p.clusters.len() > 1, "{} triangles", p.triangles());
                split += 1;
            }
            // Clustering again finds the same triangles (as their corners'
            // vertices), as a set, and numbers vertices in first use.
            let (vertices, again, _) = cluster(&p.vertices, &p.indices);
            let triangles = |vertices: &[ProxyVertex], indices: &[u32]| {
                let mut t: Vec<Vec<[u32; 8]>> = (indices.chunks_exact(3))
                    .map(|t| {
                        t.iter()
                            .map(|&i| bytemuck::cast(vertices[i as usize]))
                            .collect()
                    })
                    .collect();
                t.sort_unstable();
                t
            };
            assert_eq!(
                triangles(&vertices, &again),
                triangles(&p.vertices, &p.indices)
            );
            let mut seen = 0;
            for &i in &again {
                assert!(i <= seen);
                seen = seen.max(i + 1);
            }
            assert_eq!(seen as usize, vertices.len());
            // A random mask draws its clusters' indices, in order, merged.
            let mask = rng.next_u64();
            let ranges = cluster_ranges(&p.clusters, mask);
            let drawn: Vec<u32> = ranges.iter().flat_map(|r| r.clone()).collect();
            let expected: Vec<u32> = (p.clusters.iter().enumerate())
                .filter(|&(c, _)| mask & (1 << c) != 0)
                .flat_map(|(_, c)| c.first_index..c.first_index + c.index_count)
                .collect();
            assert_eq!(drawn, expected);
            assert!(ranges.windows(2).all(|w| w[0].end < w[1].start));
        }
        assert!(split > 0, "some proxy must hold several clusters");
    }
}
