//! A frame-time budget: a view given `CullingOptions::target_ms` chooses,
//! frame by frame, the LOD error and the coverage threshold it draws with, so
//! its frames fit the budget with the least error they can: accuracy when
//! there is time, frame rate when there is not.
//!
//! The choice follows the measured frame time (the renderer's own, GPU wait
//! included, chunk uploads excluded: the knobs do not change them): over
//! budget, the LOD error grows (in proportion to the overrun, up to
//! [`MAX_LOD_ERROR_PX`]), then the coverage threshold; after
//! [`CALM_FRAMES`] frames in a row well under budget, the threshold comes
//! back down first, then the error, to exact. The wait keeps a relaxing step
//! that overruns from alternating with the tightening one every other frame.
//! A feedback loop rather than a cost model: it needs no calibration per
//! machine, and its lag is one frame, which the walk measures (frames over
//! budget).

use crate::settings::CullingOptions;

/// The most LOD error a budget may choose, pixels.
pub const MAX_LOD_ERROR_PX: f64 = 8.0;
/// The highest coverage threshold a budget may choose, pixels.
pub const MAX_MIN_PIXELS: f64 = 32.0;
/// Under this share of the budget, a frame gives accuracy back.
const SLACK: f64 = 0.7;
/// How much one frame may tighten a knob, and the least it relaxes one.
const MAX_STEP: f64 = 3.0;
const RELAX: f64 = 1.25;
/// Frames in a row well under budget before a knob relaxes.
pub const CALM_FRAMES: u32 = 4;

/// The knobs a frame draws with.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KnobsInEffect {
    /// LOD error bound, pixels.
    pub lod_error_px: f64,
    /// Coverage threshold, pixels.
    pub min_pixels: f64,
    /// Frames in a row well under budget so far.
    pub calm_frames: u32,
}

impl KnobsInEffect {
    /// The knobs as `options` sets them.
    pub fn of(options: &CullingOptions) -> Self {
        Self {
            lod_error_px: options.lod_error_px,
            min_pixels: options.min_pixels,
            calm_frames: 0,
        }
    }

    /// The knobs with the coverage threshold at least `options.min_pixels`
    /// (the user may raise it while a budget runs).
    pub fn within(mut self, options: &CullingOptions) -> Self {
        self.min_pixels = self.min_pixels.max(options.min_pixels);
        self
    }

