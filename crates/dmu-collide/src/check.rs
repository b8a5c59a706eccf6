//! The discrete check: moved parts at their current poses against everything.

use std::fmt;
use std::sync::{Mutex, PoisonError};

use dmu_geom::Aabb3d;
use dmu_scene::{ChunkId, PartId, Scene};
use dmu_tree::{ChunkBvhCache, EntryId, Tree};
use glam::DVec3;

use crate::contain::{Closedness, point_inside};
use crate::enclose::Enclosers;
use crate::narrow::{
    PairScratch, PairSearch, Placement, TrianglePair, box_gap_squared, chunk_pair, pair_tolerance,
    part_tolerance, seed,
};
use crate::sweep::Path;

/// Default contact tolerance, relative to part size (see [`Settings::contact_tolerance`]).
pub const DEFAULT_CONTACT_TOLERANCE: f64 = 1e-6;

/// What to look for.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Parts closer than this (model units, millimetres in the plant) are a soft
    /// clash; 0 looks for hard clashes and contacts only.
    pub clearance: f64,
    /// Contact tolerance, relative: for a pair of parts it is this times the larger
    /// of the two parts' scales (world size, or local coordinate magnitude if
    /// larger). Surfaces closer than it touch; surfaces crossing by less than it
    /// touch too. 1e-6 is some 8 f32 ulps of the part's own coordinates, far
    /// above f64 rounding of the world pose even 10^7 mm from the origin, far
    /// below any modelled gap.
    pub contact_tolerance: f64,
    /// Part pairs that may touch or interpenetrate (a bolt in its hole).
    pub allow: AllowList,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            clearance: 0.0,
            contact_tolerance: DEFAULT_CONTACT_TOLERANCE,
            allow: AllowList::default(),
        }
    }
}

impl Settings {
    /// Default settings with a clearance.
    pub fn with_clearance(clearance: f64) -> Self {
        Self {
            clearance,
            ..Self::default()
        }
    }
}

/// Unordered pairs of parts that are never reported.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AllowList {
    /// Sorted, each pair as (smaller, larger), no duplicates.
    pairs: Vec<(PartId, PartId)>,
}

impl AllowList {
    /// Allows the pair (in either order).
    pub fn allow(&mut self, a: PartId, b: PartId) {
        let key = (a.min(b), a.max(b));
        if let Err(at) = self.pairs.binary_search(&key) {
            self.pairs.insert(at, key);
        }
    }

    /// Whether the pair is allowed.
    pub fn allows(&self, a: PartId, b: PartId) -> bool {
        self.pairs.binary_search(&(a.min(b), a.max(b))).is_ok()
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Whether no pair is allowed.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
}

impl FromIterator<(PartId, PartId)> for AllowList {
    fn from_iter<I: IntoIterator<Item = (PartId, PartId)>>(iter: I) -> Self {
        let mut list = Self::default();
        for (a, b) in iter {
            list.allow(a, b);
        }
        list
    }
}

/// How bad a clash is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ClashKind {
    /// The parts interpenetrate: surfaces cross deeper than the contact
    /// tolerance, coincide facing the same way, or one closed part holds the other.
    Hard,
    /// The surfaces touch within the contact tolerance without penetrating.
    Contact,
    /// Apart, but closer than the clearance.
    Soft,
}

impl ClashKind {
    /// `hard`, `contact` or `soft`.
    pub fn as_str(self) -> &'static str {
        crate::FindingKind::from(self).as_str()
    }
}

impl fmt::Display for ClashKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A clash between two parts: the worst over all their triangle pairs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clash {
    /// A moved part.
    pub a: PartId,
    /// The other part (also moved, then with a larger id than `a`).
    pub b: PartId,
    /// Hard, contact or soft.
    pub kind: ClashKind,
    /// Distance between the surfaces (0 for hard clashes), model units.
    pub distance: f64,
    /// A world point of the clash: midway between the closest points, a point of
    /// the crossing, or (containment) a vertex of the inner part.
    pub point: DVec3,
    /// Unit world direction in which to move `b` away from `a` (see
    /// [`TriangleClash::normal`](crate::TriangleClash::normal)).
    pub normal: DVec3,
}

/// How far apart two parts are ([`Checker::distance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Separation {
    /// Minimum distance between the surfaces, model units (0 when they cross).
    pub distance: f64,
    /// The closest point on the first part, world.
    pub point_a: DVec3,
    /// The closest point on the second part, world.
    pub point_b: DVec3,
    /// The surfaces cross deeper than the pair's contact tolerance.
    pub penetrating: bool,
}

