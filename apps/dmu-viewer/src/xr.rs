//! `dmu-viewer --xr`: the review in a headset through OpenXR. The model, its
//! tree, the selection, moves, live collision and undo are the desktop's
//! ([`Review`]); each frame both eyes are drawn by `dmu-render` with the
//! runtime's eye poses and asymmetric fields of view, copied into the
//! session's 2-layer swapchain image and submitted as a projection layer.
//!
//! The hand is scripted ([`dmu_viewer::xr_script`]): aim picks the first part
//! along its ray (`Tree::pick`, as a desktop click), grab moves the selection
//! through the same drag steps as the desktop's scripted drag, so a VR move
//! gives the desktop's tree and clashes.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use dmu_geom::Ray3d;
use dmu_geom::glam::{DQuat, DVec3};
use dmu_render::{Capture, Culling, CullingOptions, Renderer, RendererOptions, View};
use dmu_scene::PartId;
use dmu_viewer::nav::Navigator;
use dmu_viewer::xr_script::{XrAction, XrScript};
use dmu_xr::{Eye, Placement, Status, XrOptions, XrSession};
use serde_json::{Value, json};

use crate::app::{clashes_json, retint, selection_json, summary};
use dmu_viewer::review::Review;

/// How long the runtime may take to start the session (IDLE to READY).
const START_TIMEOUT: Duration = Duration::from_secs(60);
/// How long it may take to end it after the exit request.
const EXIT_TIMEOUT: Duration = Duration::from_secs(20);
/// The near plane, metres: closer than anything a hand holds up.
const NEAR_M: f64 = 0.05;
/// Where the hand is held, metres in the head's frame: right, down, ahead.
const HAND_IN_HEAD_M: DVec3 = DVec3::new(0.2, -0.3, -0.25);
/// The grid of image points whose world hits are reported with their
/// analytic disparity (columns, rows).
const KNOWN_POINT_GRID: (u32, u32) = (16, 12);
/// Half the side of the square around each known point whose disparity range
/// is reported (a patch an image comparison can match), pixels.
const KNOWN_POINT_PATCH_PX: f64 = 5.0;

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
}

/// The script's progress and what it found.
#[derive(Debug, Default)]
struct Hand {
    index: usize,
    step: u32,
    /// Extra turn of the tracking space so far (look actions), radians.
    look_rad: f64,
    look_start_rad: f64,
    results: Vec<Value>,
    grabbed_part: Option<String>,
    grab: Option<Value>,
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
            lod_levels: args.culling_options.may_draw_lods(),
            ..Default::default()
        },
    );
    let capture = Capture::stereo(&device, size);
    let placement = placement(&review, &args.script);
    let near = NEAR_M * args.script.units_per_metre;
    let overview = Navigator::overview(&review.scene.world_bounds()).camera();
    let mut views = [0, 1].map(|_| {
        let mut v = View::new(overview, size, args.culling);
        v.options = args.culling_options;
        v
    });
    let mut tints: (Vec<PartId>, Vec<PartId>) = Default::default();
    let mut hand = Hand::default();
    let mut eye_ms: [Vec<f64>; 2] = Default::default();
    let mut frame_ms = Vec::new();
    let mut triangles: [Vec<f64>; 2] = Default::default();
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
        let script_done = hand.index >= args.script.actions.len();
        if script_done && session.frames_submitted() >= target_frames {
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
        let cameras = frame.eyes.map(|e| {
            let turned = Placement {
                heading_rad: placement.heading_rad + hand.look_rad,
                ..placement
            };
            (turned.eye_camera(&e.pose, &e.fov, near), e)
        });
        step_hand(&mut hand, &args.script, &mut review, &placement, &cameras)?;
        let selected = review.selected.into_iter().collect();
        retint(&mut tints.0, selected, |p, on| renderer.set_selected(p, on));
        retint(&mut tints.1, review.clashing_parts(), |p, on| {
            renderer.set_clashing(p, on)
        });
        let target = capture.stereo_target();
        for (i, view) in views.iter_mut().enumerate() {
            let start = Instant::now();
            view.camera = cameras[i].0;
            view.fov = Some(cameras[i].1.fov);
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
            eye_ms[i].push(start.elapsed().as_secs_f64() * 1e3);
            triangles[i].push(stats.triangles_drawn as f64);
        }
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
        session.end_frame(frame)?;
        frame_ms.push(frame_start.elapsed().as_secs_f64() * 1e3);
        last_eyes = Some(cameras);
    };
    let mut report = facts;
    if let Some(dir) = &args.save_eyes {
        save_eyes(&device, &queue, &capture, dir)?;
        report["eyes_saved"] = json!({
            "left": dir.join("left.png"),
            "right": dir.join("right.png"),
        });
    }
    report["runtime"] = json!(session.runtime());
    report["adapter"] = json!(session.adapter().name);
    report["max_session_state"] = json!(session.max_state().as_str());
    report["final_state"] = json!(session.state().as_str());
    report["frames_submitted"] = json!(session.frames_submitted());
    report["frames_not_rendered"] = json!(skipped);
    report["eye_size"] = json!(size);
    report["recommended_eye_size"] = json!(session.recommended_eye_size());
    report["eye_frame_ms"] = json!({ "left": summary(&eye_ms[0]), "right": summary(&eye_ms[1]) });
    report["frame_ms"] = summary(&frame_ms);
    report["triangles_drawn"] =
        json!({ "left": summary(&triangles[0]), "right": summary(&triangles[1]) });
    report["session_s"] = json!(started.elapsed().as_secs_f64());
    report["steps"] = json!(hand.results);
    report["grabbed_part"] = json!(hand.grabbed_part);
    report["grab"] = json!(hand.grab);
    report["clashes"] = json!(
        hand.grab
            .as_ref()
            .and_then(|g| g["clashes"].as_array().map(Vec::len))
    );
    report["after"] = selection_json(&review);
    report["placement"] = json!({
        "origin": placement.origin.to_array(),
        "heading_deg": placement.heading_rad.to_degrees(),
        "units_per_metre": placement.units_per_metre,
    });
    if let Some(eyes) = &last_eyes {
        report["eye_fov"] = json!(eyes.map(|(_, e)| e.fov));
        report["eye_positions"] = json!(eyes.map(|(c, _)| c.eye.to_array()));
        report["ipd_m"] = json!(eyes[0].1.pose.position.distance(eyes[1].1.pose.position));
        let start = Instant::now();
        report["known_points"] = known_points(&review, eyes, size);
        report["known_points_ms"] = json!(start.elapsed().as_secs_f64() * 1e3);
    }
    report["exit"] = json!(exit);
    Ok(report)
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

