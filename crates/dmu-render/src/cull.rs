//! A frame of a view: culling (none, frustum, coherent occlusion) and the
//! rounds of drawing and querying it issues; the exact-visibility oracle.

use std::collections::HashMap;
use std::time::Instant;

use dmu_geom::{Aabb3d, Aabb3f, Coverage, Frustum, Plane};
use dmu_scene::Scene;
use dmu_tree::{EntryVisibility, Tree};
use glam::{DAffine3, DVec3};

use crate::capture::{Capture, IdImage};
use crate::farfield::{FarCut, NearField};
use crate::geometry::GeometrySource;
use crate::gpu::QueryBox;
use crate::hierarchy::{Hierarchy, NodeKind};
use crate::hzb::{Candidate, CandidateKind, ColorDraws, HzbVisible};
use crate::proxy::proxy_fits;
use crate::renderer::{
    Draw, FrameTarget, LodPick, ProxyRound, Renderer, RoundResult, RoundTarget, Shading,
    SubmittedRound,
};
use crate::stereo::StereoCamera;
use crate::view::{Culling, EntryState, FrameStats, View};
use crate::{KnobsInEffect, RenderError};

/// Per-frame culling context of one view, or of a stereo pair culled once.
struct Cull {
    /// Screen coverage from the eye, or from the midpoint of a stereo pair's
    /// eyes with half the interpupillary distance as its spread.
    coverage: Coverage,
    /// The view's frustum, or one enclosing both eyes' frusta.
    frustum: Frustum,
    /// World to view of each eye; the first `eye_count` are used.
    eye_views: [DAffine3; 2],
    eye_count: usize,
    min_pixels: f64,
    /// How far the near plane's corners reach from an eye.
    near_reach: f64,
    /// Pixels of error a chunk's simplified level may show (0: none).
    lod_error_px: f64,
    /// The view's section planes (what is below one is cut away).
    section: Vec<Plane>,
    /// What a far field takes over: the frame draws its near field, or a
    /// capture what lies beyond.
    far: FarCut,
}

