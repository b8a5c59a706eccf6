//! Culling without queries: frustum and coverage ([`Culling::Frustum`]), or
//! none at all ([`Culling::None`], the reference image). The frame knows its
//! draws before it draws, in one round.

use crate::cull::{Frame, add_round};
use crate::error::RenderError;
use crate::renderer::Renderer;
use crate::settings::Culling;

use super::strategy::Strategy;

/// [`Culling::Frustum`], and where another strategy cannot run.
pub(crate) struct Frustum;

/// [`Culling::None`]: every chunk instance not hidden or cut away.
pub(crate) struct Everything;

impl Strategy for Frustum {
    fn draw(&self, renderer: &mut Renderer, f: &mut Frame<'_>) -> Result<(), RenderError> {
        draw_plain(Culling::Frustum, renderer, f)
    }
}

impl Strategy for Everything {
    fn draw(&self, renderer: &mut Renderer, f: &mut Frame<'_>) -> Result<(), RenderError> {
        draw_plain(Culling::None, renderer, f)
    }
}

/// One round of the candidates `culling` finds, proxies where they fit.
fn draw_plain(culling: Culling, r: &mut Renderer, f: &mut Frame<'_>) -> Result<(), RenderError> {
    f.stats.culling = culling;
    let fit = r.frame_fit(culling, f.model.tree, f.cull, f.target);
    let plain = r.candidates(culling, &fit, f);
    f.stats.proxies_drawn = plain.nodes.len() as u64;
    let drawn = &mut f.view.state.drawn;
    drawn.extend(plain.draws.iter().map(|d| d.entry));
    for &n in &plain.nodes {
        r.proxy_drawn(&r.hierarchy, n, drawn);
    }
    f.stats.rounds = 1;
    let round = r.submit_color(f, &plain);
    r.finish_round(f.gpu, round)
        .map(|result| add_round(f.stats, &result))
}
