//! `dmu-viewer --xr`: the review in a headset through OpenXR. The model, its
//! tree, the selection, moves, live collision and undo are the desktop's
//! ([`Review`]); each frame both eyes are drawn by `dmu-render` with the
//! runtime's eye poses and asymmetric fields of view, copied into the
//! session's 2-layer swapchain image and submitted as a projection layer.
//!
//! The hands: the runtime's controllers through OpenXR actions (synced each
//! frame while the session is focused) or, while an `--xr-script` runs, the
//! script's injected controller input; either goes through the one
//! input-handling function ([`Interaction::handle`]): aim picks
//! (`Tree::pick`, as a desktop click), the trigger grabs and drags through
//! the desktop's drag code, a hard clash pulses the controller, the undo
//! button undoes, the thumbsticks move the tracking space.
//!
//! Both eyes are culled once and drawn together (`render_stereo`) where they
//! form a parallel rig sharing a field of view (a simulated headset's do),
//! else each apart.
//!
//! Comfort: the views get a frame-time budget from the runtime's predicted
//! display period (`CullingOptions::target_ms`; half of it an eye where the
//! eyes are drawn apart), so a frame that would be late draws coarser levels
//! and drops small nodes; the report gives each frame's timing and the knobs
//! chosen. The loop reads nothing from the disk (the model is in memory; a
//! recording is written by its own thread).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use dmu_geom::Ray3d;
use dmu_geom::glam::DVec3;
use dmu_render::{
    Capture, Culling, CullingOptions, Renderer, RendererOptions, StereoCamera, StereoView, View,
};
use dmu_scene::PartId;
use dmu_viewer::command::ReviewCommand;
use dmu_viewer::nav::Navigator;
use dmu_viewer::xr_input::{CLASH_PULSE_AMPLITUDE, CLASH_PULSE_S, Event, Interaction};
use dmu_viewer::xr_script::{Runner, XrAction, XrScript};
use dmu_xr::{ControllerInput, Eye, Hand, Placement, Pose, Status, XrOptions, XrSession};
use serde::Serialize;
use serde_json::Value;

use crate::app::{Summary, clashes_json, retint, selection_json, to_value};
use dmu_viewer::review::Review;

/// How long the runtime may take to start the session (IDLE to READY).
const START_TIMEOUT: Duration = Duration::from_secs(60);
/// How long it may take to end it after the exit request.
const EXIT_TIMEOUT: Duration = Duration::from_secs(20);
/// The near plane, metres: closer than anything a hand holds up.
const NEAR_M: f64 = 0.05;
/// How far the eyes may be from a parallel rig sharing a field of view for
/// both to be drawn as one (radians of turn and field, metres off the line
/// between them): a millionth, far under a pixel.
const RIG_TOLERANCE: f64 = 1e-6;
/// The grid of image points whose world hits are reported with their
/// analytic disparity (columns, rows).
const KNOWN_POINT_GRID: (u32, u32) = (32, 24);
/// Half the side of the square around each known point whose disparity range
/// is reported (a patch an image comparison can match), pixels.
const KNOWN_POINT_PATCH_PX: f64 = 5.0;

/// The frame-time budget of the eyes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// The runtime's predicted display period (half of it an eye, where
    /// the eyes are drawn apart).
    Display,
    /// None: the LOD error and coverage threshold stay as set.
    Off,
    /// A fixed budget for both eyes together, ms.
    Fixed(f64),
}

impl Budget {
    /// `display`, `off`, or a number of milliseconds (1 to 1e6).
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "display" => Ok(Self::Display),
            "off" => Ok(Self::Off),
            _ => match s.parse::<f64>() {
                Ok(ms) if (1.0..=1e6).contains(&ms) => Ok(Self::Fixed(ms)),
                _ => Err(format!(
                    "{s:?}: give display, off, or milliseconds from 1 to 1e6"
                )),
            },
        }
    }

    /// The budget of a frame (both eyes), ms.
    fn frame_ms(self, period_ms: f64) -> Option<f64> {
        match self {
            Self::Display => (period_ms > 0.0).then_some(period_ms),
            Self::Off => None,
            Self::Fixed(ms) => Some(ms),
        }
    }

    fn as_json(self) -> Value {
        match self {
            Self::Display => Value::from("display"),
            Self::Off => Value::from("off"),
            Self::Fixed(ms) => Value::from(ms),
        }
    }
}

/// How the eyes are culled and drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Stereo {
    /// Culled once for both (`render_stereo`, one multiview pass where the
    /// driver has it) where the eyes form a parallel rig sharing a field of
    /// view, else each eye apart.
    Auto,
    /// Each eye culled and drawn apart.
    PerEye,
    /// Alternate: odd frames as `auto`, even frames per eye (both timed in
    /// one run, for the ratio).
    Compare,
}

impl Stereo {
    fn as_str(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::PerEye => "per-eye",
            Self::Compare => "compare",
        }
    }
}

