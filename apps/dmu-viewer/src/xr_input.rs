//! The hands of a VR review: one function ([`Interaction::handle`]) turns a
//! frame's controller state ([`dmu_xr::ControllerInput`], from the runtime's
//! actions or injected by an XR script) into the review's edits.
//!
//! - Each hand's aim ray picks the first part it hits (`Tree::pick`, as a
//!   desktop click): that part is hovered (highlighted, named in the report).
//! - The trigger pressed over a hovered part selects it and grabs it: every
//!   frame while held, the part follows the hand's world displacement since
//!   the press through the desktop's drag commands (`ReviewCommand::BeginDrag`,
//!   `DragTo`, `EndDrag`, applied by `command::apply` as the desktop's), so
//!   the tree is updated and collision checked at each step; the trigger
//!   released ends the drag (one undoable edit).
//! - When the grabbed part enters a hard clash, the grabbing hand gets one
//!   haptic pulse (again only after it has left the hard clash).
//! - The undo button (either hand) undoes the last edit.
//! - Locomotion: the left thumbstick moves the tracking space over the
//!   floor (along where the head faces), the right thumbstick's x turns it
//!   about the head; each is a [`Locomotion`] applied by [`move_space`], as
//!   an XR script's `look` is.
//!
//! Buttons act on their edges (pressed this frame, not the last), so a held
//! button acts once.

use dmu_collide::ClashKind;
use dmu_geom::Ray3d;
use dmu_geom::glam::DVec3;
use dmu_scene::PartId;
use dmu_xr::{ControllerInput, Hand, Placement, Pose};

use crate::command::{Outcome, ReviewCommand, apply};
use crate::review::Review;
use crate::tools::Tools;

/// The trigger counts as pressed from this value on, released below
/// [`TRIGGER_RELEASE`] (a little hysteresis against a trigger resting near
/// the threshold).
pub const TRIGGER_PRESS: f32 = 0.55;
/// See [`TRIGGER_PRESS`].
pub const TRIGGER_RELEASE: f32 = 0.45;
/// Thumbstick deflections below this are ignored (a resting stick drifts).
pub const STICK_DEAD_ZONE: f32 = 0.15;
/// Walking speed at full deflection, metres per second.
pub const MOVE_M_PER_S: f64 = 2.0;
/// Turning speed at full deflection, degrees per second.
pub const TURN_DEG_PER_S: f64 = 90.0;
/// The haptic pulse on a hard clash: seconds and amplitude.
pub const CLASH_PULSE_S: f64 = 0.1;
/// See [`CLASH_PULSE_S`].
pub const CLASH_PULSE_AMPLITUDE: f32 = 0.8;

/// A part under a hand's aim ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hover {
    /// The part.
    pub part: PartId,
    /// Distance along the ray from the hand, model units.
    pub distance: f64,
    /// The ray's origin (the hand), world.
    pub from: DVec3,
}

/// A grab in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Grab {
    hand: Hand,
    part: PartId,
    /// Where the hand was in the world when the trigger was pressed.
    start: DVec3,
    /// The offset of the last drag step, world.
    offset: DVec3,
}

/// What happened in a frame, for the report and the runtime.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// The trigger grabbed a part.
    Grab {
        /// The hand.
        hand: Hand,
        /// The part.
        part: PartId,
    },
    /// The trigger released it, `offset` (world) from where it was grabbed.
    Release {
        /// The hand.
        hand: Hand,
        /// The part.
        part: PartId,
        /// Its last drag offset, world units.
        offset: DVec3,
    },
    /// The grabbed part entered a hard clash with `other`: pulse `hand`.
    HardClash {
        /// The grabbing hand (to pulse).
        hand: Hand,
        /// The grabbed part.
        part: PartId,
        /// What it clashes with.
        other: PartId,
    },
    /// The grabbed part did not follow the hand: the step would have taken
    /// it out of the world (the reason says where).
    Refused {
        /// The grabbing hand.
        hand: Hand,
        /// Why, in one line.
        reason: String,
    },
    /// The undo button undid an edit of `part` (`None`: nothing to undo).
    Undo {
        /// The part the undo moved.
        part: Option<PartId>,
    },
}

