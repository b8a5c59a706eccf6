//! What every culling strategy shares: a frame's culling context (frustum,
//! coverage, sections, far-field cut), the canonical draw order, the
//! candidates of a frame without queries, and the walk over the renderer's
//! mirror of the tree.

use dmu_geom::{Aabb3d, Coverage, Frustum, Plane};
use dmu_scene::Scene;
use dmu_tree::{EntryVisibility, Tree};
use glam::{DAffine3, DVec3};

use crate::budget::KnobsInEffect;
use crate::farfield::{FarCut, NearField};
use crate::geometry::GeometrySource;
use crate::gpu::QueryBox;
use crate::hierarchy::{Hierarchy, NodeKind};
use crate::proxy::Proxies;
use crate::renderer::Renderer;
use crate::round::{
    ColorDraws, Draw, LodPick, Model, ProxyRound, Round, RoundResult, Shading, SubmittedRound,
    ViewGpu,
};
use crate::settings::Culling;
use crate::stats::FrameStats;
use crate::stereo::StereoCamera;
use crate::target::RoundTarget;
use crate::view::View;

/// A frame being culled and drawn, as the culling strategies see it: the
/// view (its settings and state), its GPU resources, what it draws from and
/// into, its culling context, each cell's squared distance from the eye
/// (`Renderer::cell_distances`) and its stats so far.
pub(crate) struct Frame<'a> {
    pub view: &'a mut View,
    pub gpu: &'a mut ViewGpu,
    pub model: Model<'a>,
    pub target: RoundTarget<'a>,
    pub cull: &'a Cull,
    pub cell_distance: &'a [f64],
    pub stats: &'a mut FrameStats,
}

/// Per-frame culling context of one view, or of a stereo pair culled once.
pub(crate) struct Cull {
    /// Screen coverage from the eye, or from the midpoint of a stereo pair's
    /// eyes with half the interpupillary distance as its spread.
    pub coverage: Coverage,
    /// The view's frustum, or one enclosing both eyes' frusta.
    pub frustum: Frustum,
    /// World to view of each eye; the first `eye_count` are used.
    pub eye_views: [DAffine3; 2],
    pub eye_count: usize,
    pub min_pixels: f64,
    /// How far the near plane's corners reach from an eye.
    pub near_reach: f64,
    /// Pixels of error a chunk's simplified level may show (0: none).
    pub lod_error_px: f64,
    /// The view's section planes (what is below one is cut away).
    pub section: Vec<Plane>,
    /// What a far field takes over: the frame draws its near field, or a
    /// capture what lies beyond.
    pub far: FarCut,
}

impl Cull {
    /// The context of `view`'s camera, or with `ipd` of the stereo pair
    /// around it, drawing with `knobs`.
    pub(crate) fn new(view: &View, ipd: Option<f64>, knobs: KnobsInEffect) -> Self {
        let c = &view.camera;
        let eye_view = |c: &crate::Camera| DAffine3::from_mat4(c.view_matrix());
        let (frustum, eye_views, eye_count, eye_spread) = match ipd {
            None => (view.frustum(), [eye_view(c); 2], 1, 0.0),
            Some(ipd) => {
                let stereo = StereoCamera { center: *c, ipd };
                let eyes = stereo.eyes();
                (
                    stereo.enclosing(|eye| view.frustum_at(eye)),
                    [eye_view(&eyes[0]), eye_view(&eyes[1])],
                    2,
                    0.5 * ipd,
                )
            }
        };
        Self {
            coverage: Coverage {
                eye_spread,
                ..view.coverage()
            },
            frustum,
            eye_views,
            eye_count,
            min_pixels: knobs.min_pixels,
            near_reach: view.near_reach(),
            lod_error_px: knobs.lod_error_px,
            section: view.section.clone(),
            far: view
                .far_only
                .clone()
                .map(FarCut::FarOnly)
                .unwrap_or_default(),
        }
    }