/// The first impact of a part moving along a motion (see [`Checker::sweep`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Impact {
    /// A moving part.
    pub a: PartId,
    /// The part it meets (also moving, then with a larger id than `a`).
    pub b: PartId,
    /// When, as a fraction of the motion in `[0, 1]`.
    pub toi: f64,
    /// Distance at that time (within the contact tolerance unless the
    /// advancement ran out of iterations, see [`Checker::sweep`]).
    pub distance: f64,
    /// World point of the impact, at that time.
    pub point: DVec3,
}

/// What a check found, with its work counters.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Report {
    /// One per clashing part pair, in order of (a, b).
    pub clashes: Vec<Clash>,
    /// One per part pair that meets during a swept motion, in order of (a, b).
    pub impacts: Vec<Impact>,
    /// Part pairs that reached the narrow phase.
    pub part_pairs_tested: u64,
    /// Chunk pairs whose triangles were compared.
    pub chunk_pairs_tested: u64,
}

impl Report {
    /// Empties it, keeping the allocations.
    pub fn clear(&mut self) {
        self.clashes.clear();
        self.impacts.clear();
        self.part_pairs_tested = 0;
        self.chunk_pairs_tested = 0;
    }

    /// No clash and no impact.
    pub fn is_clear(&self) -> bool {
        self.clashes.is_empty() && self.impacts.is_empty()
    }
}

/// A candidate pair from the broad phase: chunk `ca` of part `a` near chunk `cb`
/// of part `b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct ChunkPair {
    pub a: PartId,
    pub b: PartId,
    pub ca: ChunkId,
    pub cb: ChunkId,
}

/// The end of the run of (sorted) chunk pairs starting at `start` that share its
/// part pair: the narrow phase and the sweep handle one part pair at a time.
pub(crate) fn run_end(pairs: &[ChunkPair], start: usize) -> usize {
    let (a, b) = (pairs[start].a, pairs[start].b);
    start
        + pairs[start..]
            .iter()
            .take_while(|p| p.a == a && p.b == b)
            .count()
}

/// Collision checks on one scene, with the per-chunk meshes they build on first
/// use and scratch buffers reused from call to call (no allocation per call
/// once warm, except for what a report grows to).
#[derive(Debug)]
pub struct Checker {
    /// The chunks' BVHs, built on first use.
    pub(crate) bvhs: ChunkBvhCache,
    /// The narrow phase's scratch (behind a lock, never contended: the sweep's
    /// search reads the checker while it advances, and a checker stays `Sync`).
    scratch: Mutex<PairScratch>,
    closed: Closedness,
    /// The largest part scale in the scene, for the broad phase's margin: no
    /// pair's contact tolerance exceeds the relative tolerance times it.
    max_scale: f64,
    pub(crate) moved: Vec<PartId>,
    pub(crate) found: Vec<EntryId>,
    pub(crate) pairs: Vec<ChunkPair>,
    /// Part pairs (moved, other) where one part's box holds the other's: the
    /// candidates for containment, whether or not any of their chunks are near.
    nested: Vec<(PartId, PartId)>,
    /// Parts whose boxes hold a moved part's box, kept current with the tree.
    enclosers: Enclosers,
    near_parts: Vec<PartId>,
    /// Per part pair of the last check, sorted: its nearest triangle pair, tried
    /// first at the next check (consecutive poses differ by millimetres).
    seeds: Vec<((PartId, PartId), TrianglePair)>,
    next_seeds: Vec<((PartId, PartId), TrianglePair)>,
    hits: Vec<f64>,
    /// Moving parts of a sweep, sorted, with their paths.
    pub(crate) paths: Vec<(PartId, Path)>,
    /// Each moving chunk's swept world box.
    pub(crate) swept: Vec<(PartId, ChunkId, Aabb3d)>,
}

impl Checker {
    /// A checker for `scene` (its chunk and mesh counts, its part sizes).
    pub fn new(scene: &Scene) -> Self {
        let max_scale = scene
            .part_ids()
            .map(|p| part_tolerance(scene, p, 1.0))
            .fold(0.0, f64::max);
        Self {
            bvhs: ChunkBvhCache::new(scene.chunks().len()),
            scratch: Mutex::default(),
            closed: Closedness::new(scene.meshes().len()),
            max_scale,
            moved: Vec::new(),
            found: Vec::new(),
            pairs: Vec::new(),
            nested: Vec::new(),
            enclosers: Enclosers::default(),
            near_parts: Vec::new(),
            seeds: Vec::new(),
            next_seeds: Vec::new(),
            hits: Vec::new(),
            paths: Vec::new(),
            swept: Vec::new(),
        }
    }