/// The hands' state between frames.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Interaction {
    /// What each hand's ray hits this frame (left, right); a grabbing hand
    /// keeps the part it grabbed.
    pub hover: [Option<Hover>; 2],
    grab: Option<Grab>,
    trigger_down: [bool; 2],
    undo_down: [bool; 2],
    in_hard_clash: bool,
    /// The tools the hands' commands are applied with.
    tools: Tools,
}

impl Interaction {
    /// The hand holding a part, and the part.
    pub fn grabbing(&self) -> Option<(Hand, PartId)> {
        self.grab.map(|g| (g.hand, g.part))
    }

    /// Applies a command of the hands or an XR script that cannot fail
    /// (selection, drag start and end, undo, redo): through the one apply,
    /// as the desktop's.
    pub fn apply(&mut self, review: &mut Review, command: ReviewCommand) -> Outcome {
        apply(review, &mut self.tools, command)
            .expect("selection, drags, undo and redo do not fail")
    }

    /// One frame of input: locomotion (moves `placement`), the grabbing
    /// hand's drag step, the aim rays' hover, then the trigger and undo
    /// edges. `head` is the head's pose in the tracking space (for
    /// locomotion; `None`: no locomotion this frame), `dt_s` the frame's
    /// time step, seconds. Returns what happened.
    pub fn handle(
        &mut self,
        input: &ControllerInput,
        head: Option<&Pose>,
        placement: &mut Placement,
        review: &mut Review,
        dt_s: f64,
    ) -> Vec<Event> {
        let mut events = Vec::new();
        if let Some(head) = head {
            locomote(input, head, placement, dt_s);
        }
        let aim_ray = |hand: Hand| {
            input.hands[hand.index()].aim.map(|aim| {
                let from = placement.point(aim.position);
                Ray3d::new(from, placement.direction(aim.orientation * DVec3::NEG_Z))
            })
        };
        // The grabbed part follows the hand (the desktop's drag step).
        if let Some(grab) = &mut self.grab
            && let Some(ray) = aim_ray(grab.hand)
        {
            grab.offset = ray.origin - grab.start;
            if let Err(e) = apply(review, &mut self.tools, ReviewCommand::DragTo(grab.offset)) {
                events.push(Event::Refused {
                    hand: grab.hand,
                    reason: format!("{e:#}"),
                });
            }
            let hard = review
                .report
                .clashes
                .iter()
                .find(|c| c.kind == ClashKind::Hard && (c.a == grab.part || c.b == grab.part));
            if let Some(c) = hard
                && !self.in_hard_clash
            {
                events.push(Event::HardClash {
                    hand: grab.hand,
                    part: grab.part,
                    other: if c.a == grab.part { c.b } else { c.a },
                });
            }
            self.in_hard_clash = hard.is_some();
        }
        for hand in Hand::BOTH {
            let i = hand.index();
            if self.grab.is_some_and(|g| g.hand == hand) {
                continue;
            }
            self.hover[i] = aim_ray(hand).and_then(|ray| {
                review.pick(&ray).map(|hit| Hover {
                    part: hit.part,
                    distance: hit.t * ray.dir.length(),
                    from: ray.origin,
                })
            });
        }
        for hand in Hand::BOTH {
            let i = hand.index();
            let state = &input.hands[i];
            let was = self.trigger_down[i];
            let down = if was {
                state.trigger >= TRIGGER_RELEASE
            } else {
                state.trigger >= TRIGGER_PRESS
            };
            self.trigger_down[i] = down;
            match self.grab {
                Some(g) if g.hand == hand && was && !down => {
                    self.apply(review, ReviewCommand::EndDrag);
                    self.grab = None;
                    self.in_hard_clash = false;
                    events.push(Event::Release {
                        hand,
                        part: g.part,
                        offset: g.offset,
                    });
                }
                None if down && !was => {
                    let hover = self.hover[i];
                    self.apply(review, ReviewCommand::Select(hover.map(|h| h.part)));
                    if let (Some(h), Some(ray)) = (hover, aim_ray(hand))
                        && self.apply(review, ReviewCommand::BeginDrag) == Outcome::Acted(true)
                    {
                        self.grab = Some(Grab {
                            hand,
                            part: h.part,
                            start: ray.origin,
                            offset: DVec3::ZERO,
                        });
                        self.in_hard_clash = false;
                        events.push(Event::Grab { hand, part: h.part });
                    }
                }
                _ => {}
            }
            let undo_was = self.undo_down[i];
            self.undo_down[i] = state.undo;
            if state.undo && !undo_was {
                // An undo ends a grab in progress first (as the desktop's).
                if let Some(g) = self.grab.take() {
                    events.push(Event::Release {
                        hand: g.hand,
                        part: g.part,
                        offset: g.offset,
                    });
                    self.in_hard_clash = false;
                }
                let part = match self.apply(review, ReviewCommand::Undo) {
                    Outcome::Part(part) => part,
                    _ => None,
                };
                events.push(Event::Undo { part });
            }
        }
        events
    }
}