/// What `--xr` was asked to do.
#[derive(Debug)]
pub struct XrArgs {
    /// Placement and hand actions.
    pub script: XrScript,
    /// Frames to submit at least (the script runs to its end in any case);
    /// `None`: until the runtime ends the session.
    pub frames: Option<u32>,
    /// Write the last frame's eyes here as `left.png` and `right.png`.
    pub save_eyes: Option<PathBuf>,
    /// Longest side of an eye's image, pixels.
    pub eye_px: u32,
    /// Culling mode of both eyes.
    pub culling: Culling,
    /// Culling knobs of both eyes.
    pub culling_options: CullingOptions,
    /// The frame-time budget.
    pub budget: Budget,
    /// Culling the eyes once or apart.
    pub stereo: Stereo,
}

/// What the session saw of the runtime's controllers.
#[derive(Debug, Default)]
struct RuntimeControllers {
    /// Frames whose actions were synced (focused).
    synced_frames: u64,
    /// Frames the runtime's input drove the hands (no script running).
    driven_frames: u64,
    profiles: [Option<String>; 2],
    /// The first aim pose the runtime located per hand.
    first_aim: [Option<Pose>; 2],
    /// The highest trigger value read per hand.
    max_trigger: [f32; 2],
}

/// The script's results and the hands' events for the report.
#[derive(Debug, Default)]
struct Log {
    steps: Vec<Value>,
    grabbed_part: Option<String>,
    grab: Option<Value>,
    haptic_pulses: Vec<Value>,
    events: Vec<Value>,
    /// The clashes the session saw at every recorded step.
    recorded_steps: Vec<RecordedStep>,
}

/// How a frame's eyes were drawn.
#[derive(Clone, Copy, Debug, Default)]
struct Drawn {
    /// Culled once for both eyes (`render_stereo`), else per eye.
    culled_once: bool,
    /// Each eye's render and GPU wait, ms (drawn per eye).
    eye_ms: Option<[f64; 2]>,
    /// Triangles drawn (both eyes: a pair's draws count once).
    triangles: u64,
    /// The LOD error and coverage threshold drawn with (the coarser eye's).
    knobs: [f64; 2],
}

/// Per-frame timing and the knobs the budget chose.
#[derive(Debug, Default)]
struct Timing {
    eye_ms: [Vec<f64>; 2],
    frame_ms: Vec<f64>,
    /// Both eyes' render and GPU wait, ms: drawn per eye, culled once.
    render_ms: [Vec<f64>; 2],
    triangles: [Vec<f64>; 2],
    frames: Vec<XrFrame>,
    late: u64,
    missed_displays: i64,
    last_display_ns: Option<i64>,
}

