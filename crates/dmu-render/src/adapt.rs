//! The per-view decision whether occlusion queries pay: they cost query
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

use crate::renderer::Renderer;
use crate::view::{AUTO_PROBE_EVERY, AutoChoice, Culling, FrameStats, OcclusionDecision, View};

/// The modes `auto` chooses among, in the order it first times them.
const AUTO_MODES: [Culling; 3] = [Culling::Hzb, Culling::Occlusion, Culling::Frustum];
/// Frames in a mode before its times count (visibility builds up).
const AUTO_WARMUP: u32 = 2;
/// Frames a mode runs when timed (the first [`AUTO_WARMUP`] not counted).
const AUTO_PROBE_FRAMES: u32 = 4;

/// `auto` culling's state in a view: the mode it runs, how long it has, and
/// each mode's frame time (in [`AUTO_MODES`] order; 0: not timed yet).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct AutoState {
    /// Index into [`AUTO_MODES`].
    mode: usize,
    frames_in_mode: u32,
    ms: [f64; 3],
    /// Which of the other two the next re-timing takes.
    next_probe: usize,
}

impl AutoState {
    /// The mode this frame runs.
    pub(crate) fn mode(&self) -> Culling {
        AUTO_MODES[self.mode]
    }

    /// What each mode took, as the stats give it, with the mode that `ran`.
    pub(crate) fn choice(&self, ran: Culling) -> AutoChoice {
        AutoChoice {
            ran,
            hzb_ms: self.ms[0],
            chc_ms: self.ms[1],
            frustum_ms: self.ms[2],
        }
    }

    /// Counts a frame of the current mode that took `frame_ms`, and picks
    /// the next frame's: a mode not timed yet, else back to the fastest
    /// after timing another, else another every [`AUTO_PROBE_EVERY`] frames.
    pub(crate) fn after_frame(&mut self, frame_ms: f64) {
        self.frames_in_mode += 1;
        if self.frames_in_mode > AUTO_WARMUP {
            let m = &mut self.ms[self.mode];
            *m = blend(*m, frame_ms, self.frames_in_mode == AUTO_WARMUP + 1);
        }
        if self.frames_in_mode < AUTO_PROBE_FRAMES {
            return;
        }
        let fastest = (0..AUTO_MODES.len())
            .min_by(|&a, &b| self.ms[a].total_cmp(&self.ms[b]))
            .expect("modes");
        let next = if let Some(untimed) = self.ms.iter().position(|&m| m == 0.0) {
            untimed
        } else if self.mode != fastest {
            fastest
        } else if self.frames_in_mode >= AUTO_PROBE_EVERY {
            let others: Vec<usize> = (0..AUTO_MODES.len()).filter(|&m| m != fastest).collect();
            self.next_probe = (self.next_probe + 1) % others.len();
            others[self.next_probe]
        } else {
            return;
        };
        self.mode = next;
        self.frames_in_mode = 0;
    }
}

/// Frames queries run after (re)enabling before they may be switched off; the
/// first [`WARMUP_FRAMES`] of them build visibility and are not measured.
const PROBE_FRAMES: u32 = 8;
const WARMUP_FRAMES: u32 = 3;
/// Frames a view draws without queries before trying them again.
const RETRY_FRAMES: u32 = 60;
/// Weight of the newest frame in the running averages.
const ALPHA: f64 = 0.3;

fn blend(old: f64, new: f64, first: bool) -> f64 {
    if first {
        new
    } else {
        old + ALPHA * (new - old)
    }
}

impl Renderer {
    /// Occlusion queries' decision after a frame culled with `culling`.
    pub(crate) fn decide(&self, view: &mut View, culling: Culling, stats: &mut FrameStats) {
        if culling != Culling::Occlusion {
            stats.occlusion = OcclusionDecision::default();
            return;
        }
        // Drawing time: the passes that drew, by timestamps where there are any.
        let draw_ms = if stats.gpu_draw_ms > 0.0 {
            stats.gpu_draw_ms
        } else {
            stats.cpu_ms
        };
        // The frame minus drawing: culling, uploads and, with queries, the query
        // passes and the waits between rounds.
        let overhead_ms = (stats.cpu_ms - draw_ms).max(0.0);
        if stats.triangles_drawn >= 10_000 {
            let ns = draw_ms * 1e6 / stats.triangles_drawn as f64;
            view.ns_per_triangle = blend(view.ns_per_triangle, ns, view.ns_per_triangle == 0.0);
        }
        let proxies = self.proxies.is_some() && stats.lod_error_px > 0.0;
        let d = &mut view.decision;
        if d.enabled {
            view.probe_frames += 1;
            if view.probe_frames > WARMUP_FRAMES {
                let first = view.probe_frames == WARMUP_FRAMES + 1;
                let culled = stats
                    .triangles_in_frustum
                    .saturating_sub(stats.triangles_drawn);
                let saved = if proxies {
                    // What a frame without queries would draw beyond this
                    // one's drawing (its overhead aside), so that cost >
                    // saved is "slower than without".
                    (view.frustum_frame_ms - view.baseline_overhead_ms - draw_ms).max(0.0)
                } else {
                    culled as f64 * view.ns_per_triangle * 1e-6
                };
                let cost = (overhead_ms - view.baseline_overhead_ms).max(0.0);
                d.saved_ms = blend(d.saved_ms, saved, first);
                d.cost_ms = blend(d.cost_ms, cost, first);
            }
            let unmeasured = proxies && view.frustum_frame_ms == 0.0;
            if view.options.adaptive
                && view.probe_frames >= PROBE_FRAMES
                && (d.cost_ms > d.saved_ms || unmeasured)
            {
                d.enabled = false;
                d.retry_in_frames = RETRY_FRAMES;
            }
        } else {
            if proxies {
                view.frustum_frame_ms = blend(
                    view.frustum_frame_ms,
                    stats.cpu_ms,
                    view.frustum_frame_ms == 0.0,
                );
            }
            view.baseline_overhead_ms = blend(
                view.baseline_overhead_ms,
                overhead_ms,
                view.baseline_overhead_ms == 0.0,
            );
            d.retry_in_frames = d.retry_in_frames.saturating_sub(1);
            if d.retry_in_frames == 0 {
                d.enabled = true;
                view.probe_frames = 0;
                view.entries.clear();
            }
        }
        stats.occlusion = *d;
    }
}
