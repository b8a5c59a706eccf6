//! [`Culling::Auto`]: per view, whichever of frustum, chc and hzb draws its
//! frames fastest here (the timing is `crate::state::AutoState`'s).

use crate::cull::Frame;
use crate::error::RenderError;
use crate::renderer::Renderer;
use crate::settings::Culling;
use crate::stats::FrameStats;
use crate::view::View;

use super::chc::Chc;
use super::frustum::Frustum;
use super::hzb::Hzb;
use super::strategy::Strategy;

/// Runs the mode the view's `auto` state chose and times it.
pub(crate) struct Auto;

/// The strategy of a mode `auto` runs.
fn of(mode: Culling) -> &'static dyn Strategy {
    match mode {
        Culling::Hzb => &Hzb,
        Culling::Occlusion => &Chc,
        _ => &Frustum,
    }
}

impl Strategy for Auto {
    fn draw(&self, renderer: &mut Renderer, f: &mut Frame<'_>) -> Result<(), RenderError> {
        of(f.view.state.auto.mode()).draw(renderer, f)?;
        if f.stats.culling == Culling::Frustum {
            // What frustum culling drew counts as visible, so a switch
            // to chc or hzb starts from it rather than from nothing.
            let state = &mut f.view.state;
            for &e in &state.drawn {
                state.entries[e as usize].visible_frame = state.frame;
            }
        }
        Ok(())
    }

    fn after_frame(&self, renderer: &Renderer, view: &mut View, stats: &mut FrameStats) {
        let mode = view.state.auto.mode();
        of(mode).after_frame(renderer, view, stats);
        // Uploads aside: they are the model's arriving, not the mode's cost.
        view.state.auto.after_frame(stats.cpu_ms - stats.upload_ms);
        stats.auto = Some(view.state.auto.choice(mode));
    }
}
