//! The one trait every culling strategy implements.

use crate::cull::Frame;
use crate::error::RenderError;
use crate::renderer::Renderer;
use crate::stats::FrameStats;
use crate::view::View;

/// A way of culling a frame: it draws the frame's rounds into its target
/// and says in [`FrameStats::culling`] what culled (a strategy that cannot
/// run on this frame hands it to frustum culling), then keeps its own
/// books once the frame's times are known.
pub(crate) trait Strategy {
    /// Culls and draws the frame.
    fn draw(&self, renderer: &mut Renderer, f: &mut Frame<'_>) -> Result<(), RenderError>;

    /// After the frame, with its stats complete but for the strategy's own.
    fn after_frame(&self, _renderer: &Renderer, _view: &mut View, _stats: &mut FrameStats) {}
}
