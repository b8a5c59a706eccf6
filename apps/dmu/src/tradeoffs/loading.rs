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

pub fn steps(quick: bool) -> u64 {
    (if quick { BUDGETS_QUICK } else { BUDGETS_FULL }).len() as u64 + ORDERS.len() as u64
}

pub fn run(bench: &Bench<'_>) -> anyhow::Result<Vec<Knob>> {
    let file = bench.scratch.join("loading.dmu");
    dmu_store::write_scene(bench.scene, &file, WriteOptions::default())
        .with_context(|| format!("writing {}", file.display()))?;
    let store = Arc::new(Store::open(&file)?);
    let geometry = store.info().geometry_resident_bytes;
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
    let (width, height) = bench.scale.render_size;
    let options = |order: LoadOrder, percent: f64| WalkOptions {
        order,
        budget_bytes: (geometry as f64 * percent / 100.0) as u64,
        loader_threads: 2,
        disk_bytes_per_frame: Some(16 << 20),
        frame_rate_hz: 60.0,
        viewport: Viewport { width, height },
        min_pixels: 1.0,
        prefetch: None,
        warmup_frames: path.len() / 10,
    };
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
            super::median(ms),
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
