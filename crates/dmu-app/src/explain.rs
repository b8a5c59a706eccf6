//! The choices the renderer makes by measurement, in words with the figures
//! behind them: what `--explain` prints on `dmu render` and `dmu walk`, and what
//! the viewer's "Why" section lists. (The collision sweep's choice speaks for
//! itself: `dmu_collide::SweepDecision::describe`, which `dmu collide
//! --explain` prints.)

use dmu_render::{AUTO_PROBE_EVERY, AutoChoice, Culling, FrameStats, OcclusionDecision};

/// An `auto` view's choice in one sentence: the culling a frame ran and
/// what each mode's frames took here.
pub fn auto_now(used: Culling, a: &AutoChoice) -> String {
    let ms = |v: f64| {
        if v > 0.0 {
            format!("{v:.1} ms")
        } else {
            "not timed yet".to_owned()
        }
    };
    format!(
        "auto culling ran {}: a frame took hzb {}, chc {}, frustum {} here (the fastest is kept, the others timed again every {AUTO_PROBE_EVERY} frames)",
        used.name(),
        ms(a.hzb_ms),
        ms(a.chc_ms),
        ms(a.frustum_ms)
    )
}

/// An `auto` view's choices over a run of frames: each frame whose culling
/// differs from the frame before, and the last, `frame N: ...`. Nothing for
/// frames of other modes.
pub fn auto_changes(frames: &[FrameStats]) -> Vec<String> {
    let mut lines = Vec::new();
    let mut before = None;
    for (i, s) in frames.iter().enumerate() {
        let Some(a) = &s.auto else { continue };
        if before != Some(s.culling) || i + 1 == frames.len() {
            lines.push(format!("frame {}: {}", i + 1, auto_now(s.culling, a)));
        }
        before = Some(s.culling);
    }
    lines
}

/// A view's occlusion decision now, in one sentence.
pub fn occlusion_now(culling: Culling, d: &OcclusionDecision) -> String {
    if culling != Culling::Occlusion {
        return format!(
            "occlusion queries not asked for (culling {}): nothing chosen by measurement",
            culling.name()
        );
    }
    if d.enabled && d.cost_ms == 0.0 && d.saved_ms == 0.0 {
        return "occlusion queries on: measuring (the first frames build visibility)".to_owned();
    }
    if d.enabled {
        format!(
            "occlusion queries on: they save {:.3} ms a frame of drawing for {:.3} ms of queries and waits",
            d.saved_ms, d.cost_ms
        )
    } else {
        format!(
            "occlusion queries off: they cost {:.3} ms a frame in queries and waits and saved only {:.3} ms of drawing; tried again in {} frames",
            d.cost_ms, d.saved_ms, d.retry_in_frames
        )
    }
}

/// The occlusion decisions over a run of frames: the first frame's, each
/// frame where queries were switched on or off, and the last frame's, one
/// line each, `frame N: ...`.
pub fn occlusion_changes(culling: Culling, frames: &[FrameStats]) -> Vec<String> {
    let mut lines = Vec::new();
    let mut before: Option<bool> = None;
    for (i, s) in frames.iter().enumerate() {
        let last = i + 1 == frames.len();
        if before != Some(s.occlusion.enabled) || last {
            lines.push(format!(
                "frame {}: {}",
                i + 1,
                occlusion_now(culling, &s.occlusion)
            ));
        }
        before = Some(s.occlusion.enabled);
        if culling != Culling::Occlusion {
            break;
        }
    }
    lines
}

