//! The stereo pair's knob: how a headset-like pair is drawn for less than two
//! eyes (`dmu render --stereo --shared-far-px`, `--reproject`), each way
//! timed against the pair drawn in full and its right eye compared with the
//! full pair's.

use dmu_render::{Culling, CullingOptions, Renderer};
use dmu_scene::Scene;
use dmu_tree::Tree;
use serde_json::Value;

use super::{Bench, Knob, Point};
use crate::stereo_far::{Setup, Variants, compare, eye_fovs};

/// The ways measured, after the pair in full: the far part shared within
/// each error (pixels), then the right eye reprojected.
const SHARED_FAR_PX: [f64; 2] = [0.5, 2.0];

/// Eye separation, model units (millimetres on the built-in plant).
const IPD: f64 = 65.0;

/// Steps of the progress bar this knob takes (a comparison per shared-far
/// error; the reprojection rides on the last).
pub fn steps() -> u64 {
    SHARED_FAR_PX.len() as u64
}

/// The stereo pair knob, on `renderer` (made for `scene` and `tree`), from the
/// first camera of the rendering path.
pub fn knob(
    bench: &Bench<'_>,
    renderer: &mut Renderer,
    device: &dmu_render::wgpu::Device,
    queue: &dmu_render::wgpu::Queue,
    scene: &Scene,
    tree: &Tree,
) -> anyhow::Result<Knob> {
    let center = super::render::path(tree, bench.scale.render_frames)[0];
    let width = bench.scale.render_size.0;
    let setup = Setup {
        center,
        ipd: IPD,
        fovs: eye_fovs(&[-52.0, 43.0, -50.0, 48.0])?,
        size: (width, width),
        culling: Culling::Frustum,
        options: CullingOptions::default(),
        frames: bench.scale.render_frames as u32,
        scene,
        tree,
    };
    let outputs = |name: &str| {
        [
            bench.scratch.join(format!("stereo-{name}-left.png")),
            bench.scratch.join(format!("stereo-{name}-right.png")),
        ]
    };
    // The right eye's pixels off by more than 8 levels from the full pair's.
    let off = |v: &Value| {
        100.0
            * v["image_difference"]["fraction_over_8_levels"][1]
                .as_f64()
                .unwrap_or(f64::NAN)
    };
    let ms = |v: &Value, key: &str| v[key].as_f64().unwrap_or(f64::NAN);
    let mut points = Vec::new();
    for (i, &error_px) in SHARED_FAR_PX.iter().enumerate() {
        let variants = Variants {
            shared_far: Some((error_px, outputs(&format!("shared-{error_px}")))),
            reprojected: (i + 1 == SHARED_FAR_PX.len()).then(|| outputs("reprojected")),
        };
        let report = compare(renderer, device, queue, &setup, &variants)?;
        let shared = &report["shared_far"];
        if i == 0 {
            points.push(
                Point::new(0.0, ms(shared, "true_stereo_frame_ms"), 0.0, "%")
                    .label("pair in full")
                    .extra("× one eye", ms(shared, "true_stereo_ratio")),
            );
        }
        points.push(
            Point::new(
                points.len() as f64,
                ms(shared, "frame_ms"),
                off(shared),
                "%",
            )
            .label(&format!("far part shared within {error_px} px"))
            .extra("× one eye", ms(shared, "ratio"))
            .extra(
                "disparity error bound, px",
                ms(shared, "disparity_error_bound_px"),
            ),
        );
        let r = &report["reprojected"];
        if !r.is_null() {
            points.push(
                Point::new(points.len() as f64, ms(r, "frame_ms"), off(r), "%")
                    .label("right eye reprojected")
                    .extra("× one eye", ms(r, "ratio"))
                    .extra("gaps filled, %", 100.0 * ms(r, "gap_fraction")),
            );
        }
        bench.progress.inc(1);
    }
    Ok(Knob {
        section: "rendering",
        name: "stereo pair".to_owned(),
        unit: String::new(),
        note: format!(
            "a headset-like pair (eyes of {width}x{width}, fields of view -52/43/-50/48 degrees \
             and their mirror, {IPD} model units apart) inside the model, frustum culling, every \
             view lit from between the eyes; the far part shared beyond the depth where the eyes' \
             disparity is within the error, or the right eye made from the left eye's image by \
             its depth"
        ),
        reference: "the pair drawn in full, each eye its own view".to_owned(),
        time: "median frame time of the pair".to_owned(),
        error_unit: "% of the right eye's pixels off by more than 8 levels".to_owned(),
        exact_setting: Some(0.0),
        log_x: false,
        log_error: false,
        points,
    })
}
