//! Coherent hierarchical occlusion culling (CHC), and the per-view decision
//! whether its queries pay: they cost query
//! passes and round trips, and save the triangles they cull. Both are measured
//! every frame; a view where queries cost more than they save draws with
//! frustum culling only and tries queries again later.
//!
//! Where proxies draw (a renderer with [`crate::Proxies`] and a LOD error
//! above 0), frustum culling draws far fewer triangles than are in the
//! frustum, so the triangles queries cull say little of what they save:
//! there the frames without queries are timed, and queries are kept only
//! while a frame with them is faster than those. A view measures that once
//! before it can keep queries (its first probe ends in frustum frames).

use dmu_geom::Aabb3d;

use crate::cull::{Frame, Walk, add_round, sort_draws};
use crate::error::RenderError;
use crate::farfield::FarCut;
use crate::hierarchy::NodeKind;
use crate::renderer::Renderer;
use crate::round::{Draw, ProxyRound, Round, Shading};
use crate::settings::Culling;
use crate::state::blend;
use crate::stats::FrameStats;
use crate::view::View;

use super::frustum::Frustum;
use super::strategy::Strategy;

/// Frames queries run after (re)enabling before they may be switched off; the
/// first [`WARMUP_FRAMES`] of them build visibility and are not measured.
const PROBE_FRAMES: u32 = 8;
const WARMUP_FRAMES: u32 = 3;
/// Frames a view draws without queries before trying them again.
const RETRY_FRAMES: u32 = 60;

/// [`Culling::Occlusion`]: queries where the view's decision keeps them on
/// and no far field is drawn, else frustum culling.
pub(crate) struct Chc;

impl Strategy for Chc {
    fn draw(&self, renderer: &mut Renderer, f: &mut Frame<'_>) -> Result<(), RenderError> {
        let near_field = matches!(f.cull.far, FarCut::Near(_));
        if !f.view.state.chc.decision.enabled || near_field {
            return Frustum.draw(renderer, f);
        }
        f.stats.culling = Culling::Occlusion;
        renderer.frame_occlusion(f)
    }

    /// Occlusion queries' decision after a frame.
    fn after_frame(&self, renderer: &Renderer, view: &mut View, stats: &mut FrameStats) {
        // Drawing time: the passes that drew, by timestamps where there are any.
        let draw_ms = if stats.gpu_draw_ms > 0.0 {
            stats.gpu_draw_ms
        } else {
            stats.cpu_ms
        };
        // The frame minus drawing: culling, uploads and, with queries, the query
        // passes and the waits between rounds.
        let overhead_ms = (stats.cpu_ms - draw_ms).max(0.0);
        let chc = &mut view.state.chc;
        if stats.triangles_drawn >= 10_000 {
            let ns = draw_ms * 1e6 / stats.triangles_drawn as f64;
            chc.ns_per_triangle = blend(chc.ns_per_triangle, ns, chc.ns_per_triangle == 0.0);
        }
        let proxies = renderer.proxies.is_some() && stats.lod_error_px > 0.0;
        let d = &mut chc.decision;
        if d.enabled {
            chc.probe_frames += 1;
            if chc.probe_frames > WARMUP_FRAMES {
                let first = chc.probe_frames == WARMUP_FRAMES + 1;
                let culled = stats
                    .triangles_in_frustum
                    .saturating_sub(stats.triangles_drawn);
                let saved = if proxies {
                    // What a frame without queries would draw beyond this
                    // one's drawing (its overhead aside), so that cost >
                    // saved is "slower than without".
                    (chc.frustum_frame_ms - chc.baseline_overhead_ms - draw_ms).max(0.0)
                } else {
                    culled as f64 * chc.ns_per_triangle * 1e-6
                };
                let cost = (overhead_ms - chc.baseline_overhead_ms).max(0.0);
                d.saved_ms = blend(d.saved_ms, saved, first);
                d.cost_ms = blend(d.cost_ms, cost, first);
            }
            let unmeasured = proxies && chc.frustum_frame_ms == 0.0;
            if view.options.adaptive
                && chc.probe_frames >= PROBE_FRAMES
                && (d.cost_ms > d.saved_ms || unmeasured)
            {
                d.enabled = false;
                d.retry_in_frames = RETRY_FRAMES;
            }
        } else {
            if proxies {
                chc.frustum_frame_ms = blend(
                    chc.frustum_frame_ms,
                    stats.cpu_ms,
                    chc.frustum_frame_ms == 0.0,
                );
            }
            chc.baseline_overhead_ms = blend(
                chc.baseline_overhead_ms,
                overhead_ms,
                chc.baseline_overhead_ms == 0.0,
            );
            d.retry_in_frames = d.retry_in_frames.saturating_sub(1);
            if d.retry_in_frames == 0 {
                d.enabled = true;
                chc.probe_frames = 0;
                view.state.entries.clear();
            }
        }
        stats.occlusion = *d;
    }
}