/// A frame-time budget's choices over a run of frames: each frame whose LOD
/// error or coverage threshold differs from the frame before, with the time
/// of the frame that made the budget choose, `frame N: ...`. Nothing without
/// a budget.
pub fn budget_changes(target_ms: Option<f64>, frames: &[FrameStats]) -> Vec<String> {
    let Some(target) = target_ms else {
        return Vec::new();
    };
    frames
        .windows(2)
        .enumerate()
        .filter(|(_, w)| {
            (w[0].lod_error_px, w[0].min_pixels) != (w[1].lod_error_px, w[1].min_pixels)
        })
        .map(|(i, w)| {
            let (a, b) = (&w[0], &w[1]);
            // What the budget weighs: the frame without its chunk uploads.
            let ms = a.cpu_ms - a.upload_ms;
            format!(
                "frame {}: the frame before took {ms:.1} ms (uploads aside) against the \
                 {target} ms budget ({}): LOD error {:.2} -> {:.2} px, coverage threshold \
                 {:.2} -> {:.2} px",
                i + 2,
                if ms > target {
                    "over: less accuracy"
                } else {
                    "time to spare: more accuracy"
                },
                a.lod_error_px,
                b.lod_error_px,
                a.min_pixels,
                b.min_pixels
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(enabled: bool, cost_ms: f64, saved_ms: f64) -> FrameStats {
        FrameStats {
            occlusion: OcclusionDecision {
                enabled,
                cost_ms,
                saved_ms,
                retry_in_frames: if enabled { 0 } else { 60 },
            },
            ..FrameStats::default()
        }
    }

    #[test]
    fn changes_name_the_frames_and_the_figures() {
        let frames = [
            frame(true, 0.0, 0.0),
            frame(true, 2.0, 0.5),
            frame(false, 2.0, 0.5),
            frame(false, 2.0, 0.5),
        ];
        let lines = occlusion_changes(Culling::Occlusion, &frames);
        assert_eq!(lines.len(), 3, "{lines:?}");
        assert!(lines[0].starts_with("frame 1: occlusion queries on: measuring"));
        assert!(
            lines[1].starts_with("frame 3: occlusion queries off: they cost 2.000 ms")
                && lines[1].contains("saved only 0.500 ms")
                && lines[1].contains("60 frames"),
            "{}",
            lines[1]
        );
        assert!(lines[2].starts_with("frame 4: occlusion queries off"));
        let frustum = occlusion_changes(Culling::Frustum, &frames);
        assert_eq!(frustum.len(), 1);
        assert!(frustum[0].contains("not asked for (culling frustum)"));
    }

    #[test]
    fn auto_names_each_switch_and_the_times_behind_it() {
        let times = AutoChoice {
            ran: Culling::Hzb,
            frustum_ms: 480.0,
            chc_ms: 0.0,
            hzb_ms: 250.5,
        };
        let at = |culling: Culling| FrameStats {
            culling,
            auto: Some(AutoChoice {
                ran: culling,
                ..times
            }),
            ..FrameStats::default()
        };
        let frames = [
            at(Culling::Hzb),
            at(Culling::Hzb),
            at(Culling::Frustum),
            at(Culling::Hzb),
            at(Culling::Hzb),
        ];
        let lines = auto_changes(&frames);
        assert_eq!(lines.len(), 4, "{lines:#?}");
        assert!(
            lines[0].starts_with("frame 1: auto culling ran hzb"),
            "{}",
            lines[0]
        );
        assert!(
            lines[1].starts_with("frame 3: auto culling ran frustum"),
            "{}",
            lines[1]
        );
        assert!(lines[3].starts_with("frame 5: "), "{}", lines[3]);
        assert!(
            lines[0].contains("hzb 250.5 ms, chc not timed yet, frustum 480.0 ms"),
            "{}",
            lines[0]
        );
        // Frames of a fixed mode say nothing of auto.
        assert!(auto_changes(&[FrameStats::default()]).is_empty());
    }

    #[test]
    fn a_budget_explains_each_change_with_the_time_behind_it() {
        let frame = |cpu_ms: f64, lod_error_px: f64, min_pixels: f64| FrameStats {
            cpu_ms,
            lod_error_px,
            min_pixels,
            ..FrameStats::default()
        };
        let frames = [
            frame(250.0, 1.0, 0.0),
            frame(150.0, 2.5, 0.0),
            frame(90.0, 2.5, 0.0),
            frame(40.0, 2.5, 0.0),
            frame(60.0, 2.0, 0.0),
        ];
        let lines = budget_changes(Some(100.0), &frames);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(
            lines[0].starts_with("frame 2: the frame before took 250.0 ms (uploads aside)"),
            "{}",
            lines[0]
        );
        assert!(
            lines[0].contains("over") && lines[0].contains("1.00 -> 2.50"),
            "{}",
            lines[0]
        );
        assert!(
            lines[1].starts_with("frame 5:") && lines[1].contains("time to spare"),
            "{}",
            lines[1]
        );
        assert!(budget_changes(None, &frames).is_empty());
    }
}
