//! Loading knobs: the residency budget and the load order, on the model
//! written as a store and walked GPU-free along the rendering section's path
//! at 60 frames a second (loaders reading a fixed 16 MiB a frame, so the
//! counts are the same on any machine).

use std::sync::Arc;

use anyhow::Context as _;
use dmu_store::{CameraFrame, LoadOrder, Store, Viewport, WalkOptions, WriteOptions, walk};
use dmu_tree::{Tree, TreeOptions};

use super::{Bench, Knob, Point};

const BUDGETS_QUICK: &[f64] = &[5.0, 20.0, 100.0];
const BUDGETS_FULL: &[f64] = &[2.0, 5.0, 10.0, 20.0, 50.0, 100.0];
const ORDERS: &[(LoadOrder, &str)] = &[
    (LoadOrder::Visibility, "visibility"),
    (LoadOrder::Area, "area"),
    (LoadOrder::Fifo, "fifo"),
];
/// The budget the load orders are compared at, percent of the geometry.
const ORDER_BUDGET: f64 = 10.0;

/// How far ahead the rendered walk's predicted view looks, ms (0: none),
/// whether the next frame's view is drawn too, and the setting's label.
const PREDICT: &[(f64, bool, &str)] = &[
    (0.0, false, "none"),
    (0.0, true, "next frame"),
    (100.0, false, "100 ms"),
    (100.0, true, "100 ms and next frame (the default)"),
];
/// Frames of the rendered walk (the path's first, from a cold start).
const RENDERED_FRAMES: usize = 120;

pub fn steps(quick: bool) -> u64 {
    (if quick { BUDGETS_QUICK } else { BUDGETS_FULL }).len() as u64
        + ORDERS.len() as u64
        + PREDICT.len() as u64
}

/// The model as a store, its tree and the rendering section's path.
fn walked(bench: &Bench<'_>) -> anyhow::Result<(Arc<Store>, Tree, Vec<CameraFrame>)> {
    let file = bench.scratch.join("loading.dmu");
    if !file.exists() {
        dmu_store::write_scene(bench.scene, &file, WriteOptions::default())
            .with_context(|| format!("writing {}", file.display()))?;
    }
    let store = Arc::new(Store::open(&file)?);
    let tree = Tree::build(store.skeleton(), TreeOptions::default());
    let path: Vec<CameraFrame> = super::render::path(&tree, bench.scale.walk_frames)
        .into_iter()
        .map(|c| CameraFrame {
            eye: c.eye,
            target: c.target,
            up: c.up,
            fov_y_deg: c.fov_y_rad.to_degrees(),
        })
        .collect();
    Ok((store, tree, path))
}

/// The walk's options at `percent` of the geometry.
fn walk_options(
    bench: &Bench<'_>,
    geometry: u64,
    frames: usize,
    order: LoadOrder,
    percent: f64,
) -> WalkOptions {
    let (width, height) = bench.scale.render_size;
    WalkOptions {
        order,
        budget_bytes: (geometry as f64 * percent / 100.0) as u64,
        loader_threads: 2,
        disk_bytes_per_frame: Some(16 << 20),
        frame_rate_hz: 60.0,
        viewport: Viewport { width, height },
        min_pixels: 1.0,
        prefetch: None,
        warmup_frames: frames / 10,
        // From a cold start: the warm frames are what the knobs are judged by.
        opening_frames: 0,
        lod_cut: None,
    }
}

