//! Scripts for `dmu-viewer --xr`: where the tracking space stands in the
//! model, and what the hands do, one step per submitted frame, so a VR
//! session is testable on a runtime without controllers (or with idle
//! simulated ones). The hand actions become controller input ([`Runner`]:
//! aim poses, trigger, undo button, thumbstick) fed into the same
//! input-handling function as the runtime's actions
//! ([`crate::xr_input::Interaction::handle`]).
//!
//! ```json
//! {
//!   "origin": [4509000, 5349750, 12000],
//!   "heading_deg": -90,
//!   "units_per_metre": 1000,
//!   "actions": [
//!     {"look": {"yaw_deg": 10, "frames": 10}},
//!     {"aim": [4515000, 5350000, 13500]},
//!     {"grab": {"by": [0, 0, -400], "frames": 20}},
//!     "undo",
//!     {"controller": {"hand": "left", "thumbstick": [0, 1], "frames": 10}},
//!     {"frames": 10}
//!   ]
//! }
//! ```
//!
//! `origin` is the world point of the tracking space's origin (OpenXR's local
//! space: the head as the session starts; default: the desktop viewer's
//! overview eye), `heading_deg`
//! turns the tracking space about world Z (0: the headset's forward is world
//! +Y). `aim` holds the right hand ahead of the head and points its ray at a
//! world point (the part it hits is hovered); `grab` presses the trigger
//! (grabbing the hovered part), moves the hand by a world offset (model
//! units) in equal steps, one per frame, and releases the trigger with the
//! last step: the part follows through the same drag code as the desktop's
//! `{"drag": ...}`. `undo` presses the undo button; `controller` holds one
//! hand's raw input (aim, trigger, thumbstick, undo button) for some frames.

use std::path::Path;

use anyhow::Context as _;
use dmu_geom::glam::{DQuat, DVec3};
use dmu_xr::{ControllerInput, Hand, HandInput, Placement, Pose};
use serde::Deserialize;

use crate::xr_input::{Locomotion, move_space};

/// Where a scripted hand is held before it is moved, metres in the head's
/// frame: right, down, ahead.
pub const HAND_IN_HEAD_M: DVec3 = DVec3::new(0.2, -0.3, -0.25);

/// A turn of the view about the head, in equal steps.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Look {
    /// Total turn about world Z, degrees (counter-clockwise seen from above).
    pub yaw_deg: f64,
    /// Frames it takes; at least 1.
    pub frames: u32,
}

/// A grab: the aimed part follows the hand by a world offset, then is released.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Grab {
    /// Total offset `[dx, dy, dz]`, model units.
    pub by: [f64; 3],
    /// Frames it takes; at least 1.
    pub frames: u32,
}

/// Which hand a raw controller action drives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HandName {
    /// The left hand.
    Left,
    /// The right hand (the default).
    #[default]
    Right,
}

impl HandName {
    /// The runtime's hand.
    pub fn hand(self) -> Hand {
        match self {
            Self::Left => Hand::Left,
            Self::Right => Hand::Right,
        }
    }
}

/// One hand's raw controller input, held for some frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Controller {
    /// The hand.
    #[serde(default)]
    pub hand: HandName,
    /// Point the hand's aim ray at this world point (from where the hand is
    /// held); default: keep its aim.
    #[serde(default)]
    pub aim: Option<[f64; 3]>,
    /// Trigger value, 0 to 1.
    #[serde(default)]
    pub trigger: f32,
    /// Thumbstick `[x, y]`, each -1 to 1 (left hand: walk; right hand's x:
    /// turn).
    #[serde(default)]
    pub thumbstick: [f32; 2],
    /// The undo button held.
    #[serde(default)]
    pub undo: bool,
    /// Frames it is held; at least 1.
    pub frames: u32,
}

/// One action of an XR script.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum XrAction {
    /// Turn the view.
    Look(Look),
    /// Point the right hand's ray at a world point; the first part hit is
    /// hovered (nothing when the ray misses).
    Aim([f64; 3]),
    /// Press the trigger (grabbing the hovered part), move the hand, release.
    Grab(Grab),
    /// Press and release the undo button.
    Undo,
    /// Redo it.
    Redo,
    /// Submit this many frames doing nothing else.
    Frames(u32),
    /// One hand's raw controller input for some frames.
    Controller(Controller),
}