impl Renderer {
    /// Coherent hierarchical culling (CHC, Bittner et al. 2004, with CHC++'s
    /// randomised re-checks): draw what was visible last frame, query the
    /// invisible frontier by boxes against that depth, draw what turns out
    /// visible and query below visible inner nodes, for a bounded number of
    /// rounds; what is left is carried to the next frame.
    pub(crate) fn frame_occlusion(&mut self, f: &mut Frame<'_>) -> Result<(), RenderError> {
        let model = f.model;
        let (scene, tree, geometry) = (model.scene, model.tree, model.geometry);
        let (target, cull, cell_distance) = (f.target, f.cull, f.cell_distance);
        let (view, gpu, stats) = (&mut *f.view, &mut *f.gpu, &mut *f.stats);
        let frame = view.state.frame;
        let h = std::mem::take(&mut self.hierarchy);
        // Last frame's visibility, pulled up: a node is visible when any
        // chunk instance below was; children pulled before their parents.
        let order = h.pre_order();
        let mut was_visible = vec![false; h.len()];
        for &n in order.iter().rev() {
            was_visible[n as usize] = match h.kind(n) {
                NodeKind::Entry(e) => view.state.entries[e.0 as usize].visible_frame == frame - 1,
                _ => h.children(n).iter().any(|&c| was_visible[c as usize]),
            };
        }
        let interval = view.options.requery_interval.max(1);
        // A per-chunk offset spreads re-checks evenly over frames.
        let schedule = |e: u32| {
            let offset = (u64::from(e).wrapping_mul(0x9E37_79B9) >> 7) % u64::from(interval);
            frame.saturating_add(interval).saturating_add(offset as u32)
        };

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
                        let state = &mut view.state.entries[e.0 as usize];
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
                model,
                &Round {
                    shading: Shading::Color,
                    clear: round == 0,
                    draws: &draws,
                    boxes: &boxes,
                    lod: cull.lod(),
                    proxies: ProxyRound {
                        nodes: &proxy_nodes,
                        frames: &frames,
                        tinted: &tinted,
                        clusters: &[],
                    },
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
            view.state.drawn.extend(draws.iter().map(|d| d.entry));
            walk.stats.proxies_drawn += proxy_nodes.len() as u64;
            for &n in &proxy_nodes {
                self.proxy_drawn(&h, n, &mut view.state.drawn);
            }
            let (box_samples, check_samples) = if target.is_multiview() {
                r.box_samples.split_at(queries.len())
            } else {
                (&r.box_samples[..], &r.draw_samples[..])
            };
            assert_eq!(check_samples.len(), checked.len(), "one result per query");
            for (&e, &s) in checked.iter().zip(check_samples) {
                if s > 0 {
                    let state = &mut view.state.entries[e as usize];
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
                        let state = &mut view.state.entries[e.0 as usize];
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
                            let state = &mut view.state.entries[e as usize];
                            state.visible_frame = frame;
                            state.requery_frame = frame.saturating_add(1);
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
        walk.stats.culled_occlusion = in_frustum.saturating_sub(view.state.drawn.len() as u64);
        self.hierarchy = h;
        result
    }
}
