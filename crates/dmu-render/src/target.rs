//! Where frames go: the caller's targets (a view's, a stereo pair's) and
//! the rounds' view of them.

/// Where a frame goes: a colour view (of the renderer's colour format, or
/// [`crate::ID_FORMAT`] for the oracle) and a [`crate::DEPTH_FORMAT`] view of
/// the same size.
#[derive(Clone, Copy, Debug)]
pub struct FrameTarget<'a> {
    /// Colour (or id) attachment.
    pub color: &'a wgpu::TextureView,
    /// Depth attachment.
    pub depth: &'a wgpu::TextureView,
}

/// Where a round draws: a view's target, or the layers of a stereo pair.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RoundTarget<'a> {
    /// Every layer at once: a view's target, or a stereo pair's array views.
    pub all: FrameTarget<'a>,
    /// Each eye's layer alone; empty for a single view.
    pub eyes: &'a [FrameTarget<'a>],
    /// A stereo pair's geometry goes to both layers in one multiview pass
    /// (else one pass per layer).
    pub multiview: bool,
    /// The first pass keeps the colour there (clears depth only).
    pub keep_color: bool,
}

impl<'a> RoundTarget<'a> {
    /// A single view's target.
    pub fn single(target: FrameTarget<'a>) -> Self {
        Self {
            all: target,
            eyes: &[],
            multiview: false,
            keep_color: false,
        }
    }

    /// The same target, its colour kept by the first pass ([`View::keep_color`]).
    ///
    /// [`View::keep_color`]: crate::View::keep_color
    pub fn keeping_color(self, keep_color: bool) -> Self {
        Self { keep_color, ..self }
    }

    /// A stereo pair's target, drawn with multiview or a pass per layer.
    pub fn stereo(target: &'a StereoTarget<'a>, multiview: bool) -> Self {
        Self {
            all: FrameTarget {
                color: target.color,
                depth: target.depth,
            },
            eyes: &target.eyes,
            multiview,
            keep_color: false,
        }
    }

    /// Every layer's target at once (a single view's target).
    pub fn all(&self) -> FrameTarget<'a> {
        self.all
    }

    /// True when geometry is drawn into every layer by one multiview pass,
    /// which carries no occlusion queries.
    pub fn is_multiview(&self) -> bool {
        self.multiview
    }

    /// Eyes: 1 for a single view, 2 for a stereo pair.
    pub fn eye_count(&self) -> usize {
        self.eyes.len().max(1)
    }
}

/// Where a stereo frame goes: colour and depth array views of two layers
/// (layer 0 the left eye) for the multiview pass, and each layer alone for
/// the per-eye passes (occlusion queries; everything without multiview), all
/// of the view's size.
#[derive(Clone, Copy, Debug)]
pub struct StereoTarget<'a> {
    /// Colour: a `D2Array` view of both layers, of the renderer's colour format.
    pub color: &'a wgpu::TextureView,
    /// Depth: a `D2Array` view of both layers, [`crate::DEPTH_FORMAT`].
    pub depth: &'a wgpu::TextureView,
    /// Layer 0 (left eye) and layer 1 (right eye) alone, as `D2` views.
    pub eyes: [FrameTarget<'a>; 2],
}
