//! Controllers through OpenXR actions: one action set (aim pose, trigger,
//! undo button, thumbstick, haptic output) per hand, suggested bindings for
//! the common interaction profiles, synced each frame while the session has
//! input focus, and haptic pulses.
//!
//! The state read each frame is a plain [`ControllerInput`], the same type a
//! script injects, so one input-handling function serves both.

use crate::error::{XrError, xr_call};
use crate::pose::Pose;

/// A hand (a subaction path: `/user/hand/left` or `/user/hand/right`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Hand {
    /// `/user/hand/left`.
    Left,
    /// `/user/hand/right`.
    Right,
}

impl Hand {
    /// Both hands, left first (the index of [`ControllerInput::hands`]).
    pub const BOTH: [Hand; 2] = [Hand::Left, Hand::Right];

    /// Its index in [`ControllerInput::hands`].
    pub fn index(self) -> usize {
        match self {
            Hand::Left => 0,
            Hand::Right => 1,
        }
    }

    /// `"left"` or `"right"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Hand::Left => "left",
            Hand::Right => "right",
        }
    }

    fn user_path(self) -> &'static str {
        match self {
            Hand::Left => openxr::USER_HAND_LEFT,
            Hand::Right => openxr::USER_HAND_RIGHT,
        }
    }
}

/// One hand's controller state for a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HandInput {
    /// The aim pose in the tracking space (its -Z is the pointing ray);
    /// `None` when the controller is not tracked (or absent).
    pub aim: Option<Pose>,
    /// Trigger (select), 0 to 1.
    pub trigger: f32,
    /// The undo button is held.
    pub undo: bool,
    /// Thumbstick (or trackpad), x right and y forward, -1 to 1.
    pub thumbstick: [f32; 2],
}

/// Both hands' state for a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ControllerInput {
    /// Left, right.
    pub hands: [HandInput; 2],
}

/// An interaction profile's suggested bindings and whether the runtime
/// accepted them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ProfileBinding {
    /// The profile's path.
    pub profile: &'static str,
    /// `None` when accepted, else the runtime's result.
    pub error: Option<String>,
}

/// dmu's actions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Act {
    Aim,
    Trigger,
    Undo,
    Thumbstick,
    Haptic,
}
use Act::{Aim, Haptic, Thumbstick, Trigger, Undo};

/// A profile's bindings: each action with its subpath under
/// `/user/hand/{left,right}`, per hand.
type Bindings = &'static [(Act, [&'static str; 2])];

/// The actions' bindings per interaction profile.
const PROFILES: &[(&str, Bindings)] = &[
    (
        "/interaction_profiles/khr/simple_controller",
        &[
            (Aim, ["input/aim/pose"; 2]),
            (Trigger, ["input/select/click"; 2]),
            (Undo, ["input/menu/click"; 2]),
            (Haptic, ["output/haptic"; 2]),
        ],
    ),
    (
        "/interaction_profiles/oculus/touch_controller",
        &[
            (Aim, ["input/aim/pose"; 2]),
            (Trigger, ["input/trigger/value"; 2]),
            (Undo, ["input/y/click", "input/b/click"]),
            (Thumbstick, ["input/thumbstick"; 2]),
            (Haptic, ["output/haptic"; 2]),
        ],
    ),
    (
        "/interaction_profiles/valve/index_controller",
        &[
            (Aim, ["input/aim/pose"; 2]),
            (Trigger, ["input/trigger/value"; 2]),
            (Undo, ["input/b/click"; 2]),
            (Thumbstick, ["input/thumbstick"; 2]),
            (Haptic, ["output/haptic"; 2]),
        ],
    ),
    (
        "/interaction_profiles/htc/vive_controller",
        &[
            (Aim, ["input/aim/pose"; 2]),
            (Trigger, ["input/trigger/value"; 2]),
            (Undo, ["input/menu/click"; 2]),
            (Thumbstick, ["input/trackpad"; 2]),
            (Haptic, ["output/haptic"; 2]),
        ],
    ),
    (
        "/interaction_profiles/microsoft/motion_controller",
        &[
            (Aim, ["input/aim/pose"; 2]),
            (Trigger, ["input/trigger/value"; 2]),
            (Undo, ["input/menu/click"; 2]),
            (Thumbstick, ["input/thumbstick"; 2]),
            (Haptic, ["output/haptic"; 2]),
        ],
    ),
];