/// Runs the session; the report.
pub fn run(mut review: Review, args: XrArgs, facts: Value) -> anyhow::Result<Value> {
    let mut session = XrSession::new(&XrOptions {
        app_name: "dmu-viewer".into(),
        eye_px: args.eye_px,
    })
    .context("starting the OpenXR session (is a runtime running? XR_RUNTIME_JSON names it)")?;
    let size = session.eye_size();
    let device = session.device().clone();
    let queue = session.queue().clone();
    let mut renderer = Renderer::new(
        &device,
        &queue,
        &review.scene,
        &review.tree,
        RendererOptions {
            // A budget may choose simplified levels.
            lod_levels: args.culling_options.may_draw_lods() || args.budget != Budget::Off,
            ..Default::default()
        },
    );
    let capture = Capture::stereo(&device, size);
    let mut placement = placement(&review, &args.script);
    let near = NEAR_M * args.script.units_per_metre;
    let overview = Navigator::overview(&review.scene.world_bounds()).camera();
    let mut views = [0, 1].map(|_| {
        let mut v = View::new(overview, size, args.culling);
        v.options = args.culling_options;
        v
    });
    let mut pair = StereoView::new(
        StereoCamera {
            center: overview,
            ipd: 0.0,
        },
        size,
        args.culling,
    );
    pair.view.options = args.culling_options;
    let mut tints: [Vec<PartId>; 3] = Default::default();
    let mut runner = Runner::default();
    let mut hands = Interaction::default();
    let mut log = Log::default();
    let mut real = RuntimeControllers::default();
    let mut timing = Timing::default();
    let mut skipped = 0u64;
    let mut last_eyes: Option<[(dmu_geom::Camera, Eye); 2]> = None;
    let started = Instant::now();
    let target_frames = u64::from(args.frames.unwrap_or(u32::MAX));
    let exit = loop {
        match session.poll()? {
            Status::Exit => break "runtime",
            Status::Waiting => {
                anyhow::ensure!(
                    session.frames_submitted() > 0 || started.elapsed() < START_TIMEOUT,
                    "the OpenXR session did not start within {} s (state {})",
                    START_TIMEOUT.as_secs(),
                    session.state().as_str()
                );
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
            Status::Running => {}
        }
        if runner.done(&args.script) && session.frames_submitted() >= target_frames {
            break if session.finish(EXIT_TIMEOUT)? {
                "clean"
            } else {
                "timeout"
            };
        }
        let Some(frame) = session.begin_frame()? else {
            skipped += 1;
            continue;
        };
        let frame_start = Instant::now();
        let period_ms = frame.display_period_ns as f64 * 1e-6;
        let head = head_pose(&frame.eyes);
        // The runtime's controllers are synced on every focused frame; they
        // drive the hands when no script does.
        let synced = session.controllers(&frame)?;
        if let Some(input) = &synced {
            note_runtime_input(&mut real, &session, input)?;
        }
        let lines_before = recorded_lines(&review);
        let scripted = runner.next(&args.script, &head, &mut placement);
        let input = match &scripted {
            Some(step) => Some(step.input),
            None => {
                real.driven_frames += u64::from(synced.is_some());
                synced
            }
        };
        let frame_no = session.frames_submitted();
        if let Some(input) = input {
            let dt_s = if period_ms > 0.0 {
                period_ms * 1e-3
            } else {
                0.0
            };
            let events = hands.handle(&input, Some(&head), &mut placement, &mut review, dt_s);
            for event in events {
                log_event(&mut log, &session, &review, frame_no, event);
            }
        }
        if let Some(step) = &scripted {
            if matches!(step.action, XrAction::Redo) {
                hands.apply(&mut review, ReviewCommand::Redo);
            }
            if step.last {
                let mut entry = step_result(&mut log, &review, &hands, step.action);
                entry["frame"] = Value::from(frame_no);
                entry["placement"] = to_value(placement_json(&placement));
                log.steps.push(entry);
            }
        }
        if recorded_lines(&review) > lines_before {
            log.recorded_steps.push(RecordedStep {
                frame: frame_no,
                clashes: clashes_json(&review.report),
            });
        }
        let selected = review.selected.into_iter().collect();
        retint(&mut tints[0], selected, |p, on| {
            renderer.set_selected(p, on)
        });
        retint(&mut tints[1], review.clashing_parts(), |p, on| {
            renderer.set_clashing(p, on)
        });
        let hovered = hands.hover.iter().flatten().map(|h| h.part).collect();
        retint(&mut tints[2], hovered, |p, on| renderer.set_hovered(p, on));
        let cameras = frame
            .eyes
            .map(|e| (placement.eye_camera(&e.pose, &e.fov, near), e));
        let target = capture.stereo_target();
        let render_start = Instant::now();
        let rig = match args.stereo {
            Stereo::PerEye => None,
            Stereo::Auto => parallel_rig(&frame.eyes, &placement, near),
            // Culled once on odd frames, per eye on even ones.
            Stereo::Compare => {
                parallel_rig(&frame.eyes, &placement, near).filter(|_| frame_no % 2 == 1)
            }
        };
        let drawn = match rig {
            Some((stereo, fov)) => {
                pair.camera = stereo;
                pair.view.fov = Some(fov);
                pair.view.options.target_ms = args.budget.frame_ms(period_ms);
                let stats = renderer.render_stereo(
                    &mut pair,
                    &review.scene,
                    &review.tree,
                    &review.scene,
                    target,
                )?;
                device
                    .poll(wgpu::PollType::wait_indefinitely())
                    .context("waiting for the eyes' frame")?;
                Drawn {
                    culled_once: true,
                    eye_ms: None,
                    triangles: stats.triangles_drawn,
                    knobs: [stats.lod_error_px, stats.min_pixels],
                }
            }
            None => {
                let mut eye_ms = [0.0; 2];
                let mut drawn = Drawn::default();
                for (i, view) in views.iter_mut().enumerate() {
                    let start = Instant::now();
                    view.camera = cameras[i].0;
                    view.fov = Some(cameras[i].1.fov);
                    view.options.target_ms = args.budget.frame_ms(period_ms).map(|ms| 0.5 * ms);
                    let stats = renderer.render(
                        view,
                        &review.scene,
                        &review.tree,
                        &review.scene,
                        target.eyes[i],
                    )?;
                    device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .context("waiting for an eye's frame")?;
                    eye_ms[i] = start.elapsed().as_secs_f64() * 1e3;
                    drawn.triangles += stats.triangles_drawn;
                    // The coarser eye's knobs.
                    drawn.knobs[0] = drawn.knobs[0].max(stats.lod_error_px);
                    drawn.knobs[1] = drawn.knobs[1].max(stats.min_pixels);
                }
                drawn.eye_ms = Some(eye_ms);
                drawn
            }
        };
        let render_ms = render_start.elapsed().as_secs_f64() * 1e3;
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_texture(
            capture.color_texture().as_image_copy(),
            frame.image.as_image_copy(),
            wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 2,
            },
        );
        queue.submit([encoder.finish()]);
        let display_ns = frame.display_time_ns;
        session.end_frame(frame)?;
        let frame_ms = frame_start.elapsed().as_secs_f64() * 1e3;
        note_timing(
            &mut timing,
            frame_no,
            frame_ms,
            period_ms,
            display_ns,
            render_ms,
            &drawn,
        );
        last_eyes = Some(cameras);
    };
    let eyes_saved = match &args.save_eyes {
        Some(dir) => {
            save_eyes(&device, &queue, &capture, dir)?;
            Some(EyesSaved {
                left: dir.join("left.png"),
                right: dir.join("right.png"),
            })
        }
        None => None,
    };
    let recording = match review.recorder.take() {
        Some(rec) => {
            let (path, lines) = (rec.path().to_owned(), rec.lines());
            rec.finish()?;
            Some(Recording {
                path,
                lines,
                clearance: review.settings.clearance,
                steps: &log.recorded_steps,
            })
        }
        None => None,
    };
    let per_eye_and_once = |v: &[Vec<f64>; 2]| PerEyeAndOnce {
        per_eye: Summary::of(&v[0]),
        culled_once: Summary::of(&v[1]),
    };
    let known_start = Instant::now();
    let known_points = last_eyes
        .as_ref()
        .map(|eyes| known_points(&review, eyes, size));
    let known_points_ms = known_points
        .is_some()
        .then(|| known_start.elapsed().as_secs_f64() * 1e3);
    let run = XrReport {
        eyes_saved,
        recording,
        record_error: review.record_error.as_deref(),
        runtime: session.runtime(),
        adapter: &session.adapter().name,
        max_session_state: session.max_state().as_str(),
        final_state: session.state().as_str(),
        frames_submitted: session.frames_submitted(),
        frames_not_rendered: skipped,
        eye_size: size,
        recommended_eye_size: session.recommended_eye_size(),
        eye_frame_ms: EyePair {
            left: Summary::of(&timing.eye_ms[0]),
            right: Summary::of(&timing.eye_ms[1]),
        },
        frame_ms: Summary::of(&timing.frame_ms),
        render_ms: per_eye_and_once(&timing.render_ms),
        stereo: StereoFacts {
            mode: args.stereo.as_str(),
            frames_culled_once: timing.render_ms[1].len(),
            frames_per_eye: timing.render_ms[0].len(),
            multiview: renderer.stereo_mode() == dmu_render::StereoMode::Multiview,
        },
        frames_late: timing.late,
        displays_missed: timing.missed_displays,
        budget: args.budget.as_json(),
        frames: &timing.frames,
        triangles_drawn: per_eye_and_once(&timing.triangles),
        session_s: started.elapsed().as_secs_f64(),
        steps: &log.steps,
        grabbed_part: log.grabbed_part.as_deref(),
        grab: log.grab.as_ref(),
        clashes: log
            .grab
            .as_ref()
            .and_then(|g| g["clashes"].as_array().map(Vec::len)),
        haptic_pulses: &log.haptic_pulses,
        events: &log.events,
        controllers: controllers_json(&session, &real),
        after: selection_json(&review),
        placement: placement_json(&placement),
        eye_fov: last_eyes.as_ref().map(|e| [e[0].1.fov, e[1].1.fov]),
        eye_positions: (last_eyes.as_ref()).map(|e| [e[0].0.eye.to_array(), e[1].0.eye.to_array()]),
        ipd_m: (last_eyes.as_ref()).map(|e| e[0].1.pose.position.distance(e[1].1.pose.position)),
        known_points,
        known_points_ms,
        exit,
    };
    let mut report = facts;
    let Value::Object(run) = to_value(run) else {
        unreachable!("a struct serializes as an object");
    };
    for (key, value) in run {
        report[key.as_str()] = value;
    }
    Ok(report)
}