    /// True when a far-field capture leaves the chunk instance out (it
    /// touches the cull box or its part is left out).
    pub(crate) fn far_cut(&self, entry: &dmu_tree::Entry) -> bool {
        match &self.far {
            FarCut::FarOnly(f) => {
                entry.bounds.overlaps(&f.near_box) || f.excluded.contains(&entry.part.0)
            }
            _ => false,
        }
    }

    /// True when the section planes cut all of the box away.
    pub(crate) fn cut_away(&self, b: &Aabb3d) -> bool {
        self.section.iter().any(|p| p.excludes_aabb(b))
    }

    /// How the view's rounds pick chunk levels, when they may.
    pub(crate) fn lod(&self) -> Option<LodPick> {
        (self.lod_error_px > 0.0).then_some(LodPick {
            coverage: self.coverage,
            max_error_px: self.lod_error_px,
        })
    }

    /// World to view of each eye.
    pub(crate) fn eye_views(&self) -> &[DAffine3] {
        &self.eye_views[..self.eye_count]
    }

    /// Coverage below the knob from the nearest eye (never when an eye may
    /// be inside).
    pub(crate) fn too_small(&self, b: &Aabb3d) -> bool {
        self.coverage.size_px(b) < self.min_pixels
    }

    /// The eye, or the midpoint of a stereo pair's eyes.
    pub(crate) fn eye(&self) -> DVec3 {
        self.coverage.eye
    }

    /// Rounding between the f64 boxes and the f32 geometry: queried boxes grow
    /// by this so that a box never hides behind the geometry it encloses.
    pub(crate) fn margin(&self, b: &Aabb3d) -> f64 {
        1e-5 * ((b.center() - self.eye()).length() + self.coverage.eye_spread + b.extent().length())
    }

    /// True when the near plane of an eye may cut the box: its query would be
    /// wrong, so the node counts as visible without one.
    pub(crate) fn eye_near(&self, b: &Aabb3d) -> bool {
        b.inflated(self.near_reach + self.coverage.eye_spread + self.margin(b))
            .contains_point(self.eye())
    }

    /// Each proxy's frame in each eye's view space (eye-major): its origin
    /// there, formed in f64, and the world axes, as the proxy pipeline reads
    /// them.
    pub(crate) fn proxy_frames(&self, origins: &[DVec3]) -> Vec<QueryBox> {
        let v = |d: DVec3| [d.x as f32, d.y as f32, d.z as f32, 0.0];
        let mut frames = Vec::with_capacity(origins.len() * self.eye_count);
        for view_matrix in self.eye_views() {
            let m = view_matrix.matrix3;
            frames.extend(origins.iter().map(|&o| QueryBox {
                center: v(view_matrix.transform_point3(o)),
                axis_x: v(m.x_axis),
                axis_y: v(m.y_axis),
                axis_z: v(m.z_axis),
            }));
        }
        frames
    }

    /// The boxes as the query pipeline draws them, in each eye's view space:
    /// all of the first eye's, then all of the second's.
    pub(crate) fn query_boxes(&self, bounds: &[Aabb3d]) -> Vec<QueryBox> {
        let v = |d: DVec3| [d.x as f32, d.y as f32, d.z as f32, 0.0];
        let mut boxes = Vec::with_capacity(bounds.len() * self.eye_count);
        for view_matrix in self.eye_views() {
            boxes.extend(bounds.iter().map(|b| {
                let b = b.inflated(self.margin(b));
                let c = view_matrix.transform_point3(b.center());
                let h = b.extent() * 0.5;
                let m = view_matrix.matrix3;
                QueryBox {
                    center: v(c),
                    axis_x: v(m.x_axis * h.x),
                    axis_y: v(m.y_axis * h.y),
                    axis_z: v(m.z_axis * h.z),
                }
            }));
        }
        boxes
    }
}

