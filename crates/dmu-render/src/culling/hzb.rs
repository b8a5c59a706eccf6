//! Two-pass hierarchical-Z culling ([`Culling::Hzb`]) as a strategy: which
//! candidates the first pass draws, what the second pass tests, and what
//! the frame leaves visible for the next (the GPU side is `crate::hzb`).

use std::collections::HashMap;

use dmu_geom::{Aabb3d, Aabb3f};
use dmu_scene::Scene;
use dmu_tree::Tree;
use glam::DVec3;

use crate::cull::{Cull, Frame, add_round, sort_draws};
use crate::error::RenderError;
use crate::farfield::FarCut;
use crate::hzb::{Candidate, CandidateKind, SecondPassInput, draw_list};
use crate::renderer::Renderer;
use crate::round::{ColorDraws, Draw};
use crate::settings::Culling;
use crate::state::HzbVisible;

use super::frustum::Frustum;
use super::strategy::Strategy;

/// [`Culling::Hzb`]: single views whose device and depth target allow it,
/// else frustum culling.
pub(crate) struct Hzb;

impl Strategy for Hzb {
    fn draw(&self, renderer: &mut Renderer, f: &mut Frame<'_>) -> Result<(), RenderError> {
        if f.target.eye_count() != 1 || !renderer.hzb_supported(f.target.all().depth) {
            return Frustum.draw(renderer, f);
        }
        f.stats.culling = Culling::Hzb;
        renderer.frame_hzb(f)
    }
}

impl Renderer {
    /// Two-pass hierarchical-Z occlusion culling ([`crate::hzb`]): the
    /// frustum's candidates (chunk instances and proxies) visible last frame,
    /// or with an eye near their box, are drawn first in canonical order;
    /// every candidate is then tested against the depth pyramid of that
    /// pass and the newly visible are drawn in the same frame. A candidate
    /// visible in this frame's test is drawn first next frame; a proxy the
    /// first pass draws is tested cluster by cluster, and only its clusters
    /// found visible are drawn first next frame.
    pub(crate) fn frame_hzb(&mut self, f: &mut Frame<'_>) -> Result<(), RenderError> {
        let (scene, tree) = (f.model.scene, f.model.tree);
        let (target, cull, cell_distance) = (f.target, f.cull, f.cell_distance);
        let frame = f.view.state.frame;
        // Last frame's visible set, where last frame was an `hzb` frame of
        // this view: the first pass draws it before the tree is traversed,
        // so the traversal runs while the GPU draws.
        let last = std::mem::take(&mut f.view.state.hzb.visible);
        let fit = self.frame_fit(Culling::Hzb, tree, cull, target);
        let early = (last.frame == frame - 1
            && last.revision == Some(tree.revision())
            && matches!(cull.far, FarCut::None))
        .then(|| self.last_visible(scene, tree, cull, cell_distance, &fit, &last));
        let early_round = early.as_ref().map(|first| self.submit_color(f, first));
        let ColorDraws {
            draws,
            nodes: proxy_nodes,
            frames,
            ..
        } = self.candidates(Culling::Hzb, &fit, f);
        let h = &self.hierarchy;
        if f.view.state.hzb.proxy_visible.len() != h.len() {
            f.view.state.hzb.proxy_visible = vec![0; h.len()];
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
                    let was = f.view.state.hzb.proxy_visible[n as usize];
                    let near = cull.eye_near(h.bounds(tree, n));
                    if near || (was > 0 && was == frame - 1) {
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
                    let was = f.view.state.entries[d.entry as usize].visible_frame;
                    cull.eye_near(&b) || (was > 0 && was == frame - 1)
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
                    draws: draw_list(&candidates),
                    ..ColorDraws::default()
                };
                for ((&n, &mask), frame) in proxy_nodes.iter().zip(&proxy_drawn).zip(&frames) {
                    if mask != 0 {
                        first.nodes.push(n);
                        first.frames.push(*frame);
                        first.clusters.push(mask);
                    }
                }
                let round = self.submit_color(f, &first);
                (round, first.draws)
            }
        };
        // Second pass: the pyramid, every candidate's test, the newly visible,
        // prepared while the GPU draws the first.
        let input = SecondPassInput {
            projection: f.view.projection(),
            candidates: &candidates,
            proxy_nodes: &proxy_nodes,
            proxy_frames: &frames,
            lod: cull.lod(),
        };
        let second = self.hzb_second_pass(
            f.gpu,
            &mut f.view.state.pyramid,
            target.all(),
            f.model,
            &input,
        )?;
        let r = self.finish_round(f.gpu, first)?;
        add_round(f.stats, &r);
        f.stats.rounds = 2;
        f.stats.passes += 1;
        f.stats.draw_calls += second.draw_calls;
        f.stats.gpu_ms += second.compute_ms + second.draw_ms;
        f.stats.gpu_draw_ms += second.draw_ms;
        f.stats.triangles_drawn += second.triangles;
        f.stats.not_resident += second.missing.iter().filter(|&&m| m).count() as u64;
        f.view
            .state
            .drawn
            .extend(first_draws.iter().map(|d| d.entry));
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
                    f.view.state.entries[e as usize].visible_frame = frame;
                    visible_now.entries.push(e);
                    if !c.drawn {
                        // Not drawn for want of geometry: still wanted.
                        f.view.state.drawn.push(e);
                        f.stats.newly_visible += u64::from(!missing);
                        f.stats.chunks_drawn += u64::from(!missing);
                    }
                }
                CandidateKind::Entry(_) => {
                    if !c.drawn {
                        f.stats.culled_occlusion += 1;
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
                    f.stats.culled_clusters += u64::from(!visible && !c.drawn);
                }
            }
        }
        for (k, &n) in proxy_nodes.iter().enumerate() {
            let seen = proxy_seen[k];
            if seen != 0 {
                f.view.state.hzb.proxy_visible[n as usize] = frame;
                visible_now.nodes.push(n);
                visible_now.clusters.push(seen);
            }
            if proxy_drawn[k] != 0 || seen != 0 {
                f.stats.proxies_drawn += 1;
                self.proxy_drawn(&self.hierarchy, n, &mut f.view.state.drawn);
            }
            f.stats.newly_visible += u64::from(proxy_new[k]);
        }
        f.view.state.hzb.visible = visible_now;
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
}