/// The predicted view of `dmu walk --render` within a budget: the renderer
/// (chc, stand-ins for chunks not resident) walks the path's first frames
/// at a 10 % budget, drawing each frame a second view from where the eye
/// will be; what that view draws is loaded before it shows. Needs a GPU
/// (lavapipe will do).
pub fn run_predicted(bench: &Bench<'_>) -> anyhow::Result<Vec<Knob>> {
    let (store, tree, path) = walked(bench)?;
    let path = &path[..RENDERED_FRAMES.min(path.len())];
    let o = walk_options(
        bench,
        store.info().geometry_resident_bytes,
        path.len(),
        LoadOrder::Visibility,
        ORDER_BUDGET,
    );
    let points = (PREDICT.iter().zip(0..))
        .map(|(&(ms, next, label), i)| {
            let report = crate::walk_render::run_resident(
                &store,
                &tree,
                path,
                &o,
                crate::walk_render::Resident {
                    culling: dmu_render::Culling::Occlusion,
                    culling_options: dmu_render::CullingOptions::default(),
                    stand_ins: true,
                    predict_s: ms * 1e-3,
                    predict_next: next,
                    predict_scale: 1.0,
                    progress: false,
                    proxy_bytes: 0,
                    started: std::time::Instant::now(),
                },
            )?;
            let r = &report["render"];
            let frames = r["per_frame_residency"]
                .as_array()
                .map_or(&[][..], Vec::as_slice);
            let ahead: Vec<f64> = frames
                .iter()
                .filter_map(|f| f["ahead_ms"].as_f64())
                .collect();
            let main = r["totals"]["mean_frame_ms"].as_f64().unwrap_or(f64::NAN);
            bench.progress.inc(1);
            Ok(Point::new(
                f64::from(i),
                main + ahead.iter().sum::<f64>() / ahead.len().max(1) as f64,
                r["warm_frames_with_standin"].as_f64().unwrap_or(f64::NAN),
                "warm frames drawing a stand-in",
            )
            .label(label)
            .extra(
                "stand-ins drawn",
                r["stand_ins_drawn"].as_f64().unwrap_or(f64::NAN),
            )
            .extra(
                "MB loaded",
                report["walk"]["total"]["loaded_bytes"]
                    .as_f64()
                    .unwrap_or(f64::NAN)
                    / 1e6,
            ))
        })
        .collect::<anyhow::Result<_>>()?;
    Ok(vec![Knob {
        section: "loading",
        name: "predicted view".to_owned(),
        unit: String::new(),
        note: format!(
            "the views `dmu walk --render` draws ahead of the eye to load what they see (`--predict-ms`, `--no-predict-next`); chc, box stand-ins, a {ORDER_BUDGET}% budget, the path's first {} frames at 60 Hz",
            path.len()
        ),
        reference: "every chunk the renderer draws resident when its frame is drawn (no stand-in)"
            .to_owned(),
        time: "frame time, the predicted views' included".to_owned(),
        error_unit: "warm frames drawing a stand-in".to_owned(),
        exact_setting: None,
        log_x: false,
        log_error: false,
        points,
    }])
}

pub fn run(bench: &Bench<'_>) -> anyhow::Result<Vec<Knob>> {
    let (store, tree, path) = walked(bench)?;
    let geometry = store.info().geometry_resident_bytes;
    let options =
        |order: LoadOrder, percent: f64| walk_options(bench, geometry, path.len(), order, percent);
    // Each walk three times: the counts are the same every time (the loaders
    // read a fixed amount a frame), the time is the median.
    let measure = |setting: f64, o: &WalkOptions| -> anyhow::Result<Point> {
        let mut ms = Vec::new();
        let mut report = None;
        for _ in 0..3 {
            let r = walk(&store, &tree, &path, o)?;
            ms.push(r.total.wall_ms / r.total.frames.max(1) as f64);
            report = Some(r);
        }
        let report = report.expect("three walks");
        let t = &report.total;
        bench.progress.inc(1);
        Ok(Point::new(
            setting,
            dmu_geom::median(ms),
            t.warm_frames_with_miss as f64,
            "warm frames with a miss",
        )
        .extra("MB loaded", t.loaded_bytes as f64 / 1e6)
        .extra("frames with a miss", t.frames_with_miss as f64)
        .extra("chunks missing", t.missing_chunks as f64))
    };
    let budgets = if bench.scale.quick {
        BUDGETS_QUICK
    } else {
        BUDGETS_FULL
    };
    let reference = "every wanted chunk resident when its frame is drawn (0 misses)";
    let budget = Knob {
        section: "loading",
        name: "memory budget".to_owned(),
        unit: "%".to_owned(),
        note: "budget as a share of the decoded geometry, visibility order".to_owned(),
        reference: reference.to_owned(),
        time: "walk time a frame".to_owned(),
        error_unit: "warm frames with a miss".to_owned(),
        exact_setting: None,
        log_x: false,
        log_error: false,
        points: budgets
            .iter()
            .map(|&p| measure(p, &options(LoadOrder::Visibility, p)))
            .collect::<anyhow::Result<_>>()?,
    };
    let order = Knob {
        section: "loading",
        name: "load order".to_owned(),
        unit: String::new(),
        note: format!("queue order, at a {ORDER_BUDGET}% budget"),
        reference: reference.to_owned(),
        time: "walk time a frame".to_owned(),
        error_unit: "warm frames with a miss".to_owned(),
        exact_setting: None,
        log_x: false,
        log_error: false,
        points: ORDERS
            .iter()
            .enumerate()
            .map(|(i, &(order, name))| {
                Ok(measure(i as f64, &options(order, ORDER_BUDGET))?.label(name))
            })
            .collect::<anyhow::Result<_>>()?,
    };
    Ok(vec![budget, order])
}