    /// Builds now what the first check would build over the whole model
    /// (the index of whole-part boxes), so that a process under a memory
    /// budget holds it before it sizes the rest. `tree` must be up to date
    /// with `scene`.
    pub fn prepare(&mut self, scene: &Scene, tree: &Tree) {
        self.enclosers.sync(scene, tree);
    }

    /// Chunks whose BVH has been built so far (chunks of at most 16 triangles,
    /// which need none, count once tested).
    pub fn chunk_meshes_built(&self) -> usize {
        self.bvhs.built()
    }

    /// Clashes of the `moved` parts, at their current poses, with every other
    /// visible part, found through the tree: each moved chunk's box, inflated by
    /// the clearance, gathers the chunks near it. Only pairs involving a moved
    /// part are tested, a pair of two moved parts once; hidden parts and allowed
    /// pairs are skipped. `tree` must be up to date with `scene`.
    ///
    /// Containment is found whatever the chunk layout: the closed parts whose
    /// boxes hold a moved part's box come from an index over whole-part boxes
    /// (kept current through the tree's change log), and a closed moved part
    /// is tested against every part whose box lies inside its own.
    pub fn check(
        &mut self,
        scene: &Scene,
        tree: &Tree,
        moved: &[PartId],
        settings: &Settings,
        report: &mut Report,
    ) {
        report.clear();
        self.set_moved(moved);
        self.pairs.clear();
        self.nested.clear();
        self.enclosers.sync(scene, tree);
        let margin = self.margin(settings);
        let entries = tree.entries();
        for i in 0..self.moved.len() {
            let a = self.moved[i];
            if scene.part(a).hidden {
                continue;
            }
            let box_a = scene.part_world_bounds(a);
            self.near_parts.clear();
            self.enclosers
                .containing(scene, &box_a, &mut self.near_parts);
            if self.closed.is_closed(scene, scene.part(a).mesh) {
                self.found.clear();
                tree.entries_in_box(&box_a, &mut self.found);
                self.near_parts.extend(
                    self.found
                        .iter()
                        .map(|e| entries[e.0 as usize].part)
                        .filter(|&b| box_a.contains(&scene.part_world_bounds(b))),
                );
            }
            self.keep_nested(scene, settings, a);
            for ea in tree.part_entries(a) {
                let query = entries[ea.0 as usize].bounds.inflated(margin);
                self.found.clear();
                tree.entries_in_box(&query, &mut self.found);
                for &eb in &self.found {
                    let e = &entries[eb.0 as usize];
                    if self.wanted(scene, settings, a, e.part) {
                        self.pairs.push(ChunkPair {
                            a,
                            b: e.part,
                            ca: entries[ea.0 as usize].chunk,
                            cb: e.chunk,
                        });
                    }
                }
            }
        }
        self.narrow(scene, settings, report);
    }

    /// The minimum distance between parts `a` and `b` and its closest points,
    /// world f64, by the narrow phase every check uses (so it equals the
    /// distance a soft clash of the pair reports at a clearance above it);
    /// `None` when either part has no triangles. Penetrating parts give
    /// distance 0 at a point of the crossing; a part wholly inside a closed
    /// one gives the distance between their surfaces (it is not 0).
    pub fn distance(
        &self,
        scene: &Scene,
        settings: &Settings,
        a: PartId,
        b: PartId,
    ) -> Option<Separation> {
        let world_a = scene.part_world(a);
        let origin = world_a.translation;
        let place_a = Placement::new(&world_a, origin);
        let place_b = Placement::new(&scene.part_world(b), origin);
        let mut pairs: Vec<(f64, ChunkPair)> = Vec::new();
        for ca in scene.part_mesh(a).chunk_ids() {
            let box_a = scene.chunk(ca).bounds.transformed(&place_a.to_pair);
            for cb in scene.part_mesh(b).chunk_ids() {
                let box_b = scene.chunk(cb).bounds.transformed(&place_b.to_pair);
                pairs.push((box_gap_squared(&box_a, &box_b), ChunkPair { a, b, ca, cb }));
            }
        }
        // Nearest boxes first: the first pairs shrink the search for the rest.
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
        let pairs: Vec<ChunkPair> = pairs.into_iter().map(|(_, p)| p).collect();
        let tolerance = pair_tolerance(scene, a, b, settings.contact_tolerance);
        let mut search = PairSearch::new(tolerance, f64::INFINITY);
        let mut scratch_report = Report::default();
        self.search_chunk_pairs(
            scene,
            &pairs,
            (&place_a, &place_b),
            &mut search,
            &mut scratch_report,
        );
        search.best.map(|t| Separation {
            distance: t.distance,
            point_a: origin + t.point_a,
            point_b: origin + t.point_b,
            penetrating: t.penetrating,
        })
    }