/// The eyes' images saved.
#[derive(Debug, Serialize)]
struct EyesSaved {
    left: PathBuf,
    right: PathBuf,
}

/// The session's recording: its file, lines, clearance and the clashes at
/// each step.
#[derive(Debug, Serialize)]
struct Recording<'a> {
    path: PathBuf,
    lines: u64,
    clearance: f64,
    steps: &'a [RecordedStep],
}

/// A summary per eye.
#[derive(Debug, Serialize)]
struct EyePair {
    left: Summary,
    right: Summary,
}

/// A summary of the frames drawn per eye and of those culled once.
#[derive(Debug, Serialize)]
struct PerEyeAndOnce {
    per_eye: Summary,
    culled_once: Summary,
}

/// How the eyes were drawn.
#[derive(Debug, Serialize)]
struct StereoFacts {
    mode: &'static str,
    frames_culled_once: usize,
    frames_per_eye: usize,
    multiview: bool,
}

/// The report of an `--xr` session, beside the model and load facts it
/// began with (keys absent where there is nothing to say).
#[derive(Debug, Serialize)]
struct XrReport<'a> {
    #[serde(skip_serializing_if = "Option::is_none")]
    eyes_saved: Option<EyesSaved>,
    #[serde(skip_serializing_if = "Option::is_none")]
    recording: Option<Recording<'a>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    record_error: Option<&'a str>,
    runtime: &'a str,
    adapter: &'a str,
    max_session_state: &'static str,
    final_state: &'static str,
    frames_submitted: u64,
    frames_not_rendered: u64,
    eye_size: (u32, u32),
    recommended_eye_size: (u32, u32),
    eye_frame_ms: EyePair,
    frame_ms: Summary,
    render_ms: PerEyeAndOnce,
    stereo: StereoFacts,
    frames_late: u64,
    displays_missed: i64,
    budget: Value,
    frames: &'a [XrFrame],
    triangles_drawn: PerEyeAndOnce,
    session_s: f64,
    steps: &'a [Value],
    grabbed_part: Option<&'a str>,
    grab: Option<&'a Value>,
    clashes: Option<usize>,
    haptic_pulses: &'a [Value],
    events: &'a [Value],
    controllers: Value,
    after: Value,
    placement: PlacementFacts,
    #[serde(skip_serializing_if = "Option::is_none")]
    eye_fov: Option<[dmu_geom::Fov; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    eye_positions: Option<[[f64; 3]; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    ipd_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    known_points: Option<Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    known_points_ms: Option<f64>,
    exit: &'static str,
}

/// The head in the tracking space: the eyes' midpoint, the left eye's
/// orientation.
fn head_pose(eyes: &[Eye; 2]) -> Pose {
    Pose {
        position: (eyes[0].pose.position + eyes[1].pose.position) * 0.5,
        orientation: eyes[0].pose.orientation,
    }
}

/// Lines the recording holds so far (0 when not recording).
fn recorded_lines(review: &Review) -> u64 {
    review.recorder.as_ref().map_or(0, |r| r.lines())
}

/// Notes what the runtime's controllers gave this frame.
fn note_runtime_input(
    real: &mut RuntimeControllers,
    session: &XrSession,
    input: &ControllerInput,
) -> anyhow::Result<()> {
    real.synced_frames += 1;
    if real.profiles.iter().any(Option::is_none) {
        real.profiles = session.interaction_profiles()?;
    }
    for hand in Hand::BOTH {
        let h = &input.hands[hand.index()];
        let i = hand.index();
        if real.first_aim[i].is_none() {
            real.first_aim[i] = h.aim;
        }
        real.max_trigger[i] = real.max_trigger[i].max(h.trigger);
    }
    Ok(())
}

/// The runtime's controllers in the report.
fn controllers_json(session: &XrSession, real: &RuntimeControllers) -> Value {
    let pose = |p: &Option<Pose>| {
        p.map(|p| PoseFacts {
            position: p.position.to_array(),
            orientation: p.orientation.to_array(),
        })
    };
    to_value(ControllerFacts {
        bindings: session
            .bindings()
            .iter()
            .map(|b| BindingFacts {
                profile: b.profile,
                accepted: b.error.is_none(),
                error: b.error.as_deref(),
            })
            .collect(),
        synced_frames: real.synced_frames,
        driven_frames: real.driven_frames,
        profiles: Hands {
            left: real.profiles[0].as_deref(),
            right: real.profiles[1].as_deref(),
        },
        first_aim: Hands {
            left: pose(&real.first_aim[0]),
            right: pose(&real.first_aim[1]),
        },
        max_trigger: Hands {
            left: real.max_trigger[0],
            right: real.max_trigger[1],
        },
    })
}

/// The runtime's controllers: bindings, frames synced and driven, and per
/// hand the profile, first aim pose and highest trigger.
#[derive(Debug, Serialize)]
struct ControllerFacts<'a> {
    bindings: Vec<BindingFacts<'a>>,
    synced_frames: u64,
    driven_frames: u64,
    profiles: Hands<Option<&'a str>>,
    first_aim: Hands<Option<PoseFacts>>,
    max_trigger: Hands<f32>,
}