/// The profiles dmu suggests bindings for.
pub fn suggested_profiles() -> impl Iterator<Item = &'static str> {
    PROFILES.iter().map(|(p, _)| *p)
}

/// The action set and its actions, the hands' aim spaces.
///
/// Field order is drop order: the spaces before the actions and the set.
pub(crate) struct Controllers {
    aim_spaces: [openxr::Space; 2],
    aim: openxr::Action<openxr::Posef>,
    trigger: openxr::Action<f32>,
    undo: openxr::Action<bool>,
    thumbstick: openxr::Action<openxr::Vector2f>,
    haptic: openxr::Action<openxr::Haptic>,
    set: openxr::ActionSet,
    hands: [openxr::Path; 2],
    pub(crate) bindings: Vec<ProfileBinding>,
}

impl Controllers {
    /// Creates the action set, suggests the bindings of every profile in
    /// [`PROFILES`] (a profile the runtime refuses is noted, not fatal),
    /// attaches the set to `session` and makes the aim spaces.
    pub(crate) fn new(
        instance: &openxr::Instance,
        session: &openxr::Session<openxr::Vulkan>,
    ) -> Result<Self, XrError> {
        let path = |s: &str| {
            instance
                .string_to_path(s)
                .map_err(xr_call("xrStringToPath"))
        };
        let hands = [
            path(Hand::Left.user_path())?,
            path(Hand::Right.user_path())?,
        ];
        let set = instance
            .create_action_set("dmu", "dmu review", 0)
            .map_err(xr_call("xrCreateActionSet"))?;
        let create = "xrCreateAction";
        let aim = set
            .create_action::<openxr::Posef>("aim", "Aim", &hands)
            .map_err(xr_call(create))?;
        let trigger = set
            .create_action::<f32>("trigger", "Grab (trigger)", &hands)
            .map_err(xr_call(create))?;
        let undo = set
            .create_action::<bool>("undo", "Undo", &hands)
            .map_err(xr_call(create))?;
        let thumbstick = set
            .create_action::<openxr::Vector2f>("thumbstick", "Move and turn", &hands)
            .map_err(xr_call(create))?;
        let haptic = set
            .create_action::<openxr::Haptic>("haptic", "Clash pulse", &hands)
            .map_err(xr_call(create))?;
        let mut bindings = Vec::new();
        for (profile, entries) in PROFILES {
            let mut paths = Vec::new();
            for (action, subpaths) in *entries {
                for (hand, sub) in Hand::BOTH.iter().zip(subpaths) {
                    paths.push((*action, path(&format!("{}/{sub}", hand.user_path()))?));
                }
            }
            let suggested: Vec<openxr::Binding<'_>> = paths
                .iter()
                .map(|(action, p)| match action {
                    Aim => openxr::Binding::new(&aim, *p),
                    Trigger => openxr::Binding::new(&trigger, *p),
                    Undo => openxr::Binding::new(&undo, *p),
                    Thumbstick => openxr::Binding::new(&thumbstick, *p),
                    Haptic => openxr::Binding::new(&haptic, *p),
                })
                .collect();
            let error = instance
                .suggest_interaction_profile_bindings(path(profile)?, &suggested)
                .err()
                .map(|e| format!("{e:?}"));
            bindings.push(ProfileBinding { profile, error });
        }
        session
            .attach_action_sets(&[&set])
            .map_err(xr_call("xrAttachSessionActionSets"))?;
        let space = |hand: openxr::Path| {
            aim.create_space(session, hand, openxr::Posef::IDENTITY)
                .map_err(xr_call("xrCreateActionSpace"))
        };
        let aim_spaces = [space(hands[0])?, space(hands[1])?];
        Ok(Self {
            aim_spaces,
            aim,
            trigger,
            undo,
            thumbstick,
            haptic,
            set,
            hands,
            bindings,
        })
    }