impl XrAction {
    /// Frames the action takes: a grab's press frame and its moving
    /// frames, an undo's press and release.
    pub fn frames(&self) -> u32 {
        match self {
            Self::Look(l) => l.frames.max(1),
            Self::Grab(g) => g.frames.max(1).saturating_add(1),
            Self::Frames(n) => (*n).max(1),
            Self::Controller(c) => c.frames.max(1),
            Self::Undo => 2,
            Self::Aim(_) | Self::Redo => 1,
        }
    }

    /// Its name in reports.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Look(_) => "look",
            Self::Aim(_) => "aim",
            Self::Grab(_) => "grab",
            Self::Undo => "undo",
            Self::Redo => "redo",
            Self::Frames(_) => "frames",
            Self::Controller(_) => "controller",
        }
    }
}

/// An XR script: the placement of the tracking space and the actions.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct XrScript {
    /// World point of the tracking origin (the head at the start), model
    /// units (default: the desktop viewer's overview eye).
    #[serde(default)]
    pub origin: Option<[f64; 3]>,
    /// Heading of the tracking space, degrees about world Z.
    #[serde(default)]
    pub heading_deg: f64,
    /// Model units per metre (1000 for millimetres, the plant's unit).
    #[serde(default = "default_units_per_metre")]
    pub units_per_metre: f64,
    /// What the hand does, in order.
    #[serde(default)]
    pub actions: Vec<XrAction>,
}

impl Default for XrScript {
    fn default() -> Self {
        Self {
            origin: None,
            heading_deg: 0.0,
            units_per_metre: default_units_per_metre(),
            actions: Vec::new(),
        }
    }
}

fn default_units_per_metre() -> f64 {
    1000.0
}

/// Parses an XR script, checking every number where it enters.
pub fn parse(text: &str) -> anyhow::Result<XrScript> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let script: XrScript = serde_json::from_str(text)?;
    let world = dmu_scene::MAX_WORLD_COORDINATE;
    let in_world = |p: &[f64; 3]| dmu_geom::is_within(glam::DVec3::from_array(*p), world);
    if let Some(o) = &script.origin {
        anyhow::ensure!(
            in_world(o),
            "origin {}: coordinates must be finite and within ±{world:e}",
            dmu_geom::Short(*o)
        );
    }
    anyhow::ensure!(
        script.heading_deg.is_finite(),
        "heading_deg: {} must be finite",
        dmu_geom::Short(script.heading_deg)
    );
    anyhow::ensure!(
        script.units_per_metre.is_finite()
            && script.units_per_metre > 0.0
            && script.units_per_metre <= 1e9,
        "units_per_metre: {} must be in (0, 1e9]",
        dmu_geom::Short(script.units_per_metre)
    );
    for (i, a) in script.actions.iter().enumerate() {
        let ok = match a {
            XrAction::Look(l) => l.yaw_deg.is_finite(),
            XrAction::Aim(p) => in_world(p),
            XrAction::Grab(g) => in_world(&g.by),
            XrAction::Controller(c) => {
                c.aim.as_ref().is_none_or(in_world)
                    && (0.0..=1.0).contains(&c.trigger)
                    && c.thumbstick.iter().all(|v| (-1.0..=1.0).contains(v))
            }
            _ => true,
        };
        anyhow::ensure!(
            ok,
            "action {i} ({}): numbers must be finite and within ±{world:e} (trigger 0 to 1, thumbstick -1 to 1)",
            a.name()
        );
        let frames = match a {
            XrAction::Look(l) => l.frames,
            XrAction::Grab(g) => g.frames,
            XrAction::Frames(n) => *n,
            XrAction::Controller(c) => c.frames,
            _ => 1,
        };
        anyhow::ensure!(
            frames <= crate::script::MAX_FRAMES,
            "action {i} ({}): {frames} frames is more than the limit of {}",
            a.name(),
            crate::script::MAX_FRAMES
        );
    }
    Ok(script)
}

/// Reads and parses an XR script file.
pub fn read(path: &Path) -> anyhow::Result<XrScript> {
    let bytes = dmu_scene::read_regular_file(path)
        .with_context(|| format!("reading {}", path.display()))?;
    let text = String::from_utf8(bytes)
        .with_context(|| format!("reading {}: not UTF-8 text", path.display()))?;
    parse(&text).with_context(|| format!("parsing XR script {}", path.display()))
}