    /// The same check without the tree: every visible part's box against each
    /// moved part's, then chunk boxes. The reference the tree is measured
    /// against, in results (equal) and time.
    pub fn check_without_tree(
        &mut self,
        scene: &Scene,
        moved: &[PartId],
        settings: &Settings,
        report: &mut Report,
    ) {
        report.clear();
        self.set_moved(moved);
        self.pairs.clear();
        self.nested.clear();
        let margin = self.margin(settings);
        for i in 0..self.moved.len() {
            let a = self.moved[i];
            if scene.part(a).hidden {
                continue;
            }
            let box_a = scene.part_world_bounds(a);
            self.near_parts.clear();
            self.near_parts.extend(scene.part_ids().filter(|&b| {
                let box_b = scene.part_world_bounds(b);
                box_b.contains(&box_a) || box_a.contains(&box_b)
            }));
            self.keep_nested(scene, settings, a);
            let near = box_a.inflated(margin);
            for b in scene.part_ids() {
                if !self.wanted(scene, settings, a, b)
                    || !scene.part_world_bounds(b).overlaps(&near)
                {
                    continue;
                }
                for cb in scene.part_mesh(b).chunk_ids() {
                    let box_b = scene.chunk_world_bounds(b, cb);
                    for ca in scene.part_mesh(a).chunk_ids() {
                        if scene
                            .chunk_world_bounds(a, ca)
                            .inflated(margin)
                            .overlaps(&box_b)
                        {
                            self.pairs.push(ChunkPair { a, b, ca, cb });
                        }
                    }
                }
            }
        }
        self.narrow(scene, settings, report);
    }

    fn set_moved(&mut self, moved: &[PartId]) {
        self.moved.clear();
        self.moved.extend_from_slice(moved);
        self.moved.sort_unstable();
        self.moved.dedup();
    }

    /// Keeps the wanted pairs of moved part `a` with `self.near_parts` as
    /// containment candidates.
    fn keep_nested(&mut self, scene: &Scene, settings: &Settings, a: PartId) {
        for i in 0..self.near_parts.len() {
            let b = self.near_parts[i];
            if self.wanted(scene, settings, a, b) {
                self.nested.push((a, b));
            }
        }
    }

    pub(crate) fn margin(&self, settings: &Settings) -> f64 {
        settings.clearance.max(0.0) + settings.contact_tolerance * self.max_scale
    }

    /// Whether moved part `a` is to be tested against `b`.
    pub(crate) fn wanted(&self, scene: &Scene, settings: &Settings, a: PartId, b: PartId) -> bool {
        // Two moved parts are tested once, from the smaller id.
        let twice = b < a && self.moved.binary_search(&b).is_ok();
        !(a == b || twice || scene.part(b).hidden || settings.allow.allows(a, b))
    }

    /// Tests `pairs` (chunk pairs of one part pair, placed by `places`) whose
    /// boxes are within the search's reach, nearest result into `search`,
    /// until it finds penetration.
    pub(crate) fn search_chunk_pairs(
        &self,
        scene: &Scene,
        pairs: &[ChunkPair],
        (place_a, place_b): (&Placement, &Placement),
        search: &mut PairSearch,
        report: &mut Report,
    ) {
        for pair in pairs {
            if search.done() {
                break;
            }
            let box_a = scene.chunk(pair.ca).bounds.transformed(&place_a.to_pair);
            let box_b = scene.chunk(pair.cb).bounds.transformed(&place_b.to_pair);
            if box_gap_squared(&box_a, &box_b) > search.limit * search.limit {
                continue;
            }
            report.chunk_pairs_tested += 1;
            chunk_pair(
                scene,
                &self.bvhs,
                (pair.ca, place_a),
                (pair.cb, place_b),
                search,
                &mut self.scratch.lock().unwrap_or_else(PoisonError::into_inner),
            );
        }
    }

