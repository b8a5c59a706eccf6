//! Render settings as the panels and scripts name them: occlusion culling off,
//! on or auto over the renderer's culling mode and adaptive switch.

use dmu_render::{Culling, View};
use serde::Deserialize;

/// Whether a view uses occlusion queries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Occlusion {
    /// No queries: frustum and coverage culling only (or no culling at all
    /// where the view culls nothing).
    Off,
    /// CHC queries every frame, whatever they cost.
    On,
    /// CHC queries where they save more drawing than they cost, measured per
    /// view ([`dmu_render::OcclusionDecision`]).
    Auto,
}

impl Occlusion {
    /// Every setting, in menu order.
    pub const ALL: [Self; 3] = [Self::Off, Self::On, Self::Auto];

    /// The setting `view` is in.
    pub fn of(view: &View) -> Self {
        match (view.culling, view.options.adaptive) {
            (Culling::Occlusion, true) => Self::Auto,
            (Culling::Occlusion, false) => Self::On,
            _ => Self::Off,
        }
    }

    /// Puts `view` in this setting. Off keeps a view that culls nothing as it
    /// is and turns an occlusion-culled one to frustum culling.
    pub fn apply(self, view: &mut View) {
        match self {
            Self::Off => {
                if view.culling == Culling::Occlusion {
                    view.culling = Culling::Frustum;
                }
            }
            Self::On | Self::Auto => {
                view.culling = Culling::Occlusion;
                view.options.adaptive = self == Self::Auto;
            }
        }
    }

    /// `off`, `on` or `auto`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Off => "off",
            Self::On => "on",
            Self::Auto => "auto",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn occlusion_settings_round_trip_through_the_view() {
        let camera = crate::nav::Navigator::overview(&dmu_geom::Aabb3d::new(
            glam::DVec3::ZERO,
            glam::DVec3::ONE,
        ))
        .camera();
        let mut view = View::new(camera, (4, 4), Culling::Frustum);
        assert_eq!(Occlusion::of(&view), Occlusion::Off);
        for setting in Occlusion::ALL {
            setting.apply(&mut view);
            assert_eq!(Occlusion::of(&view), setting);
        }
        Occlusion::Off.apply(&mut view);
        assert_eq!(
            view.culling,
            Culling::Frustum,
            "off after auto culls the frustum"
        );
        view.culling = Culling::None;
        Occlusion::Off.apply(&mut view);
        assert_eq!(view.culling, Culling::None);
        Occlusion::On.apply(&mut view);
        assert_eq!(
            (view.culling, view.options.adaptive),
            (Culling::Occlusion, false)
        );
    }
}