/// A thumbstick's deflection with the dead zone removed (0 inside it,
/// rising from 0 at its edge to 1 at full deflection), per axis.
fn deflection(v: f32) -> f64 {
    let a = f64::from(v.abs().min(1.0));
    let dz = f64::from(STICK_DEAD_ZONE);
    if a <= dz {
        0.0
    } else {
        f64::from(v.signum()) * (a - dz) / (1.0 - dz)
    }
}

/// A move of the tracking space over the world: what the thumbsticks and
/// an XR script's `look` emit, applied by [`move_space`] alone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Locomotion {
    /// Slides the space by a world offset.
    Slide(DVec3),
    /// Turns the space to a heading about Z, radians, keeping the
    /// tracking-space point `about` where it is in the world.
    Heading {
        /// The new heading.
        radians: f64,
        /// The tracking-space point that stays put.
        about: DVec3,
    },
}

/// Applies a [`Locomotion`] to the tracking space's placement.
pub fn move_space(placement: &mut Placement, command: Locomotion) {
    match command {
        Locomotion::Slide(by) => placement.origin += by,
        Locomotion::Heading { radians, about } => {
            let before = placement.point(about);
            placement.heading_rad = radians;
            placement.origin += before - placement.point(about);
        }
    }
}

/// Moves the tracking space: the left stick walks over the floor (y along
/// the head's horizontal forward, x to its right), the right stick's x
/// turns about the head (right: clockwise seen from above).
fn locomote(input: &ControllerInput, head: &Pose, placement: &mut Placement, dt_s: f64) {
    let dt = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
    let [mx, my] = input.hands[Hand::Left.index()].thumbstick.map(deflection);
    if mx != 0.0 || my != 0.0 {
        let flat = |v: DVec3| {
            let w = placement.direction(head.orientation * v);
            DVec3::new(w.x, w.y, 0.0).normalize_or_zero()
        };
        let step = (flat(DVec3::NEG_Z) * my + flat(DVec3::X) * mx)
            * (MOVE_M_PER_S * dt * placement.units_per_metre);
        move_space(placement, Locomotion::Slide(step));
    }
    let turn = deflection(input.hands[Hand::Right.index()].thumbstick[0]);
    if turn != 0.0 {
        let radians = placement.heading_rad - (TURN_DEG_PER_S * dt).to_radians() * turn;
        let about = head.position;
        move_space(placement, Locomotion::Heading { radians, about });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmu_geom::glam::DQuat;
    use dmu_xr::HandInput;

    /// A 2x2x1 grid of 10-unit boxes 4 apart, seen from a tracking space at
    /// the origin with 1 model unit per metre (heading 0: forward is +Y).
    fn setup() -> (Review, Placement) {
        let review = Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
        let placement = Placement {
            origin: DVec3::new(5.0, -30.0, 5.0),
            heading_rad: 0.0,
            units_per_metre: 1.0,
        };
        (review, placement)
    }

    /// A right hand at tracking position `at` aiming at world point `target`.
    fn aiming(placement: &Placement, at: DVec3, target: DVec3, trigger: f32) -> ControllerInput {
        let inv = placement.to_world().inverse();
        let dir = (inv.transform_point3(target) - at).normalize();
        let mut input = ControllerInput::default();
        input.hands[1] = HandInput {
            aim: Some(Pose {
                position: at,
                orientation: DQuat::from_rotation_arc(DVec3::NEG_Z, dir),
            }),
            trigger,
            ..HandInput::default()
        };
        input
    }

    /// Aim, press, move the hand, release: the part moves by the hand's
    /// world displacement (the tracking-space move carried into the world),
    /// one undoable edit; the tree stays valid; a hard clash pulses once.
    #[test]
    fn aim_grab_move_release_and_pulse_once() {
        let (mut review, mut placement) = setup();
        let target = review.scene.find_part("box_0_0_0").unwrap();
        let centre = review.scene.part_world_bounds(target).center();
        let mut hands = Interaction::default();
        let at = DVec3::new(0.0, 0.0, 0.0);
        let frame = |hands: &mut Interaction, review: &mut Review, p: &mut Placement, at, t| {
            let input = aiming(p, at, centre, t);
            hands.handle(&input, None, p, review, 0.01)
        };
        assert!(frame(&mut hands, &mut review, &mut placement, at, 0.0).is_empty());
        assert_eq!(hands.hover[1].map(|h| h.part), Some(target));
        let start = review.scene.part_world(target);
        let events = frame(&mut hands, &mut review, &mut placement, at, 1.0);
        assert_eq!(
            events,
            [Event::Grab {
                hand: Hand::Right,
                part: target
            }]
        );
        // Tracking +X is world +X with heading 0: towards box_1_0_0, 4 away.
        let mut pulses = 0;
        for k in 1..=10 {
            let at = DVec3::new(0.8 * f64::from(k), 0.0, 0.0);
            let events = frame(&mut hands, &mut review, &mut placement, at, 1.0);
            pulses += events
                .iter()
                .filter(|e| matches!(e, Event::HardClash { .. }))
                .count();
            let moved = review.scene.part_world(target).translation - start.translation;
            assert!(
                (moved - at).length() < 1e-12,
                "step {k}: moved {moved}, hand {at}"
            );
            assert!(review.tree.validate_against(&review.scene).is_ok());
        }
        assert_eq!(pulses, 1, "one pulse when the box enters its neighbour");
        let events = frame(&mut hands, &mut review, &mut placement, DVec3::X * 8.0, 0.0);
        assert!(matches!(events[..], [Event::Release { offset, .. }] if offset == DVec3::X * 8.0));
        assert_eq!(review.history(), (1, 0));
        // The undo button puts it back, bit for bit, once per press.
        let mut input = ControllerInput::default();
        input.hands[0].undo = true;
        for _ in 0..3 {
            hands.handle(&input, None, &mut placement, &mut review, 0.01);
        }
        assert_eq!(review.scene.part_world(target), start);
        assert_eq!(review.history(), (0, 1));
    }

    /// A trigger pressed over nothing selects nothing and grabs nothing; a
    /// trigger hovering between the thresholds neither presses nor releases.
    #[test]
    fn trigger_hysteresis_and_empty_press() {
        let (mut review, mut placement) = setup();
        let mut hands = Interaction::default();
        let away = DVec3::new(0.0, -1000.0, 0.0);
        let input = aiming(&placement, DVec3::ZERO, away, 1.0);
        assert!(
            hands
                .handle(&input, None, &mut placement, &mut review, 0.01)
                .is_empty()
        );
        assert_eq!(review.selected, None);
        let part = review.scene.find_part("box_0_0_0").unwrap();
        let centre = review.scene.part_world_bounds(part).center();
        let mut hands = Interaction::default();
        for (t, grabbing) in [(0.5, false), (0.6, true), (0.5, true), (0.4, false)] {
            let input = aiming(&placement, DVec3::ZERO, centre, t);
            hands.handle(&input, None, &mut placement, &mut review, 0.01);
            assert_eq!(hands.grabbing().is_some(), grabbing, "trigger {t}");
        }
    }

    /// A slide moves the origin by its offset; a heading keeps its `about`
    /// point where it was in the world (about the tracking space's origin,
    /// as a script's `look` turns, the origin stays bit for bit).
    #[test]
    fn move_space_slides_and_turns_about_a_point() {
        let (_, mut placement) = setup();
        let (start, by) = (placement, DVec3::new(1.0, 2.0, 0.0));
        move_space(&mut placement, Locomotion::Slide(by));
        assert_eq!(placement.origin, start.origin + by);
        let about = DVec3::new(0.3, 1.6, -0.2);
        let fixed = placement.point(about);
        move_space(
            &mut placement,
            Locomotion::Heading {
                radians: 1.0,
                about,
            },
        );
        assert_eq!(placement.heading_rad, 1.0);
        assert!((placement.point(about) - fixed).length() < 1e-12);
        let origin = placement.origin;
        let about = DVec3::ZERO;
        move_space(
            &mut placement,
            Locomotion::Heading {
                radians: -0.5,
                about,
            },
        );
        assert_eq!((placement.origin, placement.heading_rad), (origin, -0.5));
    }

    /// Locomotion: full forward for 1 s walks MOVE_M_PER_S metres along the
    /// head's horizontal forward; a full right turn for 1 s turns
    /// TURN_DEG_PER_S clockwise about the head, which stays where it was.
    #[test]
    fn thumbsticks_walk_and_turn_about_the_head() {
        let (_, mut placement) = setup();
        placement.units_per_metre = 1000.0;
        // The head looks 30 degrees left of forward and down a little.
        let head = Pose {
            position: DVec3::new(0.3, 1.6, -0.2),
            orientation: DQuat::from_rotation_y(30f64.to_radians()) * DQuat::from_rotation_x(-0.3),
        };
        let mut input = ControllerInput::default();
        input.hands[0].thumbstick = [0.0, 1.0];
        let before = placement;
        for _ in 0..100 {
            locomote(&input, &head, &mut placement, 0.01);
        }
        let walked = placement.origin - before.origin;
        let a = 30f64.to_radians();
        let want = DVec3::new(-a.sin(), a.cos(), 0.0) * 2000.0;
        assert!((walked - want).length() < 1e-6, "{walked} vs {want}");
        let mut input = ControllerInput::default();
        input.hands[1].thumbstick = [1.0, 0.0];
        let (head_world, heading) = (placement.point(head.position), placement.heading_rad);
        for _ in 0..100 {
            locomote(&input, &head, &mut placement, 0.01);
        }
        assert!((placement.point(head.position) - head_world).length() < 1e-6);
        let turned = (heading - placement.heading_rad).to_degrees();
        assert!((turned - TURN_DEG_PER_S).abs() < 1e-9, "{turned}");
        // Inside the dead zone nothing moves.
        let mut input = ControllerInput::default();
        input.hands[0].thumbstick = [0.1, -0.14];
        let still = placement;
        locomote(&input, &head, &mut placement, 1.0);
        assert_eq!(placement, still);
    }
}