impl Cull {
    /// The context of `view`'s camera, or with `ipd` of the stereo pair
    /// around it, drawing with `knobs`.
    fn new(view: &View, ipd: Option<f64>, knobs: KnobsInEffect) -> Self {
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
    fn far_cut(&self, entry: &dmu_tree::Entry) -> bool {
        match &self.far {
            FarCut::FarOnly(f) => {
                entry.bounds.overlaps(&f.near_box) || f.excluded.contains(&entry.part.0)
            }
            _ => false,
        }
    }

    /// True when the section planes cut all of the box away.
    fn cut_away(&self, b: &Aabb3d) -> bool {
        self.section.iter().any(|p| p.excludes_aabb(b))
    }

    /// How the view's rounds pick chunk levels, when they may.
    fn lod(&self) -> Option<LodPick> {
        (self.lod_error_px > 0.0).then_some(LodPick {
            coverage: self.coverage,
            max_error_px: self.lod_error_px,
        })
    }

    /// World to view of each eye.
    fn eye_views(&self) -> &[DAffine3] {
        &self.eye_views[..self.eye_count]
    }

    /// Coverage below the knob from the nearest eye (never when an eye may
    /// be inside).
    fn too_small(&self, b: &Aabb3d) -> bool {
        self.coverage.size_px(b) < self.min_pixels
    }

    /// The eye, or the midpoint of a stereo pair's eyes.
    fn eye(&self) -> DVec3 {
        self.coverage.eye
    }

    /// Rounding between the f64 boxes and the f32 geometry: queried boxes grow
    /// by this so that a box never hides behind the geometry it encloses.
    fn margin(&self, b: &Aabb3d) -> f64 {
        1e-5 * ((b.center() - self.eye()).length() + self.coverage.eye_spread + b.extent().length())
    }

    /// True when the near plane of an eye may cut the box: its query would be
    /// wrong, so the node counts as visible without one.
    fn eye_near(&self, b: &Aabb3d) -> bool {
        b.inflated(self.near_reach + self.coverage.eye_spread + self.margin(b))
            .contains_point(self.eye())
    }

    /// Each proxy's frame in each eye's view space (eye-major): its origin
    /// there, formed in f64, and the world axes, as the proxy pipeline reads
    /// them.
    fn proxy_frames(&self, origins: &[DVec3]) -> Vec<QueryBox> {
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
    fn query_boxes(&self, bounds: &[Aabb3d]) -> Vec<QueryBox> {
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
fn sort_draws(h: &Hierarchy, cell_distance: &[f64], draws: &mut [Draw]) {
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

fn box_distance_sq(b: &Aabb3d, p: DVec3) -> f64 {
    (b.min - p).max(p - b.max).max(DVec3::ZERO).length_squared()
}

impl Renderer {
    /// A frame of `view`, or with `ipd` of the stereo pair around its camera
    /// (culled once, drawn in one multiview pass).
    pub(crate) fn render_frame(
        &mut self,
        view: &mut View,
        ipd: Option<f64>,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        target: RoundTarget<'_>,
    ) -> Result<FrameStats, RenderError> {
        let start = Instant::now();
        view.frame += 1;
        self.hierarchy.sync(tree);
        self.sync_part_flags(scene, tree);
        let proxy_time = self.sync_proxies(scene, tree, geometry);
        if view.entries.len() != tree.entries().len() {
            view.entries = vec![EntryState::default(); tree.entries().len()];
        }
        let mut stats = FrameStats {
            frame: view.frame,
            ..FrameStats::default()
        };
        let knobs = match view.options.target_ms {
            Some(_) => view
                .knobs
                .unwrap_or(KnobsInEffect::of(&view.options))
                .within(&view.options),
            None => KnobsInEffect::of(&view.options),
        };
        stats.lod_error_px = knobs.lod_error_px;
        stats.min_pixels = knobs.min_pixels;
        let mut cull = Cull::new(view, ipd, knobs);
        let cell_distance = self.cell_distances(tree, cull.eye());
        // The mode of this frame: the view's, or the one `auto` runs now.
        let culling = match view.culling {
            Culling::Auto => view.auto.mode(),
            c => c,
        };
        self.sync_far(scene, tree);
        let near = match culling {
            Culling::None => None,
            _ if target.eye_count() > 1 => None,
            _ => self.near_field(view, tree),
        };
        if let Some(near) = &near {
            cull.far = FarCut::Near(near.clone());
        }
        let use_queries = culling == Culling::Occlusion && view.decision.enabled && near.is_none();
        let hzb = culling == Culling::Hzb
            && target.eye_count() == 1
            && self.hzb_supported(target.all().depth);
        stats.culling = match culling {
            Culling::Hzb if !hzb => Culling::Frustum,
            Culling::Occlusion if !use_queries => Culling::Frustum,
            c => c,
        };
        // A frame without occlusion culling knows its draws before it draws.
        let plain = (!hzb && !use_queries).then(|| {
            self.candidates(
                culling,
                scene,
                tree,
                &cull,
                &self.frame_fit(culling, tree, &cull, target),
                &cell_distance,
                &mut stats,
            )
        });
        let mut gpu_state = self.prepare_view(view, cull.eye_views());
        view.drawn.clear();
        let outcome = if hzb {
            self.frame_hzb(
                view,
                &mut gpu_state,
                scene,
                tree,
                geometry,
                target,
                &cull,
                &cell_distance,
                &mut stats,
            )
        } else if use_queries {
            self.frame_occlusion(
                view,
                &mut gpu_state,
                scene,
                tree,
                geometry,
                target,
                &cull,
                &cell_distance,
                &mut stats,
            )
        } else {
            let plain = plain.expect("a frame without occlusion culling");
            stats.proxies_drawn = plain.nodes.len() as u64;
            view.drawn.extend(plain.draws.iter().map(|d| d.entry));
            // A proxy draws the chunk instances below it, approximated.
            for &n in &plain.nodes {
                self.hierarchy.leaves(n, &mut view.drawn);
            }
            if view.culling == Culling::Auto {
                // What frustum culling drew counts as visible, so a switch
                // to chc or hzb starts from it rather than from nothing.
                for &e in &view.drawn {
                    view.entries[e as usize].visible_frame = view.frame;
                }
            }
            stats.rounds = 1;
            let round =
                self.submit_color(&mut gpu_state, target, geometry, scene, tree, &cull, &plain);
            self.finish_round(&gpu_state, round)
                .map(|r| add_round(&mut stats, &r))
        };
        view.gpu = Some(gpu_state);
        outcome?;
        if let Some(near) = &near {
            stats.far_field = true;
            stats.far_field_moved_parts = near.always.len() as u64;
            stats.far_field_triangles = self.draw_far_field(view, target.all())?;
        }
        stats.upload_ms += proxy_time.as_secs_f64() * 1e3;
        stats.proxies_stale = self.proxies.as_ref().map_or(0, |p| p.cpu.stats().stale);
        stats.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        view.knobs = Some(knobs.next(&view.options, stats.cpu_ms - stats.upload_ms));
        self.decide(view, culling, &mut stats);
        if view.culling == Culling::Auto {
            // Uploads aside: they are the model's arriving, not the mode's cost.
            view.auto.after_frame(stats.cpu_ms - stats.upload_ms);
            stats.auto = Some(view.auto.choice(culling));
        }
        view.last = stats;
        Ok(stats)
    }

    /// Renders one frame of `view` into `target`: culls, draws and (with
    /// [`Culling::Occlusion`]) queries in rounds, waits for the GPU, and
    /// returns what it did. `geometry` supplies chunks not yet on the GPU.
    pub fn render(
        &mut self,
        view: &mut View,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        target: FrameTarget<'_>,
    ) -> Result<FrameStats, RenderError> {
        let target = RoundTarget::single(target).keeping_color(view.keep_color);
        self.render_frame(view, None, scene, tree, geometry, target)
    }

    /// The chunk instances owning at least one pixel of `view`, by drawing
    /// every non-hidden chunk instance in the frustum (no occlusion culling)
    /// as ids; `capture` must have the view's size.
    pub fn render_ids(
        &mut self,
        view: &mut View,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        capture: &Capture,
    ) -> Result<IdImage, RenderError> {
        assert_eq!(capture.size(), view.size, "capture and view sizes differ");
        self.hierarchy.sync(tree);
        self.sync_part_flags(scene, tree);
        let cull = Cull {
            min_pixels: 0.0,
            ..Cull::new(view, None, KnobsInEffect::default())
        };
        let cell_distance = self.cell_distances(tree, cull.eye());
        let mut gpu_state = self.prepare_view(view, cull.eye_views());
        let mut scratch = FrameStats::default();
        let mut draws = self.frustum_draws(scene, tree, &cull, &mut scratch);
        sort_draws(&self.hierarchy, &cell_distance, &mut draws);
        let round = self.submit_round(
            &mut gpu_state,
            RoundTarget::single(capture.id_target()),
            Shading::Ids,
            true,
            geometry,
            scene,
            tree,
            &draws,
            &[],
            None,
            ProxyRound::default(),
        );
        let result = self.finish_round(&gpu_state, round);
        view.gpu = Some(gpu_state);
        result?;
        capture.read_ids(&self.device, &self.queue)
    }

    /// Squared eye distance of every cell node's box (0 inside) by tree node
    /// slot (mirror node less the entry count); other nodes 0.
    fn cell_distances(&self, tree: &Tree, eye: DVec3) -> Vec<f64> {
        let h = &self.hierarchy;
        (h.entry_cell.len() as u32..h.len() as u32)
            .map(|n| match h.kind(n) {
                NodeKind::Cell(_) => box_distance_sq(h.bounds(tree, n), eye),
                _ => 0.0,
            })
            .collect()
    }

    /// Every chunk instance not hidden and not wholly cut away by a section.
    fn all_draws(
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
    fn frustum_draws(
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
    fn proxy_draws(
        &self,
        scene: &Scene,
        tree: &Tree,
        cull: &Cull,
        fit: &[bool],
        stats: &mut FrameStats,
    ) -> (Vec<Draw>, Vec<u32>) {
        let h = &self.hierarchy;
        let mut walk = Walk::new(h, scene, tree, cull, stats);
        walk.proxy_fit = fit;
        let mut nodes = Vec::new();
        if h.is_empty() {
            return (Vec::new(), nodes);
        }
        let mut stack = vec![h.root];
        while let Some(n) = stack.pop() {
            let Some(kind) = walk.admit(n) else { continue };
            if let NodeKind::Entry(e) = kind {
                walk.draws.push(Draw {
                    entry: e.0,
                    query: false,
                });
                continue;
            }
            if walk.fits(n) {
                nodes.push(n);
                walk.count_below(n);
            } else {
                stack.extend_from_slice(h.children(n));
            }
        }
        (walk.draws, nodes)
    }

    /// Per mirror node of `h`, whether this frame draws it as its proxy: its
    /// proxy is current and its error projects within the LOD error (empty
    /// without proxies, LODs, or in multiview rounds, which cannot draw them).
    fn proxy_fit(
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
                        proxy_fits(&cull.coverage, b, x.error, cull.lod_error_px)
                    })
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    /// Puts a round's proxies front to back and gives their frames in each
    /// eye's view space.
    fn proxy_frames(
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
    fn frame_fit(
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
    #[expect(
        clippy::too_many_arguments,
        reason = "the frame's context, passed through once"
    )]
    fn candidates(
        &self,
        culling: Culling,
        scene: &Scene,
        tree: &Tree,
        cull: &Cull,
        fit: &[bool],
        cell_distance: &[f64],
        stats: &mut FrameStats,
    ) -> ColorDraws {
        let mut proxy_nodes = Vec::new();
        let mut draws = match culling {
            _ if let FarCut::Near(near) = &cull.far => near_draws(scene, tree, cull, near, stats),
            Culling::None => self.all_draws(scene, tree, cull, stats),
            _ if !fit.is_empty() => {
                let (draws, nodes) = self.proxy_draws(scene, tree, cull, fit, stats);
                proxy_nodes = nodes;
                draws
            }
            _ => self.frustum_draws(scene, tree, cull, stats),
        };
        sort_draws(&self.hierarchy, cell_distance, &mut draws);
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

    /// Two-pass hierarchical-Z occlusion culling ([`crate::hzb`]): the
    /// frustum's candidates (chunk instances and proxies) visible last frame,
    /// or with an eye near their box, are drawn first in canonical order;
    /// every candidate is then tested against the depth pyramid of that
    /// pass and the newly visible are drawn in the same frame. A candidate
    /// visible in this frame's test is drawn first next frame; a proxy the
    /// first pass draws is tested cluster by cluster, and only its clusters
    /// found visible are drawn first next frame.
    #[expect(
        clippy::too_many_arguments,
        reason = "the frame's context, passed through once"
    )]
    fn frame_hzb(
        &mut self,
        view: &mut View,
        gpu: &mut crate::renderer::ViewGpu,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        target: RoundTarget<'_>,
        cull: &Cull,
        cell_distance: &[f64],
        stats: &mut FrameStats,
    ) -> Result<(), RenderError> {
        let frame = view.frame;
        // Last frame's visible set, where last frame was an `hzb` frame of
        // this view: the first pass draws it before the tree is traversed,
        // so the traversal runs while the GPU draws.
        let last = std::mem::take(&mut view.hzb_visible);
        let fit = self.frame_fit(Culling::Hzb, tree, cull, target);
        let early = (last.frame + 1 == frame
            && last.revision == Some(tree.revision())
            && matches!(cull.far, FarCut::None))
        .then(|| self.last_visible(scene, tree, cull, cell_distance, &fit, &last));
        let early_round = early
            .as_ref()
            .map(|first| self.submit_color(gpu, target, geometry, scene, tree, cull, first));
        let ColorDraws {
            draws,
            nodes: proxy_nodes,
            frames,
            ..
        } = self.candidates(Culling::Hzb, scene, tree, cull, &fit, cell_distance, stats);
        let h = &self.hierarchy;
        if view.proxy_visible.len() != h.len() {
            view.proxy_visible = vec![0; h.len()];
        }
        // What the early first pass drew, for lookups: its chunk instances
        // (sorted), its proxies with the clusters of each drawn.
        let drawn_early = early.as_ref().map(|first| {
            let mut entries: Vec<u32> = first.draws.iter().map(|d| d.entry).collect();
            entries.sort_unstable();
            let nodes: HashMap<u32, u64> = (first.nodes.iter().copied())
                .zip(first.clusters.iter().copied())
                .collect();
            (entries, nodes)
        });
        // Per proxy, the clusters the first pass draws (0: not drawn): where
        // it was not drawn early, every one of a proxy visible last frame or
        // with the eye near its box.
        let proxy_drawn: Vec<u64> = (proxy_nodes.iter())
            .map(|&n| match &drawn_early {
                Some((_, nodes)) => nodes.get(&n).copied().unwrap_or(0),
                None => {
                    let was = view.proxy_visible[n as usize];
                    let near = cull.eye_near(h.bounds(tree, n));
                    if near || (was > 0 && was + 1 == frame) {
                        u64::MAX
                    } else {
                        0
                    }
                }
            })
            .collect();
        // The candidates, their world boxes and whether the first pass draws
        // them: chunk instances, then proxies, each tested cluster by cluster
        // where the first pass draws it (so that the next frame's first pass
        // draws only its clusters that showed), else whole.
        let mut listed: Vec<(CandidateKind, Aabb3d, bool)> =
            Vec::with_capacity(draws.len() + proxy_nodes.len());
        for d in &draws {
            let b = tree.entries()[d.entry as usize].bounds;
            let drawn = match &drawn_early {
                Some((entries, _)) => entries.binary_search(&d.entry).is_ok(),
                None => {
                    let was = view.entries[d.entry as usize].visible_frame;
                    cull.eye_near(&b) || (was > 0 && was + 1 == frame)
                }
            };
            listed.push((CandidateKind::Entry(d.entry), b, drawn));
        }
        // A proxy tested whole is tested by its triangles' box, which is
        // tighter than its node's.
        let cpu_proxies = self.proxies.as_ref().map(|p| &p.cpu);
        let world = |b: Aabb3f, origin: DVec3| {
            let b = b.as_dvec();
            Aabb3d::new(origin + b.min, origin + b.max)
        };
        for (k, (&n, &mask)) in (0..).zip(proxy_nodes.iter().zip(&proxy_drawn)) {
            match cpu_proxies.and_then(|p| p.nodes[n as usize].as_deref()) {
                Some(p) if mask != 0 && p.clusters.len() > 1 => {
                    for (c, cluster) in (0..).zip(&p.clusters) {
                        let b = world(cluster.bounds, p.origin);
                        let drawn = mask & (1 << c) != 0;
                        listed.push((CandidateKind::ProxyCluster(k, c), b, drawn));
                    }
                }
                Some(p) if !p.clusters.is_empty() => {
                    let bounds = (p.clusters.iter()).fold(Aabb3f::EMPTY, |b, c| b.union(c.bounds));
                    listed.push((CandidateKind::Proxy(k), world(bounds, p.origin), mask != 0));
                }
                _ => listed.push((CandidateKind::Proxy(k), *h.bounds(tree, n), mask != 0)),
            }
        }
        let world: Vec<Aabb3d> = listed.iter().map(|&(_, b, _)| b).collect();
        let candidates: Vec<Candidate> = (listed.iter().zip(cull.query_boxes(&world)))
            .map(|(&(kind, b, drawn), bounds)| Candidate {
                kind,
                bounds,
                drawn,
                forced: cull.eye_near(&b),
            })
            .collect();
        // First pass: last frame's visible set (with the candidates near the
        // eye, where it was not drawn early).
        let (first, first_draws) = match (early_round, early) {
            (Some(round), Some(first)) => (round, first.draws),
            _ => {
                let mut first = ColorDraws {
                    draws: crate::hzb::draw_list(&candidates),
                    ..ColorDraws::default()
                };
                for ((&n, &mask), frame) in proxy_nodes.iter().zip(&proxy_drawn).zip(&frames) {
                    if mask != 0 {
                        first.nodes.push(n);
                        first.frames.push(*frame);
                        first.clusters.push(mask);
                    }
                }
                let round = self.submit_color(gpu, target, geometry, scene, tree, cull, &first);
                (round, first.draws)
            }
        };
        // Second pass: the pyramid, every candidate's test, the newly visible,
        // prepared while the GPU draws the first.
        let second = self.hzb_second_pass(
            gpu,
            target.all(),
            view.projection(),
            geometry,
            scene,
            tree,
            &candidates,
            &proxy_nodes,
            &frames,
            cull.lod(),
        )?;
        let r = self.finish_round(gpu, first)?;
        add_round(stats, &r);
        stats.rounds = 2;
        stats.passes += 1;
        stats.draw_calls += second.draw_calls;
        stats.gpu_ms += second.compute_ms + second.draw_ms;
        stats.gpu_draw_ms += second.draw_ms;
        stats.triangles_drawn += second.triangles;
        stats.not_resident += second.missing.iter().filter(|&&m| m).count() as u64;
        view.drawn.extend(first_draws.iter().map(|d| d.entry));
        let h = &self.hierarchy;
        let mut visible_now = HzbVisible {
            frame,
            revision: Some(tree.revision()),
            fit,
            ..HzbVisible::default()
        };
        // Per proxy, the clusters that showed (all where tested whole), and
        // whether it showed whole without being drawn first.
        let mut proxy_seen = vec![0u64; proxy_nodes.len()];
        let mut proxy_new = vec![false; proxy_nodes.len()];
        for ((c, &visible), &missing) in candidates.iter().zip(&second.visible).zip(&second.missing)
        {
            match c.kind {
                CandidateKind::Entry(e) if visible => {
                    view.entries[e as usize].visible_frame = frame;
                    visible_now.entries.push(e);
                    if !c.drawn {
                        // Not drawn for want of geometry: still wanted.
                        view.drawn.push(e);
                        stats.newly_visible += u64::from(!missing);
                        stats.chunks_drawn += u64::from(!missing);
                    }
                }
                CandidateKind::Entry(_) => {
                    if !c.drawn {
                        stats.culled_occlusion += 1;
                    }
                }
                CandidateKind::Proxy(k) => {
                    if visible {
                        proxy_seen[k as usize] = u64::MAX;
                    }
                    proxy_new[k as usize] = visible && !c.drawn;
                }
                CandidateKind::ProxyCluster(k, cluster) => {
                    if visible {
                        proxy_seen[k as usize] |= 1 << cluster;
                    }
                    stats.culled_clusters += u64::from(!visible && !c.drawn);
                }
            }
        }
        for (k, &n) in proxy_nodes.iter().enumerate() {
            let seen = proxy_seen[k];
            if seen != 0 {
                view.proxy_visible[n as usize] = frame;
                visible_now.nodes.push(n);
                visible_now.clusters.push(seen);
            }
            if proxy_drawn[k] != 0 || seen != 0 {
                stats.proxies_drawn += 1;
                h.leaves(n, &mut view.drawn);
            }
            stats.newly_visible += u64::from(proxy_new[k]);
        }
        view.hzb_visible = visible_now;
        Ok(())
    }

    /// The first pass of an `hzb` frame drawn from `last`, the set the
    /// frame before found visible, as this frame's traversal would find it:
    /// its chunk instances still in the frustum, not hidden, cut away or too
    /// small, in canonical order, and its proxies still in the frustum whose
    /// error still projects within the LOD error (`fit`, per mirror node),
    /// front to back; less what is below a node whose proxy fits now and
    /// did not then (its proxy stands for them now).
    fn last_visible(
        &self,
        scene: &Scene,
        tree: &Tree,
        cull: &Cull,
        cell_distance: &[f64],
        fit: &[bool],
        last: &HzbVisible,
    ) -> ColorDraws {
        let h = &self.hierarchy;
        let fits = |n: u32| fit.get(n as usize).copied().unwrap_or(false);
        let shown =
            |b: &Aabb3d| cull.frustum.intersects_aabb(b) && !cull.cut_away(b) && !cull.too_small(b);
        // What is in view below a proxy that fits now and did not then.
        let mut covered = std::collections::HashSet::new();
        let mut stack: Vec<u32> = (0..fit.len() as u32)
            .filter(|&n| fits(n) && !last.fit.get(n as usize).copied().unwrap_or(false))
            .collect();
        while let Some(n) = stack.pop() {
            for &c in h.children(n) {
                if shown(h.bounds(tree, c)) {
                    covered.insert(c);
                    stack.push(c);
                }
            }
        }
        let mut draws: Vec<Draw> = (last.entries.iter())
            .filter(|&&e| {
                tree.entries().get(e as usize).is_some_and(|entry| {
                    !scene.part(entry.part).hidden && !covered.contains(&e) && shown(&entry.bounds)
                })
            })
            .map(|&entry| Draw {
                entry,
                query: false,
            })
            .collect();
        sort_draws(h, cell_distance, &mut draws);
        let mut nodes: Vec<u32> = (last.nodes.iter().copied())
            .filter(|&n| fits(n) && !covered.contains(&n) && shown(h.bounds(tree, n)))
            .collect();
        let frames = self.proxy_frames(h, tree, &mut nodes, cull);
        let mask: HashMap<u32, u64> = last
            .nodes
            .iter()
            .copied()
            .zip(last.clusters.iter().copied())
            .collect();
        let clusters = nodes.iter().map(|n| mask[n]).collect();
        ColorDraws {
            draws,
            nodes,
            frames,
            clusters,
        }
    }

    /// Submits a colour round of `round`'s draws, which clears the target
    /// (a frame without occlusion culling, or an `hzb` frame's first pass).
    #[expect(
        clippy::too_many_arguments,
        reason = "the frame's context, passed through once"
    )]
    fn submit_color(
        &mut self,
        gpu: &mut crate::renderer::ViewGpu,
        target: RoundTarget<'_>,
        geometry: &dyn GeometrySource,
        scene: &Scene,
        tree: &Tree,
        cull: &Cull,
        round: &ColorDraws,
    ) -> SubmittedRound {
        let tinted = self.proxies_tinted(&self.hierarchy, tree, &round.nodes);
        self.submit_round(
            gpu,
            target,
            Shading::Color,
            true,
            geometry,
            scene,
            tree,
            &round.draws,
            &[],
            cull.lod(),
            ProxyRound {
                nodes: &round.nodes,
                frames: &round.frames,
                tinted: &tinted,
                clusters: &round.clusters,
            },
        )
    }

    /// Coherent hierarchical culling (CHC, Bittner et al. 2004, with CHC++'s
    /// randomised re-checks): draw what was visible last frame, query the
    /// invisible frontier by boxes against that depth, draw what turns out
    /// visible and query below visible inner nodes, for a bounded number of
    /// rounds; what is left is carried to the next frame.
    #[expect(
        clippy::too_many_arguments,
        reason = "the frame's context, passed through once"
    )]
    fn frame_occlusion(
        &mut self,
        view: &mut View,
        gpu: &mut crate::renderer::ViewGpu,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        target: RoundTarget<'_>,
        cull: &Cull,
        cell_distance: &[f64],
        stats: &mut FrameStats,
    ) -> Result<(), RenderError> {
        let frame = view.frame;
        let h = std::mem::take(&mut self.hierarchy);
        // Last frame's visibility, pulled up: a node is visible when any
        // chunk instance below was; children pulled before their parents.
        let order = h.pre_order();
        let mut was_visible = vec![false; h.len()];
        for &n in order.iter().rev() {
            was_visible[n as usize] = match h.kind(n) {
                NodeKind::Entry(e) => view.entries[e.0 as usize].visible_frame + 1 == frame,
                _ => h.children(n).iter().any(|&c| was_visible[c as usize]),
            };
        }
        let interval = u64::from(view.options.requery_interval.max(1));
        // A per-chunk offset spreads re-checks evenly over frames.
        let schedule =
            |e: u32| frame + interval + (u64::from(e).wrapping_mul(0x9E37_79B9) >> 7) % interval;

        // Nodes drawn as their proxies: leaves of the traversal, drawn when
        // visible and queried by their boxes as any node.
        let proxy_fit = self.proxy_fit(&h, tree, cull, target);
        let mut walk = Walk::new(&h, scene, tree, cull, stats);
        walk.proxy_fit = &proxy_fit;
        if !order.is_empty() {
            let mut stack = vec![h.root];
            while let Some(n) = stack.pop() {
                let Some(kind) = walk.admit(n) else { continue };
                let bounds = h.bounds(tree, n);
                let open = was_visible[n as usize] || cull.eye_near(bounds);
                match kind {
                    NodeKind::Entry(_) => {}
                    // A visible proxy is drawn, and re-checked by its box
                    // (drawn a round later) on a per-node schedule.
                    _ if walk.fits(n) => {
                        let recheck = schedule(n) == frame + interval;
                        if open && (!recheck || cull.eye_near(bounds)) {
                            walk.draw_proxy(n, view, frame);
                        } else {
                            walk.queries.push(n);
                        }
                        continue;
                    }
                    _ => {}
                }
                match kind {
                    NodeKind::Entry(e) if open => {
                        let state = &mut view.entries[e.0 as usize];
                        let query = state.requery_frame <= frame && !cull.eye_near(bounds);
                        if !query {
                            state.visible_frame = frame;
                        }
                        walk.draws.push(Draw { entry: e.0, query });
                    }
                    _ if open => stack.extend_from_slice(h.children(n)),
                    _ => walk.queries.push(n),
                }
            }
        }
        let expand_levels = view.options.expand_levels.max(1);
        let max_rounds = view.options.max_rounds.max(1);
        let mut result = Ok(());
        // Chunk instances re-checked while drawn: by their geometry's queries,
        // or, in a multiview pass, which carries none, by their boxes after it.
        let mut checked: Vec<u32> = Vec::new();
        let mut bounds: Vec<Aabb3d> = Vec::new();
        let mut leaves: Vec<u32> = Vec::new();
        for round in 0..max_rounds {
            let mut draws = std::mem::take(&mut walk.draws);
            let mut queries = std::mem::take(&mut walk.queries);
            // A chunk instance due for a re-check whose geometry is not resident
            // cannot be checked by drawing it: its box is queried instead, so
            // one hidden by what is resident drops out of the visible set (and
            // out of what the loader is asked for first).
            draws.retain(|d| {
                let chunk = tree.entries()[d.entry as usize].chunk;
                let drawable = !d.query || self.pool.is_resident(chunk) || geometry.has(chunk);
                if !drawable {
                    queries.push(d.entry); // an entry's node is its id
                }
                drawable
            });
            sort_draws(&h, cell_distance, &mut draws);
            checked.clear();
            checked.extend(draws.iter().filter(|d| d.query).map(|d| d.entry));
            bounds.clear();
            bounds.extend(queries.iter().map(|&n| *h.bounds(tree, n)));
            if target.is_multiview() {
                for d in &mut draws {
                    d.query = false;
                }
                bounds.extend(checked.iter().map(|&e| *h.bounds(tree, e)));
            }
            let boxes = cull.query_boxes(&bounds);
            let mut proxy_nodes = std::mem::take(&mut walk.proxy_draws);
            let frames = self.proxy_frames(&h, tree, &mut proxy_nodes, cull);
            let tinted = self.proxies_tinted(&h, tree, &proxy_nodes);
            let submitted = self.submit_round(
                gpu,
                target,
                Shading::Color,
                round == 0,
                geometry,
                scene,
                tree,
                &draws,
                &boxes,
                cull.lod(),
                ProxyRound {
                    nodes: &proxy_nodes,
                    frames: &frames,
                    tinted: &tinted,
                    clusters: &[],
                },
            );
            let r = match self.finish_round(gpu, submitted) {
                Ok(r) => r,
                Err(e) => {
                    result = Err(e);
                    break;
                }
            };
            add_round(walk.stats, &r);
            walk.stats.rounds = round + 1;
            walk.stats.queries += (r.draw_samples.len() + r.box_samples.len()) as u64;
            view.drawn.extend(draws.iter().map(|d| d.entry));
            walk.stats.proxies_drawn += proxy_nodes.len() as u64;
            for &n in &proxy_nodes {
                h.leaves(n, &mut view.drawn);
            }
            let (box_samples, check_samples) = if target.is_multiview() {
                r.box_samples.split_at(queries.len())
            } else {
                (&r.box_samples[..], &r.draw_samples[..])
            };
            assert_eq!(check_samples.len(), checked.len(), "one result per query");
            for (&e, &s) in checked.iter().zip(check_samples) {
                if s > 0 {
                    let state = &mut view.entries[e as usize];
                    walk.stats.queries_visible += 1;
                    state.visible_frame = frame;
                    state.requery_frame = schedule(e);
                }
            }
            let last = round + 1 == max_rounds;
            for (&n, &s) in queries.iter().zip(box_samples) {
                let kind = h.kind(n);
                if s == 0 {
                    // Chunk instances were counted when admitted; inner nodes
                    // count what they hide.
                    if !matches!(kind, NodeKind::Entry(_)) {
                        walk.count_below(n);
                    }
                    continue;
                }
                walk.stats.queries_visible += 1;
                match kind {
                    NodeKind::Entry(e) => {
                        let state = &mut view.entries[e.0 as usize];
                        state.visible_frame = frame;
                        state.requery_frame = schedule(e.0);
                        walk.stats.newly_visible += 1;
                        if !last {
                            walk.draws.push(Draw {
                                entry: e.0,
                                query: false,
                            });
                        }
                    }
                    _ if last => {
                        // Out of rounds: assume everything below visible next
                        // frame and check it then, rather than start over.
                        walk.count_below(n);
                        leaves.clear();
                        h.leaves(n, &mut leaves);
                        for &e in &leaves {
                            let state = &mut view.entries[e as usize];
                            state.visible_frame = frame;
                            state.requery_frame = frame + 1;
                        }
                    }
                    _ if walk.fits(n) => {
                        walk.stats.newly_visible += 1;
                        walk.draw_proxy(n, view, frame);
                    }
                    _ => walk.expand(n, expand_levels, view, frame),
                }
            }
            if walk.draws.is_empty() && walk.queries.is_empty() && walk.proxy_draws.is_empty() {
                break;
            }
        }
        let in_frustum = walk.in_frustum_entries;
        walk.stats.culled_occlusion = in_frustum.saturating_sub(view.drawn.len() as u64);
        self.hierarchy = h;
        result
    }
}

/// The state of an occlusion-culling traversal within a frame.
struct Walk<'a> {
    h: &'a Hierarchy,
    scene: &'a Scene,
    tree: &'a Tree,
    cull: &'a Cull,
    stats: &'a mut FrameStats,
    /// Draws of the next round.
    draws: Vec<Draw>,
    /// Nodes whose boxes the next round queries.
    queries: Vec<u32>,
    /// Chunk instances that passed frustum, coverage and hidden tests.
    in_frustum_entries: u64,
    /// Per mirror node: drawn as its proxy (empty: no proxies).
    proxy_fit: &'a [bool],
    /// Proxies (mirror nodes) the next round draws.
    proxy_draws: Vec<u32>,
}