/// An interaction profile's binding: accepted, or the runtime's error.
#[derive(Debug, Serialize)]
struct BindingFacts<'a> {
    profile: &'a str,
    accepted: bool,
    error: Option<&'a str>,
}

/// Something per hand.
#[derive(Debug, Serialize)]
struct Hands<T> {
    left: T,
    right: T,
}

/// A pose in the report.
#[derive(Debug, Serialize)]
struct PoseFacts {
    position: [f64; 3],
    orientation: [f64; 4],
}

/// A hand's event in the report (a hard clash's is its pulse).
#[derive(Debug, Serialize)]
#[serde(tag = "event", rename_all = "lowercase")]
enum HandEvent {
    Grab {
        hand: &'static str,
        part: String,
        frame: u64,
    },
    Release {
        hand: &'static str,
        part: String,
        offset: [f64; 3],
        frame: u64,
    },
    Undo {
        part: Option<String>,
        frame: u64,
    },
    Refused {
        hand: &'static str,
        reason: String,
        frame: u64,
    },
}

/// Logs a hand's event; a hard clash pulses the grabbing hand's controller.
fn log_event(log: &mut Log, session: &XrSession, review: &Review, frame: u64, event: Event) {
    let name = |p: PartId| review.scene.part_name(p).to_owned();
    let entry = match event {
        Event::Grab { hand, part } => {
            log.grabbed_part = Some(review.scene.part_path(part));
            to_value(HandEvent::Grab {
                hand: hand.as_str(),
                part: name(part),
                frame,
            })
        }
        Event::Release { hand, part, offset } => to_value(HandEvent::Release {
            hand: hand.as_str(),
            part: name(part),
            offset: offset.to_array(),
            frame,
        }),
        Event::Undo { part } => to_value(HandEvent::Undo {
            part: part.map(name),
            frame,
        }),
        Event::Refused { hand, reason } => to_value(HandEvent::Refused {
            hand: hand.as_str(),
            reason,
            frame,
        }),
        Event::HardClash { hand, part, other } => {
            let result = session.haptic_pulse(hand, CLASH_PULSE_S, CLASH_PULSE_AMPLITUDE);
            let pulse = to_value(Pulse {
                frame,
                hand: hand.as_str(),
                part: name(part),
                other: name(other),
                other_id: other.0,
                duration_s: CLASH_PULSE_S,
                amplitude: CLASH_PULSE_AMPLITUDE,
                result: result
                    .as_ref()
                    .map_or_else(|e| e.to_string(), |()| "ok".into()),
            });
            log.haptic_pulses.push(pulse.clone());
            pulse
        }
    };
    log.events.push(entry);
}