/// The near field of a frame drawing a far field: the chunk instances
/// touching the cull box and those of the parts drawn wherever they are, in
/// the frustum, covering enough pixels, not hidden, not cut away
/// ([`NearField::entries`], found with the tree's box query, so the cost
/// follows the cull box, not the model).
fn near_draws(
    scene: &Scene,
    tree: &Tree,
    cull: &Cull,
    near: &NearField,
    stats: &mut FrameStats,
) -> Vec<Draw> {
    let mut draws = Vec::with_capacity(near.entries.len());
    for &e in &near.entries {
        let entry = &tree.entries()[e.0 as usize];
        stats.nodes_visited += 1;
        if !cull.frustum.intersects_aabb(&entry.bounds) {
            stats.culled_frustum += 1;
        } else if cull.too_small(&entry.bounds) {
            stats.culled_coverage += 1;
        } else if scene.part(entry.part).hidden {
            stats.hidden += 1;
        } else if cull.cut_away(&entry.bounds) {
            stats.culled_section += 1;
        } else {
            draws.push(Draw {
                entry: e.0,
                query: false,
            });
        }
    }
    draws
}

/// The canonical draw order of every mode: cells front to back by box
/// distance, then by cell and entry. Modes that draw the same visible set draw it in
/// the same order, so depth ties resolve alike and their images are equal.
pub(crate) fn sort_draws(h: &Hierarchy, cell_distance: &[f64], draws: &mut [Draw]) {
    // Cells are tree nodes: mirror nodes from the entry count on.
    let first = h.entry_cell.len();
    draws.sort_unstable_by(|a, b| {
        let (ca, cb) = (
            h.entry_cell[a.entry as usize],
            h.entry_cell[b.entry as usize],
        );
        cell_distance[ca as usize - first]
            .total_cmp(&cell_distance[cb as usize - first])
            .then(ca.cmp(&cb))
            .then(a.entry.cmp(&b.entry))
    });
}

pub(crate) fn box_distance_sq(b: &Aabb3d, p: DVec3) -> f64 {
    (b.min - p).max(p - b.max).max(DVec3::ZERO).length_squared()
}

impl Renderer {
    /// Squared eye distance of every cell node's box (0 inside) by tree node
    /// slot (mirror node less the entry count); other nodes 0.
    pub(crate) fn cell_distances(&self, tree: &Tree, eye: DVec3) -> Vec<f64> {
        let h = &self.hierarchy;
        (h.entry_cell.len() as u32..h.len() as u32)
            .map(|n| match h.kind(n) {
                NodeKind::Cell(_) => box_distance_sq(h.bounds(tree, n), eye),
                _ => 0.0,
            })
            .collect()
    }

    /// Every chunk instance not hidden and not wholly cut away by a section.
    pub(crate) fn all_draws(
        &self,
        scene: &Scene,
        tree: &Tree,
        cull: &Cull,
        stats: &mut FrameStats,
    ) -> Vec<Draw> {
        let mut draws = Vec::with_capacity(tree.entries().len());
        for (e, entry) in tree.entries().iter().enumerate() {
            stats.nodes_visited += 1;
            if scene.part(entry.part).hidden {
                stats.hidden += 1;
            } else if cull.cut_away(&entry.bounds) {
                stats.culled_section += 1;
            } else {
                draws.push(Draw {
                    entry: e as u32,
                    query: false,
                });
            }
        }
        draws
    }