    /// The narrow phase over the candidate chunk pairs, one clash per part pair,
    /// then containment for the nested pairs that have no chunk pair.
    fn narrow(&mut self, scene: &Scene, settings: &Settings, report: &mut Report) {
        self.pairs.sort_unstable();
        self.nested.sort_unstable();
        self.nested.dedup();
        let mut start = 0;
        while start < self.pairs.len() {
            let (a, b) = (self.pairs[start].a, self.pairs[start].b);
            let end = run_end(&self.pairs, start);
            report.part_pairs_tested += 1;
            let world_a = scene.part_world(a);
            let origin = world_a.translation;
            let place_a = Placement::new(&world_a, origin);
            let place_b = Placement::new(&scene.part_world(b), origin);
            let tolerance = pair_tolerance(scene, a, b, settings.contact_tolerance);
            let mut search = PairSearch::new(tolerance, settings.clearance);
            if let Ok(k) = self.seeds.binary_search_by_key(&(a, b), |s| s.0) {
                seed(scene, self.seeds[k].1, (&place_a, &place_b), &mut search);
            }
            self.search_chunk_pairs(
                scene,
                &self.pairs[start..end],
                (&place_a, &place_b),
                &mut search,
                report,
            );
            if let Some(clash) = self.classify(scene, settings, a, b, origin, &search) {
                report.clashes.push(clash);
            }
            if let Some(at) = search.best_at {
                self.next_seeds.push(((a, b), at));
            }
            start = end;
        }
        std::mem::swap(&mut self.seeds, &mut self.next_seeds);
        self.next_seeds.clear();
        let mut unordered = false;
        for i in 0..self.nested.len() {
            let (a, b) = self.nested[i];
            let at = self.pairs.partition_point(|p| (p.a, p.b) < (a, b));
            if self.pairs.get(at).is_some_and(|p| (p.a, p.b) == (a, b)) {
                continue; // classified above
            }
            report.part_pairs_tested += 1;
            let nothing_near = PairSearch::new(0.0, 0.0);
            let origin = scene.part_world(a).translation;
            if let Some(clash) = self.classify(scene, settings, a, b, origin, &nothing_near) {
                report.clashes.push(clash);
                unordered = true;
            }
        }
        if unordered {
            report.clashes.sort_by_key(|c| (c.a, c.b));
        }
    }

    fn classify(
        &mut self,
        scene: &Scene,
        settings: &Settings,
        a: PartId,
        b: PartId,
        origin: DVec3,
        search: &PairSearch,
    ) -> Option<Clash> {
        let clash = |kind, distance, point, normal| Clash {
            a,
            b,
            kind,
            distance,
            point,
            normal,
        };
        let best = search.best;
        if let Some(t) = best.filter(|t| t.penetrating) {
            return Some(clash(ClashKind::Hard, 0.0, origin + t.point_a, t.normal));
        }
        if let Some(point) = self.containment(scene, a, b) {
            let normal = best.map_or(DVec3::Z, |t| t.normal);
            return Some(clash(ClashKind::Hard, 0.0, point, normal));
        }
        let t = best?;
        let point = origin + (t.point_a + t.point_b) * 0.5;
        if t.distance <= search.tolerance {
            Some(clash(ClashKind::Contact, t.distance, point, t.normal))
        } else if t.distance < settings.clearance {
            Some(clash(ClashKind::Soft, t.distance, point, t.normal))
        } else {
            None
        }
    }

    /// A world point of one part inside the other, closed, part: the inner part's
    /// first vertex, tested when its world box lies inside the outer's.
    fn containment(&mut self, scene: &Scene, a: PartId, b: PartId) -> Option<DVec3> {
        let (box_a, box_b) = (scene.part_world_bounds(a), scene.part_world_bounds(b));
        [(a, b, box_a, box_b), (b, a, box_b, box_a)]
            .into_iter()
            .find_map(
                |(inner, outer, inner_box, outer_box): (PartId, PartId, Aabb3d, Aabb3d)| {
                    if !outer_box.contains(&inner_box)
                        || !self.closed.is_closed(scene, scene.part(outer).mesh)
                    {
                        return None;
                    }
                    let first = *scene.part_mesh(inner).positions.first()?;
                    let p = scene.part_world(inner).transform_point3(first.as_dvec3());
                    point_inside(scene, &self.bvhs, outer, p, &mut self.hits).then_some(p)
                },
            )
    }
}