    /// The knobs for the next frame after one of `frame_ms` with `self`,
    /// under `options.target_ms` (unchanged without one). The coverage
    /// threshold never drops below `options.min_pixels`; the error may drop
    /// to 0 (exact).
    pub fn next(self, options: &CullingOptions, frame_ms: f64) -> Self {
        let Some(target) = options.target_ms.filter(|t| *t > 0.0) else {
            return Self::of(options);
        };
        let mut k = self.within(options);
        let ratio = frame_ms / target;
        if !ratio.is_finite() {
            return k;
        }
        k.calm_frames = if ratio < SLACK { k.calm_frames + 1 } else { 0 };
        if ratio > 1.0 {
            let step = ratio.clamp(RELAX, MAX_STEP);
            if k.lod_error_px < MAX_LOD_ERROR_PX {
                k.lod_error_px = (k.lod_error_px.max(0.25) * step).min(MAX_LOD_ERROR_PX);
            } else {
                let ceiling = MAX_MIN_PIXELS.max(options.min_pixels);
                k.min_pixels = (k.min_pixels.max(0.5) * step).min(ceiling);
            }
        } else if k.calm_frames >= CALM_FRAMES {
            // Far under budget, give back faster (at most halving a knob).
            let step = (SLACK / ratio.max(1e-9)).clamp(RELAX, 2.0);
            if k.min_pixels > options.min_pixels {
                k.min_pixels /= step;
                if k.min_pixels < options.min_pixels + 0.25 {
                    k.min_pixels = options.min_pixels;
                }
            } else {
                k.lod_error_px /= step;
                if k.lod_error_px < 0.1 {
                    k.lod_error_px = 0.0;
                }
            }
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame's cost on a model whose drawn triangles fall as the error and
    /// the threshold grow (roughly as measured on the 10M plant).
    fn frame_ms(k: KnobsInEffect, scale: f64) -> f64 {
        scale * (20.0 + 400.0 / (1.0 + 2.0 * k.lod_error_px) / (1.0 + 0.3 * k.min_pixels))
    }

    fn options(target: Option<f64>) -> CullingOptions {
        CullingOptions {
            lod_error_px: 1.0,
            min_pixels: 0.0,
            target_ms: target,
            ..CullingOptions::default()
        }
    }

    #[test]
    fn without_a_target_the_knobs_are_the_options() {
        let o = options(None);
        let k = KnobsInEffect {
            lod_error_px: 5.0,
            min_pixels: 9.0,
            ..KnobsInEffect::default()
        };
        assert_eq!(k.next(&o, 1e9), KnobsInEffect::of(&o));
    }

    #[test]
    fn a_budget_is_met_after_a_few_frames_with_the_least_error_that_meets_it() {
        for (target, scale) in [(100.0, 1.0), (100.0, 3.0), (50.0, 1.0), (300.0, 1.0)] {
            let o = options(Some(target));
            let mut k = KnobsInEffect::of(&o);
            let mut times = Vec::new();
            for _ in 0..60 {
                let t = frame_ms(k, scale);
                times.push(t);
                k = k.next(&o, t);
                assert!((0.0..=MAX_LOD_ERROR_PX).contains(&k.lod_error_px));
                assert!((o.min_pixels..=MAX_MIN_PIXELS).contains(&k.min_pixels));
            }
            let settled = &times[30..];
            let reachable = frame_ms(
                KnobsInEffect {
                    lod_error_px: MAX_LOD_ERROR_PX,
                    min_pixels: MAX_MIN_PIXELS,
                    ..KnobsInEffect::default()
                },
                scale,
            ) <= target;
            if reachable {
                assert!(
                    settled.iter().all(|&t| t <= target * 1.1),
                    "target {target} scale {scale}: {settled:?}"
                );
            }
            // Not more error than needed: relaxing one step would overrun.
            if k.lod_error_px > 0.0 && k.min_pixels == 0.0 {
                let finer = KnobsInEffect {
                    lod_error_px: k.lod_error_px / (RELAX * RELAX * RELAX),
                    ..k
                };
                assert!(
                    frame_ms(finer, scale) > target * SLACK,
                    "target {target} scale {scale}: settled at {k:?}, finer fits"
                );
            }
        }
    }

    #[test]
    fn time_to_spare_buys_the_exact_image() {
        let o = options(Some(1000.0));
        let mut k = KnobsInEffect {
            lod_error_px: 8.0,
            min_pixels: 20.0,
            ..KnobsInEffect::default()
        };
        for _ in 0..200 {
            k = k.next(&o, frame_ms(k, 1.0));
        }
        assert_eq!((k.lod_error_px, k.min_pixels), (0.0, 0.0));
    }

    /// Levels change cost in steps: a relaxing step that overruns must not
    /// alternate with the tightening one every other frame.
    #[test]
    fn a_step_in_cost_does_not_make_every_other_frame_late() {
        // Triangles halve per level: cost doubles each time τ halves.
        let step_cost = |k: KnobsInEffect| {
            30.0 + 400.0 / 2f64.powf(k.lod_error_px.max(0.0).log2().ceil().max(0.0) + 1.0)
        };
        let o = options(Some(200.0));
        let mut k = KnobsInEffect::of(&o);
        let mut late = 0;
        for frame in 0..200 {
            let t = step_cost(k);
            if frame >= 20 && t > 200.0 * 1.1 {
                late += 1;
            }
            k = k.next(&o, t);
        }
        assert!(late * 4 <= 180, "{late} of 180 frames late");
    }

    #[test]
    fn the_users_coverage_threshold_is_a_floor_even_above_the_ceiling() {
        let mut o = options(Some(10.0));
        o.min_pixels = 50.0;
        let mut k = KnobsInEffect::of(&o);
        for _ in 0..20 {
            k = k.next(&o, 1e6);
            assert!(k.min_pixels >= 50.0, "{k:?}");
        }
        // Raised while a budget runs: the next frame draws with it.
        o.min_pixels = 60.0;
        assert!(k.next(&o, 1.0).min_pixels >= 60.0);
        assert!(k.within(&o).min_pixels >= 60.0);
    }
}