    /// Syncs the actions (`xrSyncActions`) and reads both hands, the aim
    /// poses located in `base` at `time`.
    pub(crate) fn sync(
        &self,
        session: &openxr::Session<openxr::Vulkan>,
        base: &openxr::Space,
        time: openxr::Time,
    ) -> Result<ControllerInput, XrError> {
        session
            .sync_actions(&[openxr::ActiveActionSet::new(&self.set)])
            .map_err(xr_call("xrSyncActions"))?;
        let mut input = ControllerInput::default();
        for (i, hand) in self.hands.iter().enumerate() {
            let trigger = self
                .trigger
                .state(session, *hand)
                .map_err(xr_call("xrGetActionStateFloat"))?;
            let undo = self
                .undo
                .state(session, *hand)
                .map_err(xr_call("xrGetActionStateBoolean"))?;
            let stick = self
                .thumbstick
                .state(session, *hand)
                .map_err(xr_call("xrGetActionStateVector2f"))?;
            let active = self
                .aim
                .is_active(session, *hand)
                .map_err(xr_call("xrGetActionStatePose"))?;
            let aim = if active {
                let location = self.aim_spaces[i]
                    .locate(base, time)
                    .map_err(xr_call("xrLocateSpace"))?;
                let valid = openxr::SpaceLocationFlags::POSITION_VALID
                    | openxr::SpaceLocationFlags::ORIENTATION_VALID;
                location
                    .location_flags
                    .contains(valid)
                    .then(|| Pose::from_xr(&location.pose))
            } else {
                None
            };
            input.hands[i] = HandInput {
                aim,
                trigger: if trigger.is_active {
                    trigger.current_state
                } else {
                    0.0
                },
                undo: undo.is_active && undo.current_state,
                thumbstick: if stick.is_active {
                    [stick.current_state.x, stick.current_state.y]
                } else {
                    [0.0; 2]
                },
            };
        }
        Ok(input)
    }

    /// A vibration of `hand` (`xrApplyHapticFeedback`): `duration_s`
    /// seconds at `amplitude` (0 to 1), the runtime's frequency.
    pub(crate) fn pulse(
        &self,
        session: &openxr::Session<openxr::Vulkan>,
        hand: Hand,
        duration_s: f64,
        amplitude: f32,
    ) -> Result<(), XrError> {
        let event = openxr::HapticVibration::new()
            .amplitude(amplitude.clamp(0.0, 1.0))
            .frequency(openxr::FREQUENCY_UNSPECIFIED)
            .duration(openxr::Duration::from_nanos((duration_s * 1e9) as i64));
        self.haptic
            .apply_feedback(session, self.hands[hand.index()], &event)
            .map_err(xr_call("xrApplyHapticFeedback"))
    }

    /// The interaction profile the runtime bound for `hand` (`None` while
    /// none is).
    pub(crate) fn profile(
        &self,
        instance: &openxr::Instance,
        session: &openxr::Session<openxr::Vulkan>,
        hand: Hand,
    ) -> Result<Option<String>, XrError> {
        let path = session
            .current_interaction_profile(self.hands[hand.index()])
            .map_err(xr_call("xrGetCurrentInteractionProfile"))?;
        if path == openxr::Path::NULL {
            return Ok(None);
        }
        instance
            .path_to_string(path)
            .map(Some)
            .map_err(xr_call("xrPathToString"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every profile binds every action it names for both hands, aim,
    /// trigger, undo and haptic in all of them (the thumbstick where the
    /// controller has one), each action once.
    #[test]
    fn every_profile_binds_the_actions() {
        for (profile, entries) in PROFILES {
            let names: Vec<Act> = entries.iter().map(|(a, _)| *a).collect();
            for needed in [Aim, Trigger, Undo, Haptic] {
                assert!(names.contains(&needed), "{profile} lacks {needed:?}");
            }
            let mut sorted = names.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), names.len(), "{profile} binds an action twice");
            for (action, subs) in *entries {
                for sub in subs {
                    let kind = if *action == Haptic {
                        "output/"
                    } else {
                        "input/"
                    };
                    assert!(sub.starts_with(kind), "{profile} {action:?}: {sub}");
                }
            }
        }
        assert!(suggested_profiles().any(|p| p.ends_with("khr/simple_controller")));
    }
}