/// The result of a script action that has run its last frame.
fn step_result(log: &mut Log, review: &Review, hands: &Interaction, action: &XrAction) -> Value {
    let mut entry = match action {
        XrAction::Aim(_) => {
            let hover = hands.hover[Hand::Right.index()];
            to_value(AimFacts {
                from: hover.map(|h| h.from.to_array()),
                hit: hover.is_some(),
                part: hover.map(|h| review.scene.part_name(h.part)),
                path: hover.map(|h| review.scene.part_path(h.part)),
                distance: hover.map(|h| h.distance),
            })
        }
        XrAction::Grab(_) => {
            let mut facts = selection_json(review);
            // The tree followed every step (the desktop's invariant).
            facts["tree_valid"] = Value::from(review.tree.validate_against(&review.scene).is_ok());
            facts["cells"] = Value::from(review.tree.cell_count());
            if let Some(offset) = log
                .events
                .iter()
                .rev()
                .find(|e| e["event"] == "release")
                .map(|e| e["offset"].clone())
            {
                facts["offset"] = offset;
            }
            log.grab = Some(facts.clone());
            facts
        }
        _ => Value::Object(Default::default()),
    };
    entry["action"] = Value::from(action.name());
    entry["clashes_now"] = clashes_json(&review.report);
    entry
}

/// Where the tracking space stands.
fn placement_json(placement: &Placement) -> PlacementFacts {
    PlacementFacts {
        origin: placement.origin.to_array(),
        heading_deg: placement.heading_rad.to_degrees(),
        units_per_metre: placement.units_per_metre,
    }
}

/// Where the tracking space stands in the model.
#[derive(Debug, Serialize)]
struct PlacementFacts {
    origin: [f64; 3],
    heading_deg: f64,
    units_per_metre: f64,
}

/// A submitted frame's record.
#[derive(Debug, Serialize)]
struct XrFrame {
    frame: u64,
    frame_ms: f64,
    render_ms: f64,
    eye_ms: Option<[f64; 2]>,
    culled_once: bool,
    display_period_ms: f64,
    late: bool,
    lod_error_px: f64,
    min_pixels: f64,
    triangles: u64,
}

/// A haptic pulse sent for a hard clash.
#[derive(Debug, Serialize)]
struct Pulse {
    frame: u64,
    hand: &'static str,
    part: String,
    other: String,
    other_id: u32,
    duration_s: f64,
    amplitude: f32,
    result: String,
}

/// The clashes at a recorded step.
#[derive(Debug, Serialize)]
struct RecordedStep {
    frame: u64,
    clashes: Value,
}

/// What the right hand's aim hits.
#[derive(Debug, Serialize)]
struct AimFacts<'a> {
    from: Option<[f64; 3]>,
    hit: bool,
    part: Option<&'a str>,
    path: Option<String>,
    distance: Option<f64>,
}

/// Notes a frame's timing: late when it took longer than the display
/// period; displays missed from the gaps between predicted display times.
fn note_timing(
    t: &mut Timing,
    frame: u64,
    frame_ms: f64,
    period_ms: f64,
    display_ns: i64,
    render_ms: f64,
    drawn: &Drawn,
) {
    let late = period_ms > 0.0 && frame_ms > period_ms;
    t.late += u64::from(late);
    if let Some(last) = t.last_display_ns
        && period_ms > 0.0
    {
        let gap = (display_ns - last) as f64 * 1e-6 / period_ms;
        t.missed_displays += (gap.round() as i64 - 1).max(0);
    }
    t.last_display_ns = Some(display_ns);
    t.frame_ms.push(frame_ms);
    let mode = usize::from(drawn.culled_once);
    t.render_ms[mode].push(render_ms);
    t.triangles[mode].push(drawn.triangles as f64);
    if let Some(eye_ms) = drawn.eye_ms {
        t.eye_ms[0].push(eye_ms[0]);
        t.eye_ms[1].push(eye_ms[1]);
    }
    t.frames.push(XrFrame {
        frame,
        frame_ms,
        render_ms,
        eye_ms: drawn.eye_ms,
        culled_once: drawn.culled_once,
        display_period_ms: period_ms,
        late,
        lod_error_px: drawn.knobs[0],
        min_pixels: drawn.knobs[1],
        triangles: drawn.triangles,
    });
}