    /// Frustum and coverage culling with the tree's own traversal, then per
    /// chunk instance in the surviving cells.
    pub(crate) fn frustum_draws(
        &self,
        scene: &Scene,
        tree: &Tree,
        cull: &Cull,
        stats: &mut FrameStats,
    ) -> Vec<Draw> {
        let mut draws = Vec::new();
        let nodes = tree.visit_visible(
            &cull.frustum,
            &cull.coverage,
            cull.min_pixels,
            &mut |e, entry, v| {
                stats.nodes_visited += 1;
                match v {
                    EntryVisibility::OutsideFrustum => stats.culled_frustum += 1,
                    EntryVisibility::InFrustum { wanted: false, .. } => {
                        stats.culled_coverage += 1;
                    }
                    _ if scene.part(entry.part).hidden => stats.hidden += 1,
                    _ if cull.cut_away(&entry.bounds) => stats.culled_section += 1,
                    _ if cull.far_cut(entry) => {}
                    EntryVisibility::InFrustum { wanted: true, .. } => draws.push(Draw {
                        entry: e.0,
                        query: false,
                    }),
                }
            },
        );
        stats.nodes_visited += nodes.visited;
        stats.culled_frustum += nodes.culled_frustum;
        stats.culled_coverage += nodes.culled_coverage;
        draws
    }

    /// Frustum and coverage culling on the renderer's mirror of the tree,
    /// stopping at nodes whose current proxy's error projects within the
    /// frame's LOD error: the chunk instances to draw and the proxies (mirror
    /// nodes) drawn instead of the rest. Counts the triangles of both, and of
    /// what the proxies stand for, in `triangles_in_frustum`.
    ///
    /// With stored proxies this is 3D Tiles' replace refinement: a node
    /// whose proxy would fit but is not loaded is asked for and refined past
    /// meanwhile, and a subtree that would draw a chunk `geometry` lacks (a
    /// box stand-in) is drawn as the nearest loaded proxy above it instead,
    /// however coarse, so nothing is missing while it loads.
    pub(crate) fn proxy_draws(
        &self,
        model: &Model<'_>,
        cull: &Cull,
        fit: &[bool],
        stats: &mut FrameStats,
    ) -> (Vec<Draw>, Vec<u32>) {
        let h = &self.hierarchy;
        let mut walk = Walk::new(h, model.scene, model.tree, cull, stats);
        walk.proxy_fit = fit;
        walk.proxies = self.proxies.as_ref().map(|p| &p.cpu);
        let mut nodes = Vec::new();
        if !h.is_empty() {
            refine(&mut walk, model.geometry, h.root, false, &mut nodes);
        }
        (walk.draws, nodes)
    }