/// A script's progress: the action and its step, and the scripted hands'
/// held aim poses (a hand stays where the last action left it).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Runner {
    /// The action being run.
    pub index: usize,
    /// Its step (frame).
    pub step: u32,
    aims: [Option<Pose>; 2],
    /// Where the grabbing hand was at the press, tracking space.
    grab_start: DVec3,
    /// The heading when a look began.
    look_start_rad: f64,
}

/// What a script does in a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step<'a> {
    /// The action.
    pub action: &'a XrAction,
    /// The controller input it injects.
    pub input: ControllerInput,
    /// This is the action's last frame.
    pub last: bool,
}

impl Runner {
    /// Whether every action has run.
    pub fn done(&self, script: &XrScript) -> bool {
        self.index >= script.actions.len()
    }

    /// The frame's step of `script` (`None` when it has run), with `head`
    /// the head's pose this frame (tracking space) and `placement` the
    /// tracking space's (a `look` turns it); moves on to the next frame.
    pub fn next<'a>(
        &mut self,
        script: &'a XrScript,
        head: &Pose,
        placement: &mut Placement,
    ) -> Option<Step<'a>> {
        let action = script.actions.get(self.index)?;
        let (step, steps) = (self.step, action.frames());
        let held = |aims: &[Option<Pose>; 2], hand: Hand| {
            aims[hand.index()].map_or(head.position + head.orientation * HAND_IN_HEAD_M, |p| {
                p.position
            })
        };
        // Where a world point lies from a tracking-space position, as an
        // orientation whose -Z points there.
        let aim_at = |from: DVec3, at: &[f64; 3], placement: &Placement| {
            let to = placement
                .to_world()
                .inverse()
                .transform_point3(DVec3::from_array(*at));
            Pose {
                position: from,
                orientation: DQuat::from_rotation_arc(DVec3::NEG_Z, (to - from).normalize()),
            }
        };
        let mut input = ControllerInput::default();
        match action {
            XrAction::Look(l) => {
                if step == 0 {
                    self.look_start_rad = placement.heading_rad;
                }
                let t = f64::from(step + 1) / f64::from(steps);
                let radians = self.look_start_rad + l.yaw_deg.to_radians() * t;
                // About the tracking space's origin, which stays put.
                let about = DVec3::ZERO;
                move_space(placement, Locomotion::Heading { radians, about });
            }
            XrAction::Aim(at) => {
                let from = held(&self.aims, Hand::Right);
                self.aims[Hand::Right.index()] = Some(aim_at(from, at, placement));
            }
            XrAction::Grab(g) => {
                let right = &mut self.aims[Hand::Right.index()];
                let start = right.get_or_insert(Pose {
                    position: held(&[None; 2], Hand::Right),
                    orientation: head.orientation,
                });
                if step == 0 {
                    self.grab_start = start.position;
                } else {
                    // The world offset in the tracking space, in equal steps.
                    let by = placement
                        .to_world()
                        .inverse()
                        .transform_vector3(DVec3::from_array(g.by));
                    start.position =
                        self.grab_start + by * (f64::from(step) / f64::from(g.frames.max(1)));
                }
                input.hands[Hand::Right.index()].trigger = if step + 1 < steps { 1.0 } else { 0.0 };
            }
            XrAction::Undo => input.hands[Hand::Right.index()].undo = step == 0,
            XrAction::Controller(c) => {
                let hand = c.hand.hand();
                if let (0, Some(at)) = (step, &c.aim) {
                    self.aims[hand.index()] = Some(aim_at(held(&self.aims, hand), at, placement));
                }
                input.hands[hand.index()] = HandInput {
                    aim: None,
                    trigger: c.trigger,
                    undo: c.undo,
                    thumbstick: c.thumbstick,
                };
            }
            XrAction::Redo | XrAction::Frames(_) => {}
        }
        for hand in Hand::BOTH {
            input.hands[hand.index()].aim = self.aims[hand.index()];
        }
        let last = step + 1 >= steps;
        if last {
            self.index += 1;
            self.step = 0;
        } else {
            self.step += 1;
        }
        Some(Step {
            action,
            input,
            last,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_action_and_defaults() {
        let s = parse(
            r#"{"origin": [1, 2, 3], "heading_deg": -90, "actions": [
                {"look": {"yaw_deg": 10, "frames": 5}}, {"aim": [4, 5, 6]},
                {"grab": {"by": [0, 0, -400], "frames": 20}}, "undo", "redo", {"frames": 3}]}"#,
        )
        .unwrap();
        assert_eq!(s.origin, Some([1.0, 2.0, 3.0]));
        assert_eq!(s.units_per_metre, 1000.0);
        assert_eq!(s.actions.len(), 6);
        assert_eq!(s.actions[2].frames(), 21);
        assert_eq!(s.actions[3], XrAction::Undo);
        let frames: u32 = s.actions.iter().map(XrAction::frames).sum();
        assert_eq!(frames, 5 + 1 + 21 + 2 + 1 + 3);
        assert_eq!(parse("{}").unwrap(), XrScript::default());
    }

    #[test]
    fn rejects_bad_scripts() {
        let err = |t: &str| parse(t).unwrap_err().to_string();
        assert!(parse(r#"{"origin": [1, 2]}"#).is_err());
        assert!(err(r#"{"origin": [1e300, 2, 3]}"#).contains("origin"));
        assert!(err(r#"{"units_per_metre": 0}"#).contains("units_per_metre"));
        assert!(err(r#"{"actions": [{"aim": [1, 2, 1e16]}]}"#).contains("action 0 (aim)"));
        assert!(err(r#"{"actions": [{"frames": 4000000000}]}"#).contains("limit"));
        assert!(parse(r#"{"actions": [{"teleport": [1, 2, 3]}]}"#).is_err());
        assert!(parse(r#"{"speed": 3}"#).is_err());
        assert!(
            err(r#"{"actions": [{"controller": {"trigger": 2, "frames": 1}}]}"#)
                .contains("trigger 0 to 1")
        );
        assert!(
            parse(r#"{"actions": [{"controller": {"hand": "middle", "frames": 1}}]}"#).is_err()
        );
    }

    /// A grab injects a press at the held pose, the hand moved by the
    /// world offset in equal steps (carried into the tracking space), and a
    /// release with the last step; the aim stays on the hand throughout.
    #[test]
    fn grab_injects_press_moves_and_release() {
        let script = parse(
            r#"{"actions": [{"aim": [10, 20, 30]}, {"grab": {"by": [0, 0, -400], "frames": 4}},
                "undo", {"controller": {"hand": "left", "thumbstick": [0, 1], "frames": 2}}]}"#,
        )
        .unwrap();
        let mut placement = Placement {
            origin: DVec3::new(4.5e6, 5.3e6, 1.2e4),
            heading_rad: -1.3,
            units_per_metre: 1000.0,
        };
        let head = Pose {
            position: DVec3::new(0.1, 0.05, -0.02),
            orientation: DQuat::from_rotation_y(0.4),
        };
        let mut runner = Runner::default();
        let aim = runner.next(&script, &head, &mut placement).unwrap();
        let pose = aim.input.hands[1].aim.unwrap();
        let fixed = placement;
        let world = |p: DVec3| fixed.point(p);
        assert!(
            (pose.position - (head.position + head.orientation * HAND_IN_HEAD_M)).length() < 1e-15
        );
        // The ray points at the world point.
        let dir = placement.direction(pose.orientation * DVec3::NEG_Z);
        let want = (DVec3::new(10.0, 20.0, 30.0) - world(pose.position)).normalize();
        assert!(dir.abs_diff_eq(want, 1e-9), "{dir} vs {want}");
        let mut steps = Vec::new();
        while let Some(s) = runner.next(&script, &head, &mut placement) {
            steps.push(s);
        }
        assert_eq!(steps.len(), 5 + 2 + 2);
        let triggers: Vec<f32> = steps[..5]
            .iter()
            .map(|s| s.input.hands[1].trigger)
            .collect();
        assert_eq!(triggers, [1.0, 1.0, 1.0, 1.0, 0.0]);
        for (k, s) in steps[..5].iter().enumerate() {
            let at = world(s.input.hands[1].aim.unwrap().position) - world(pose.position);
            let want = DVec3::new(0.0, 0.0, -100.0 * k as f64);
            assert!((at - want).length() < 1e-6, "step {k}: {at}");
        }
        assert!(steps[4].last && !steps[3].last);
        let undo: Vec<bool> = steps[5..7].iter().map(|s| s.input.hands[1].undo).collect();
        assert_eq!(undo, [true, false]);
        assert_eq!(steps[8].input.hands[0].thumbstick, [0.0, 1.0]);
        assert!(runner.done(&script));
    }
}
