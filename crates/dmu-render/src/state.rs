//! A view's state from frame to frame, apart from its settings: what each
//! culling strategy carries over (CHC's per-entry schedule and its decision
//! whether queries pay, what `hzb` found visible, what `auto` timed), the
//! budget's knobs and the view's GPU resources.

use crate::budget::KnobsInEffect;
use crate::hzb::HzbGpu;
use crate::round::ViewGpu;
use crate::settings::{AUTO_PROBE_EVERY, Culling};
use crate::stats::{AutoChoice, FrameStats, OcclusionDecision};

/// Everything a view carries from one frame to the next.
#[derive(Debug, Default)]
pub(crate) struct ViewState {
    /// Frame number (1 for the first frame). 32 bits, as the per-entry
    /// frame numbers: 2^32 frames are 2.3 years at 60 frames a second, after
    /// which [`ViewState::next_frame`] starts the view's visibility over.
    pub frame: u32,
    /// Per tree entry: when it was last visible and is due for a re-check.
    pub entries: Vec<EntryState>,
    pub chc: ChcState,
    pub hzb: HzbState,
    /// What `auto` culling has timed, and the mode it runs.
    pub auto: AutoState,
    /// The knobs the next frame draws with under a budget (`None` before the
    /// first frame).
    pub knobs: Option<KnobsInEffect>,
    pub last: FrameStats,
    /// Chunk instances drawn in the last frame, in draw order.
    pub drawn: Vec<u32>,
    /// GPU resources, made by the renderer on the first frame.
    pub gpu: Option<ViewGpu>,
    /// The depth pyramid and box-test buffers of `hzb` frames.
    pub pyramid: Option<HzbGpu>,
}

impl ViewState {
    /// Counts a new frame; past the last 32-bit frame number, the frame
    /// numbers start again from 1 and what was visible is forgotten, as on
    /// a view's first frame.
    pub(crate) fn next_frame(&mut self) {
        self.frame = match self.frame.checked_add(1) {
            Some(frame) => frame,
            None => {
                self.forget_visibility();
                1
            }
        };
    }

    /// Forgets what was visible: the next frame culls from scratch.
    pub(crate) fn forget_visibility(&mut self) {
        self.entries.clear();
        self.hzb = HzbState::default();
    }
}

/// Visibility state of one chunk instance in one view: 8 bytes, one of
/// them per chunk instance of the model in every view (9.5 MB a view at
/// 500M triangles, half what 64-bit frame numbers took).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct EntryState {
    /// Last frame the chunk instance was drawn as visible (0: never).
    pub visible_frame: u32,
    /// Frame at which a visible chunk instance is queried again.
    pub requery_frame: u32,
}
const _: () = assert!(size_of::<EntryState>() == 8);

/// Coherent occlusion culling's decision whether queries pay, and the
/// running averages behind it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ChcState {
    pub decision: OcclusionDecision,
    /// Drawing time per triangle, ns.
    pub ns_per_triangle: f64,
    /// Frames of the current adaptive probe (queries on while measuring).
    pub probe_frames: u32,
    /// Average non-drawing time of frames without queries, ms.
    pub baseline_overhead_ms: f64,
    /// Average frame time without queries, ms, measured where proxies draw
    /// (0: not measured yet).
    pub frustum_frame_ms: f64,
}

impl Default for ChcState {
    fn default() -> Self {
        Self {
            decision: OcclusionDecision {
                enabled: true,
                ..OcclusionDecision::default()
            },
            ns_per_triangle: 0.0,
            probe_frames: 0,
            baseline_overhead_ms: 0.0,
            frustum_frame_ms: 0.0,
        }
    }
}

/// What `hzb` frames carry over.
#[derive(Clone, Debug, Default)]
pub(crate) struct HzbState {
    /// Per mirror node: last frame its proxy tested visible in an `hzb`
    /// frame (0: never).
    pub proxy_visible: Vec<u32>,
    /// What the last `hzb` frame found visible, which the next one draws
    /// first.
    pub visible: HzbVisible,
}

/// What an `hzb` frame found visible: chunk instances (entry ids) and
/// proxies (mirror nodes); its frame number, the tree's revision then
/// (`None`: no frame yet), and per mirror node whether its proxy fitted the
/// LOD error (`Renderer::frame_fit`).
#[derive(Clone, Debug, Default)]
pub(crate) struct HzbVisible {
    pub frame: u32,
    pub revision: Option<dmu_tree::Revision>,
    pub entries: Vec<u32>,
    pub nodes: Vec<u32>,
    /// Per node of `nodes`, its proxy's clusters found visible (bit c:
    /// cluster c; all bits where the proxy was tested whole).
    pub clusters: Vec<u64>,
    pub fit: Vec<bool>,
}

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

/// Weight of the newest frame in the running averages.
const ALPHA: f64 = 0.3;

/// A running average's next value after `new` (`first`: its first value).
pub(crate) fn blend(old: f64, new: f64, first: bool) -> f64 {
    if first {
        new
    } else {
        old + ALPHA * (new - old)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 32-bit frame numbers: counted up, and past the last one started
    /// again from 1 with the visibility forgotten, so no entry's frame is
    /// ever ahead of the view's (which would skip its queries).
    #[test]
    fn frame_numbers_start_over_with_nothing_visible_after_the_last() {
        let mut state = ViewState {
            frame: u32::MAX - 1,
            entries: vec![EntryState::default(); 3],
            ..ViewState::default()
        };
        state.hzb.proxy_visible = vec![7; 2];
        state.next_frame();
        assert_eq!(state.frame, u32::MAX);
        assert_eq!(state.entries.len(), 3, "kept within the range");
        state.entries[1] = EntryState {
            visible_frame: u32::MAX,
            requery_frame: u32::MAX,
        };
        state.next_frame();
        assert_eq!(state.frame, 1);
        assert!(state.entries.is_empty(), "visibility forgotten");
        assert!(state.hzb.proxy_visible.is_empty());
    }
}