    /// Per mirror node of `h`, whether this frame draws it as its proxy: its
    /// proxy is current and its error projects within the LOD error (empty
    /// without proxies, LODs, or in multiview rounds, which cannot draw them).
    pub(crate) fn proxy_fit(
        &self,
        h: &Hierarchy,
        tree: &Tree,
        cull: &Cull,
        target: RoundTarget<'_>,
    ) -> Vec<bool> {
        match (&self.proxies, cull.lod()) {
            (Some(p), Some(_)) if !target.is_multiview() => (0..h.len() as u32)
                .map(|n| {
                    p.cpu.current(n).is_some_and(|x| {
                        let b = h.bounds(tree, n);
                        cull.coverage.error_fits(b, x.error, cull.lod_error_px)
                    })
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    /// Puts a round's proxies front to back and gives their frames in each
    /// eye's view space.
    pub(crate) fn proxy_frames(
        &self,
        h: &Hierarchy,
        tree: &Tree,
        nodes: &mut [u32],
        cull: &Cull,
    ) -> Vec<QueryBox> {
        nodes.sort_by(|&a, &b| {
            let d = |n: u32| box_distance_sq(h.bounds(tree, n), cull.eye());
            d(a).total_cmp(&d(b)).then(a.cmp(&b))
        });
        let Some(p) = &self.proxies else {
            return Vec::new();
        };
        let origins: Vec<DVec3> = nodes
            .iter()
            .map(|&n| {
                p.cpu.nodes[n as usize]
                    .as_ref()
                    .expect("a drawn proxy exists")
                    .origin
            })
            .collect();
        cull.proxy_frames(&origins)
    }

    /// Per mirror node, whether a frame under `culling` draws it as its
    /// proxy where the walk reaches it (see `proxy_fit`); empty where no
    /// proxy may draw.
    pub(crate) fn frame_fit(
        &self,
        culling: Culling,
        tree: &Tree,
        cull: &Cull,
        target: RoundTarget<'_>,
    ) -> Vec<bool> {
        match (culling, &cull.far) {
            (Culling::None, _) | (_, FarCut::Near(_) | FarCut::FarOnly(_)) => Vec::new(),
            _ => self.proxy_fit(&self.hierarchy, tree, cull, target),
        }
    }

    /// What a frame without queries draws under `culling`: the chunk
    /// instances in canonical order, and the proxies (mirror nodes, front
    /// to back) drawn instead of the rest with their frames in each eye's
    /// view space. `None` takes every chunk instance and no proxy; the other
    /// modes take the frustum's, proxies where they fit (`fit`, from
    /// `frame_fit`).
    pub(crate) fn candidates(
        &self,
        culling: Culling,
        fit: &[bool],
        f: &mut Frame<'_>,
    ) -> ColorDraws {
        let (scene, tree, cull, stats) = (f.model.scene, f.model.tree, f.cull, &mut *f.stats);
        let mut proxy_nodes = Vec::new();
        let mut draws = match culling {
            _ if let FarCut::Near(near) = &cull.far => near_draws(scene, tree, cull, near, stats),
            Culling::None => self.all_draws(scene, tree, cull, stats),
            _ if !fit.is_empty() => {
                let (draws, nodes) = self.proxy_draws(&f.model, cull, fit, stats);
                proxy_nodes = nodes;
                draws
            }
            _ => self.frustum_draws(scene, tree, cull, stats),
        };
        sort_draws(&self.hierarchy, f.cell_distance, &mut draws);
        if fit.is_empty() {
            stats.triangles_in_frustum = draws
                .iter()
                .map(|d| u64::from(tree.entries()[d.entry as usize].triangles))
                .sum();
        }
        let frames = self.proxy_frames(&self.hierarchy, tree, &mut proxy_nodes, cull);
        ColorDraws {
            draws,
            nodes: proxy_nodes,
            frames,
            clusters: Vec::new(),
        }
    }

    /// Submits a colour round of `round`'s draws, which clears the target
    /// (a frame without occlusion culling, or an `hzb` frame's first pass).
    pub(crate) fn submit_color(&mut self, f: &mut Frame<'_>, round: &ColorDraws) -> SubmittedRound {
        let tinted = self.proxies_tinted(&self.hierarchy, f.model.tree, &round.nodes);
        self.submit_round(
            f.gpu,
            f.target,
            f.model,
            &Round {
                shading: Shading::Color,
                clear: true,
                draws: &round.draws,
                boxes: &[],
                lod: f.cull.lod(),
                proxies: ProxyRound {
                    nodes: &round.nodes,
                    frames: &round.frames,
                    tinted: &tinted,
                    clusters: &round.clusters,
                },
            },
        )
    }
}

/// Draws what node `n` stands for into `walk` and `nodes` (see
/// `Renderer::proxy_draws`); whether all of it is there: every chunk drawn
/// with its own geometry, every proxy loaded. `covered`: a loaded proxy
/// above stands in for whatever is not, so a node whose stored proxy would
/// fit but is not loaded yet ends the descent (its subtree's chunks are not
/// what this view needs); without one the walk goes on down to chunks.
fn refine(
    walk: &mut Walk<'_>,
    geometry: &dyn GeometrySource,
    n: u32,
    covered: bool,
    nodes: &mut Vec<u32>,
) -> bool {
    let proxies = walk.proxies;
    walk.covered = covered;
    let Some(kind) = walk.admit(n) else {
        return true;
    };
    if let NodeKind::Entry(e) = kind {
        walk.draws.push(Draw {
            entry: e.0,
            query: false,
        });
        return geometry.has_own(walk.tree.entries()[e.0 as usize].chunk);
    }
    let loaded = proxies.and_then(|p| p.current(n));
    if let (Some(p), Some(x)) = (proxies, loaded) {
        p.used(n);
        if walk.fits(n) {
            nodes.push(n);
            walk.stats.triangles_in_frustum += x.source_triangles;
            return true;
        }
    }
    let bounds = walk.h.bounds(walk.tree, n);
    let wanted = proxies.and_then(|p| p.stored_error(n)).is_some_and(|e| {
        walk.cull
            .coverage
            .error_fits(bounds, e, walk.cull.lod_error_px)
    });
    if covered && loaded.is_none() && wanted {
        walk.stats.lod_coarse += 1;
        return false;
    }
    let (draws, drawn) = (walk.draws.len(), nodes.len());
    let mut complete = true;
    for &c in walk.h.children(n) {
        complete &= refine(walk, geometry, c, covered || loaded.is_some(), nodes);
    }
    if !complete && loaded.is_some() {
        walk.stats.lod_coarse += 1;
        walk.draws.truncate(draws);
        nodes.truncate(drawn);
        nodes.push(n);
        return true;
    }
    complete
}

/// The state of an occlusion-culling traversal within a frame.
pub(crate) struct Walk<'a> {
    pub h: &'a Hierarchy,
    pub scene: &'a Scene,
    pub tree: &'a Tree,
    pub cull: &'a Cull,
    pub stats: &'a mut FrameStats,
    /// Draws of the next round.
    pub draws: Vec<Draw>,
    /// Nodes whose boxes the next round queries.
    pub queries: Vec<u32>,
    /// Chunk instances that passed frustum, coverage and hidden tests.
    pub in_frustum_entries: u64,
    /// Per mirror node: drawn as its proxy (empty: no proxies).
    pub proxy_fit: &'a [bool],
    /// Proxies (mirror nodes) the next round draws.
    pub proxy_draws: Vec<u32>,
    /// The renderer's proxies, whose stored ones the walk asks for as it
    /// reaches their nodes (frustum and `hzb` walks; CHC's draws those
    /// loaded).
    pub proxies: Option<&'a Proxies>,
    /// Whether a loaded proxy above the node being admitted stands in for
    /// what is missing below it.
    pub covered: bool,
}

impl<'a> Walk<'a> {
    pub(crate) fn new(
        h: &'a Hierarchy,
        scene: &'a Scene,
        tree: &'a Tree,
        cull: &'a Cull,
        stats: &'a mut FrameStats,
    ) -> Self {
        Walk {
            h,
            scene,
            tree,
            cull,
            stats,
            draws: Vec::new(),
            queries: Vec::new(),
            in_frustum_entries: 0,
            proxy_fit: &[],
            proxy_draws: Vec::new(),
            proxies: None,
            covered: false,
        }
    }

    /// Whether node `n` is drawn as its proxy this frame.
    pub(crate) fn fits(&self, n: u32) -> bool {
        self.proxy_fit.get(n as usize).copied().unwrap_or(false)
    }

    /// Node `n` is visible: its proxy is drawn next round, what it stands
    /// for is counted, and its chunk instances are visible this frame.
    pub(crate) fn draw_proxy(&mut self, n: u32, view: &mut View, frame: u32) {
        self.proxy_draws.push(n);
        self.count_below(n);
        let mut leaves = Vec::new();
        self.h.leaves(n, &mut leaves);
        for e in leaves {
            view.state.entries[e as usize].visible_frame = frame;
        }
    }

    /// Frustum, coverage and hidden tests of a node, counted; its kind if it
    /// passes. Admitted chunk instances count towards what frustum culling
    /// alone would draw.
    pub(crate) fn admit(&mut self, n: u32) -> Option<NodeKind> {
        let bounds = self.h.bounds(self.tree, n);
        let kind = self.h.kind(n);
        self.stats.nodes_visited += 1;
        if !self.cull.frustum.intersects_aabb(bounds) {
            self.stats.culled_frustum += 1;
            return None;
        }
        if self.cull.cut_away(bounds) {
            self.stats.culled_section += 1;
            return None;
        }
        if self.cull.too_small(bounds) {
            self.stats.culled_coverage += 1;
            return None;
        }
        if let NodeKind::Entry(e) = kind {
            let entry = &self.tree.entries()[e.0 as usize];
            if self.scene.part(entry.part).hidden {
                self.stats.hidden += 1;
                return None;
            }
            self.in_frustum_entries += 1;
            self.stats.triangles_in_frustum += u64::from(entry.triangles);
        } else if let Some(p) = self.proxies
            && p.current(n).is_none()
            && let Some(error) = p.stored_error(n)
        {
            // Coarse first: what nothing loaded stands in for before all of
            // it; under a loaded proxy only the nodes whose own fit (the
            // others are walked through, not drawn), by screen size per
            // byte.
            let fits = self
                .cull
                .coverage
                .error_fits(bounds, error, self.cull.lod_error_px);
            if !self.covered || fits {
                p.request(n, self.cull.coverage.size_px(bounds), !self.covered);
            }
        }
        Some(kind)
    }

    /// Counts what frustum culling would draw below a node occlusion culled,
    /// for the stats and the adaptive decision (not as visited nodes).
    pub(crate) fn count_below(&mut self, n: u32) {
        let mut stack = vec![n];
        while let Some(n) = stack.pop() {
            let bounds = self.h.bounds(self.tree, n);
            if !self.cull.frustum.intersects_aabb(bounds)
                || self.cull.cut_away(bounds)
                || self.cull.too_small(bounds)
            {
                continue;
            }
            match self.h.kind(n) {
                NodeKind::Entry(e) => {
                    let entry = &self.tree.entries()[e.0 as usize];
                    if !self.scene.part(entry.part).hidden {
                        self.in_frustum_entries += 1;
                        self.stats.triangles_in_frustum += u64::from(entry.triangles);
                    }
                }
                _ => stack.extend_from_slice(self.h.children(n)),
            }
        }
    }

    /// A queried inner node turned out visible: its descendants `levels` down
    /// (or chunk instances, if reached first) are queried in the next round;
    /// ones the eye is in are opened without a query.
    pub(crate) fn expand(&mut self, n: u32, levels: u32, view: &mut View, frame: u32) {
        let mut stack: Vec<(u32, u32)> = self.h.children(n).iter().map(|&c| (c, 1)).collect();
        while let Some((c, depth)) = stack.pop() {
            let Some(kind) = self.admit(c) else { continue };
            let near = self.cull.eye_near(self.h.bounds(self.tree, c));
            match kind {
                NodeKind::Entry(e) if near => {
                    view.state.entries[e.0 as usize].visible_frame = frame;
                    self.stats.newly_visible += 1;
                    self.draws.push(Draw {
                        entry: e.0,
                        query: false,
                    });
                }
                NodeKind::Entry(_) => self.queries.push(c),
                _ if self.fits(c) && near => {
                    self.stats.newly_visible += 1;
                    self.draw_proxy(c, view, frame);
                }
                _ if self.fits(c) => self.queries.push(c),
                _ if near || depth < levels => {
                    stack.extend(self.h.children(c).iter().map(|&g| (g, depth + 1)));
                }
                _ => self.queries.push(c),
            }
        }
    }
}

pub(crate) fn add_round(stats: &mut FrameStats, r: &RoundResult) {
    stats.passes += r.passes;
    stats.not_resident += r.not_resident;
    stats.chunks_drawn += r.chunks;
    stats.draw_calls += r.draw_calls;
    stats.triangles_drawn += r.triangles;
    stats.gpu_ms += r.gpu_ms;
    stats.gpu_draw_ms += r.gpu_draw_ms;
}
