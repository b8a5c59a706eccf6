//! Culling strategies, one per file behind one trait
//! ([`strategy::Strategy`]), chosen here by the view's [`Culling`] mode.

mod auto;
mod chc;
mod frustum;
mod hzb;
mod strategy;

use crate::settings::Culling;

use auto::Auto;
use chc::Chc;
use frustum::{Everything, Frustum};
use hzb::Hzb;
pub(crate) use strategy::Strategy;

/// The strategy of a view's culling mode.
pub(crate) fn strategy(culling: Culling) -> &'static dyn Strategy {
    match culling {
        Culling::None => &Everything,
        Culling::Frustum => &Frustum,
        Culling::Occlusion => &Chc,
        Culling::Hzb => &Hzb,
        Culling::Auto => &Auto,
    }
}