impl<'a> Walk<'a> {
    fn new(
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
        }
    }

    /// Whether node `n` is drawn as its proxy this frame.
    fn fits(&self, n: u32) -> bool {
        self.proxy_fit.get(n as usize).copied().unwrap_or(false)
    }

    /// Node `n` is visible: its proxy is drawn next round, what it stands
    /// for is counted, and its chunk instances are visible this frame.
    fn draw_proxy(&mut self, n: u32, view: &mut View, frame: u64) {
        self.proxy_draws.push(n);
        self.count_below(n);
        let mut leaves = Vec::new();
        self.h.leaves(n, &mut leaves);
        for e in leaves {
            view.entries[e as usize].visible_frame = frame;
        }
    }

    /// Frustum, coverage and hidden tests of a node, counted; its kind if it
    /// passes. Admitted chunk instances count towards what frustum culling
    /// alone would draw.
    fn admit(&mut self, n: u32) -> Option<NodeKind> {
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
        }
        Some(kind)
    }

    /// Counts what frustum culling would draw below a node occlusion culled,
    /// for the stats and the adaptive decision (not as visited nodes).
    fn count_below(&mut self, n: u32) {
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
    fn expand(&mut self, n: u32, levels: u32, view: &mut View, frame: u64) {
        let mut stack: Vec<(u32, u32)> = self.h.children(n).iter().map(|&c| (c, 1)).collect();
        while let Some((c, depth)) = stack.pop() {
            let Some(kind) = self.admit(c) else { continue };
            let near = self.cull.eye_near(self.h.bounds(self.tree, c));
            match kind {
                NodeKind::Entry(e) if near => {
                    view.entries[e.0 as usize].visible_frame = frame;
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

fn add_round(stats: &mut FrameStats, r: &RoundResult) {
    stats.passes += r.passes;
    stats.not_resident += r.not_resident;
    stats.chunks_drawn += r.chunks;
    stats.draw_calls += r.draw_calls;
    stats.upload_ms += r.upload_ms;
    stats.triangles_drawn += r.triangles;
    stats.gpu_ms += r.gpu_ms;
    stats.gpu_draw_ms += r.gpu_draw_ms;
}