/// The eyes as a parallel stereo rig sharing one field of view (what
/// `render_stereo` culls once): the centre camera between them and the
/// distance between them in model units, with the shared field of view.
/// `None` where the eyes turn differently, have different fields of view,
/// or are not side by side along their x axis (within [`RIG_TOLERANCE`]).
fn parallel_rig(
    eyes: &[Eye; 2],
    placement: &Placement,
    near: f64,
) -> Option<(StereoCamera, dmu_geom::Fov)> {
    let [l, r] = eyes;
    let turn = l.pose.orientation.angle_between(r.pose.orientation);
    let [a, b] = [l.fov, r.fov].map(|f| [f.left, f.right, f.down, f.up]);
    let same_fov = a
        .iter()
        .zip(&b)
        .all(|(x, y)| (x - y).abs() <= RIG_TOLERANCE);
    // The right eye seen from the left one: along +x only.
    let offset = l.pose.orientation.inverse() * (r.pose.position - l.pose.position);
    let side_by_side =
        offset.x > 0.0 && offset.y.abs() <= RIG_TOLERANCE && offset.z.abs() <= RIG_TOLERANCE;
    (turn <= RIG_TOLERANCE && same_fov && side_by_side).then(|| {
        let head = Pose {
            position: (l.pose.position + r.pose.position) * 0.5,
            orientation: l.pose.orientation,
        };
        let center = placement.eye_camera(&head, &l.fov, near);
        let ipd = offset.x * placement.units_per_metre;
        (StereoCamera { center, ipd }, l.fov)
    })
}

/// The tracking space's placement: the script's, else at the desktop
/// viewer's overview eye, facing its way (OpenXR's local space has its
/// origin at the head as the session starts).
fn placement(review: &Review, script: &XrScript) -> Placement {
    let units = script.units_per_metre;
    match script.origin {
        Some(origin) => Placement {
            origin: DVec3::from_array(origin),
            heading_rad: script.heading_deg.to_radians(),
            units_per_metre: units,
        },
        None => {
            let nav = Navigator::overview(&review.scene.world_bounds());
            // Heading 0 faces world +Y; the overview's yaw is from +X.
            Placement {
                origin: nav.eye,
                heading_rad: nav.yaw - std::f64::consts::FRAC_PI_2
                    + script.heading_deg.to_radians(),
                units_per_metre: units,
            }
        }
    }
}

/// World points seen at a grid of the left eye's image points (rays from the
/// eyes' midpoint, parallel to the left eye's), with where each lands in both
/// eyes, the analytic disparity (left x minus right x, pixels) and the range
/// of disparities across a patch around it (`patch_px` either way, at every
/// pixel; a miss is the background, infinitely far: disparity 0): what the
/// saved images must show.
fn known_points(review: &Review, eyes: &[(dmu_geom::Camera, Eye); 2], size: (u32, u32)) -> Value {
    let (left, right) = (&eyes[0], &eyes[1]);
    let mid = (left.0.eye + right.0.eye) * 0.5;
    let hit_at = |x: f64, y: f64| {
        let through = dmu_xr::eye_ray(&left.0, &left.1.fov, size, x, y);
        // The headset's review holds the whole model: nothing to load.
        review.tree.pick_kept(
            &review.scene,
            &Ray3d::new(mid, through.dir),
            &review.section.planes(),
        )
    };
    let pixels = |p| {
        Some((
            dmu_xr::eye_pixel(&left.0, &left.1.fov, size, p)?,
            dmu_xr::eye_pixel(&right.0, &right.1.fov, size, p)?,
        ))
    };
    let (cols, rows) = KNOWN_POINT_GRID;
    let k = KNOWN_POINT_PATCH_PX;
    let mut points = Vec::new();
    for j in 0..rows {
        for i in 0..cols {
            let x = f64::from(size.0) * (f64::from(i) + 1.0) / f64::from(cols + 1);
            let y = f64::from(size.1) * (f64::from(j) + 1.0) / f64::from(rows + 1);
            let Some(hit) = hit_at(x, y) else {
                continue;
            };
            let Some((l, r)) = pixels(hit.point) else {
                continue;
            };
            let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
            // Every pixel of the patch: a thin pipe in front must not slip
            // between samples.
            let steps = 2 * k as i32 + 1;
            for n in 0..steps * steps {
                let dx = f64::from(n % steps) - k;
                let dy = f64::from(n / steps) - k;
                let d = hit_at(l.0 + dx, l.1 + dy)
                    .and_then(|h| pixels(h.point))
                    .map_or(0.0, |(a, b)| a.0 - b.0);
                low = low.min(d);
                high = high.max(d);
            }
            points.push(KnownPoint {
                world: hit.point.to_array(),
                distance: hit.point.distance(mid),
                part: review.scene.part_name(hit.part),
                left_px: [l.0, l.1],
                right_px: [r.0, r.1],
                disparity_px: l.0 - r.0,
                patch_px: k,
                patch_disparity_px: [low, high],
            });
        }
    }
    to_value(points)
}