/// One step of the script on this frame's eyes.
fn step_hand(
    hand: &mut Hand,
    script: &XrScript,
    review: &mut Review,
    placement: &Placement,
    cameras: &[(dmu_geom::Camera, Eye); 2],
) -> anyhow::Result<()> {
    let Some(action) = script.actions.get(hand.index) else {
        return Ok(());
    };
    let step = hand.step;
    let steps = action.frames();
    let mut result = None;
    match action {
        XrAction::Look(l) => {
            if step == 0 {
                hand.look_start_rad = hand.look_rad;
            }
            let t = f64::from(step + 1) / f64::from(steps);
            hand.look_rad = hand.look_start_rad + l.yaw_deg.to_radians() * t;
        }
        XrAction::Aim(at) => {
            let from = hand_position(placement, hand.look_rad, cameras);
            let ray = Ray3d::new(from, DVec3::from_array(*at) - from);
            let hit = review.pick(&ray);
            review.select(hit.as_ref().map(|h| h.part));
            hand.grabbed_part = hit.as_ref().map(|h| review.scene.part_path(h.part));
            result = Some(json!({
                "from": from.to_array(),
                "hit": hit.is_some(),
                "part": hit.as_ref().map(|h| review.scene.part_name(h.part)),
                "path": hand.grabbed_part,
                "distance": hit.as_ref().map(|h| h.t * ray.dir.length()),
            }));
        }
        XrAction::Grab(g) => {
            // The desktop's scripted drag, step for step.
            if step == 0 {
                anyhow::ensure!(review.begin_drag(), "grab: the hand aims at no part");
            }
            let t = f64::from(step + 1) / f64::from(steps);
            review.drag_to(DVec3::from_array(g.by) * t);
            if step + 1 == steps {
                review.end_drag();
                let mut facts = selection_json(review);
                // The tree followed every step (the desktop's invariant).
                facts["tree_valid"] = json!(review.tree.validate_against(&review.scene).is_ok());
                facts["cells"] = json!(review.tree.cell_count());
                hand.grab = Some(facts.clone());
                result = Some(facts);
            }
        }
        XrAction::Undo => {
            result = Some(json!({ "part_id": review.undo().map(|p| p.0) }));
        }
        XrAction::Redo => {
            result = Some(json!({ "part_id": review.redo().map(|p| p.0) }));
        }
        XrAction::Frames(_) => {}
    }
    if step + 1 >= steps {
        let mut entry = result.unwrap_or_else(|| json!({}));
        entry["action"] = json!(action.name());
        entry["clashes_now"] = clashes_json(&review.report);
        hand.results.push(entry);
        hand.index += 1;
        hand.step = 0;
    } else {
        hand.step += 1;
    }
    Ok(())
}

/// The hand in the world: held in front of the head (the eyes' midpoint),
/// turned with the view.
fn hand_position(
    placement: &Placement,
    look_rad: f64,
    cameras: &[(dmu_geom::Camera, Eye); 2],
) -> DVec3 {
    let head = (cameras[0].1.pose.position + cameras[1].1.pose.position) * 0.5;
    let orientation: DQuat = cameras[0].1.pose.orientation;
    let turned = Placement {
        heading_rad: placement.heading_rad + look_rad,
        ..*placement
    };
    turned.point(head + orientation * HAND_IN_HEAD_M)
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
        review.pick(&Ray3d::new(mid, through.dir))
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
            points.push(json!({
                "world": hit.point.to_array(),
                "distance": hit.point.distance(mid),
                "part": review.scene.part_name(hit.part),
                "left_px": [l.0, l.1],
                "right_px": [r.0, r.1],
                "disparity_px": l.0 - r.0,
                "patch_px": k,
                "patch_disparity_px": [low, high],
            }));
        }
    }
    json!(points)
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
        "{}: {} frames submitted, furthest state {}, exit {}; eye frame {:.1} ms (median, left)",
        report["runtime"].as_str().unwrap_or("?"),
        report["frames_submitted"],
        report["max_session_state"].as_str().unwrap_or("?"),
        report["exit"].as_str().unwrap_or("?"),
        report["eye_frame_ms"]["left"]["median"]
            .as_f64()
            .unwrap_or(f64::NAN),
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
}
