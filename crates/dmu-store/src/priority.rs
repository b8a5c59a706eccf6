//! What a load request says and how requests are ordered.

use dmu_scene::ChunkId;

/// Why a chunk is wanted, most urgent first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub enum Class {
    /// Drawn last frame and wanted again: a miss would make something vanish.
    Visible,
    /// Drawn lately, not last frame
    /// ([`crate::KEEP_VISIBLE_FRAMES`]): seen a moment ago, the
    /// likeliest to be seen again as gaps open and close with the eye's
    /// motion.
    Recent,
    /// In the view frustum but occluded or not yet tested (without a GPU: newly
    /// in view).
    InFrustum,
    /// Outside the frustum: prefetched along the predicted camera path.
    OutsideFrustum,
    /// In the frustum but below the screen-coverage threshold (a pixel).
    Subpixel,
}

/// How the load queue is ordered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum LoadOrder {
    /// By [`Class`], then by projected screen area, largest first.
    Visibility,
    /// By projected screen area alone (MMDr's cell-box area priority).
    Area,
    /// First requested, first loaded: no priority (a baseline).
    Fifo,
}

/// One chunk the renderer (or the prefetcher) wants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// The chunk (its geometry is shared by every part instancing its mesh).
    pub chunk: ChunkId,
    /// Why.
    pub class: Class,
    /// Projected screen area in square pixels (size and distance together);
    /// finite and non-negative.
    pub area_px: f32,
}

impl LoadOrder {
    /// The request's key, larger loading sooner; `arrival` counts up with every
    /// new request (earlier is smaller).
    pub(crate) fn key(self, request: &Request, arrival: u64) -> u64 {
        // Non-negative floats order as their bits.
        let area = u64::from(request.area_px.max(0.0).to_bits());
        match self {
            LoadOrder::Visibility => ((4 - request.class as u64) << 32) | area,
            LoadOrder::Area => area,
            LoadOrder::Fifo => u64::MAX - arrival,
        }
    }
}