/// A point of the model seen by both eyes: where, in which pixel of each,
/// and the disparity there and over its patch.
#[derive(Debug, Serialize)]
struct KnownPoint<'a> {
    world: [f64; 3],
    distance: f64,
    part: &'a str,
    left_px: [f64; 2],
    right_px: [f64; 2],
    disparity_px: f64,
    patch_px: f64,
    patch_disparity_px: [f64; 2],
}

/// Writes the capture's two layers as `left.png` and `right.png` in `dir`.
fn save_eyes(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    capture: &Capture,
    dir: &Path,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (layer, name) in ["left.png", "right.png"].iter().enumerate() {
        let image = capture.read_color_layer(device, queue, layer as u32)?;
        dmu_render::save_png(&image, &dir.join(name))?;
    }
    Ok(())
}

/// A one-line summary of the report for people (without `--json`).
pub fn summary_line(report: &Value) -> String {
    format!(
        "{}: {} frames submitted, furthest state {}, exit {}; both eyes {:.1} ms (median, culled once), {} frames late",
        report["runtime"].as_str().unwrap_or("?"),
        report["frames_submitted"],
        report["max_session_state"].as_str().unwrap_or("?"),
        report["exit"].as_str().unwrap_or("?"),
        report["render_ms"]["culled_once"]["median"]
            .as_f64()
            .unwrap_or(f64::NAN),
        report["frames_late"],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without an origin the tracking space stands under the overview eye,
    /// facing its way.
    #[test]
    fn default_placement_faces_the_overview() {
        let review = Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
        let p = placement(&review, &XrScript::default());
        let nav = Navigator::overview(&review.scene.world_bounds());
        let forward = p.direction(DVec3::NEG_Z);
        let want = DVec3::new(nav.forward().x, nav.forward().y, 0.0).normalize();
        assert!(forward.abs_diff_eq(want, 1e-12), "{forward} vs {want}");
        assert_eq!(p.point(DVec3::ZERO), nav.eye);
    }

    /// Eyes side by side with one orientation and one field of view make a
    /// parallel rig whose eyes are the eye cameras the runtime's poses give;
    /// a turned eye, another field of view or an eye off the line do not.
    #[test]
    fn parallel_rig_matches_the_eye_cameras() {
        let placement = Placement {
            origin: DVec3::new(4.5e6, 5.3e6, 1.2e4),
            heading_rad: -1.2,
            units_per_metre: 1000.0,
        };
        let orientation = dmu_geom::glam::DQuat::from_rotation_y(0.3)
            * dmu_geom::glam::DQuat::from_rotation_x(-0.2);
        let fov = dmu_geom::Fov {
            left: -0.74,
            right: 0.74,
            down: -0.78,
            up: 0.78,
        };
        let eye = |x: f64| Eye {
            pose: Pose {
                position: DVec3::new(0.1, 1.6, -0.3) + orientation * DVec3::new(x, 0.0, 0.0),
                orientation,
            },
            fov,
        };
        let eyes = [eye(-0.0315), eye(0.0315)];
        let (stereo, shared) = parallel_rig(&eyes, &placement, 50.0).expect("a parallel rig");
        assert_eq!(shared, fov);
        assert!((stereo.ipd - 63.0).abs() < 1e-9, "{}", stereo.ipd);
        for (rig, e) in stereo.eyes().iter().zip(&eyes) {
            let want = placement.eye_camera(&e.pose, &e.fov, 50.0);
            assert!(
                rig.eye.distance(want.eye) < 1e-6,
                "{} vs {}",
                rig.eye,
                want.eye
            );
            let (a, b) = (rig.target - rig.eye, want.target - want.eye);
            assert!(a.normalize().abs_diff_eq(b.normalize(), 1e-12));
            assert!(rig.up.normalize().abs_diff_eq(want.up.normalize(), 1e-12));
        }
        let mut turned = eyes;
        turned[1].pose.orientation = orientation * dmu_geom::glam::DQuat::from_rotation_y(1e-3);
        let mut other_fov = eyes;
        other_fov[1].fov.left = -0.6;
        let mut off_line = eyes;
        off_line[1].pose.position += orientation * DVec3::new(0.0, 1e-3, 0.0);
        let mut swapped = eyes;
        swapped.swap(0, 1);
        for (what, e) in [
            ("turned", turned),
            ("fov", other_fov),
            ("off the line", off_line),
            ("swapped", swapped),
        ] {
            assert!(parallel_rig(&e, &placement, 50.0).is_none(), "{what}");
        }
    }
}
