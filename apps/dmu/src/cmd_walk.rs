//! `dmu walk`: replays a camera path against the residency manager, no GPU.

use std::path::PathBuf;

use crate::walk_render::{FarUse, Mode};
use dmu_app::farfield::FarFieldSet;
use std::sync::Arc;

use anyhow::{Context as _, bail};
use dmu_render::{Culling, CullingOptions};
use dmu_store::{
    CameraFrame, LoadOrder, PrefetchOptions, Store, Viewport, WalkOptions, WalkReport, walk,
};
use dmu_tree::{Tree, TreeOptions};
use glam::DVec3;

use crate::units::{number_in, parse_bytes};

/// Replay a camera path through a store and report what the residency manager
/// kept in memory: per frame and in total, the chunks wanted (in the frustum and
/// at least --min-pixels on screen), those missing when the frame was drawn,
/// bytes loaded, peak resident bytes and the queue.
///
/// By default the loaders read a fixed number of bytes per frame
/// (--disk-per-frame), so results are the same on any machine; --real-time lets
/// loader threads run freely while frames take 1/--fps seconds each.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The store (.dmu).
    file: PathBuf,
    /// Camera path: a JSON list of `{"eye": [x,y,z], "target": [x,y,z], "up":
    /// [x,y,z], "fov": degrees}`, one per frame. Default: a built-in walk along
    /// the aisles of the plant (`dmu generate plant`, default origin).
    #[arg(long)]
    path: Option<PathBuf>,
    /// Residency budget: bytes (256MiB, 1GiB) or a percentage of the store's
    /// decoded geometry (10%).
    #[arg(long, default_value = "10%", value_parser = parse_budget)]
    memory_budget: Budget,
    /// Queue orders to compare, comma separated: visibility, area, fifo.
    #[arg(long, value_delimiter = ',', default_value = "visibility")]
    order: Vec<Order>,
    /// Disk bytes the loaders may read per frame (deterministic mode); the
    /// default is 1 GB/s at 60 frames per second.
    #[arg(long, default_value = "16MiB", value_parser = parse_bytes)]
    disk_per_frame: u64,
    /// Let loader threads run in real time instead, frames paced at --fps.
    #[arg(long)]
    real_time: bool,
    /// Frames per second of the path (0.01 to 1000).
    #[arg(long, default_value_t = 60.0, value_parser = number_in(0.01, 1000.0))]
    fps: f64,
    /// Loader threads [default: 2 for a file, 8 for a store on object
    /// storage, where each waits on the network].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    loader_threads: Option<u32>,
    /// Viewport width in pixels (16 to 16384).
    #[arg(long, default_value_t = 1920, value_parser = clap::value_parser!(u32).range(16..=16384))]
    width: u32,
    /// Viewport height in pixels (16 to 16384).
    #[arg(long, default_value_t = 1080, value_parser = clap::value_parser!(u32).range(16..=16384))]
    height: u32,
    /// Screen-coverage threshold: chunks whose box spans fewer pixels are not drawn.
    #[arg(long, default_value_t = 1.0, value_parser = number_in(0.0, 1e6))]
    min_pixels: f64,
    /// Draw each chunk's coarsest simplified level whose estimated error
    /// projects to at most this many pixels (0: every chunk whole, the exact image); with
    /// --render. With --compare, `none` stays exact: the reference.
    #[arg(long, default_value_t = 1.0, value_parser = number_in(0.0, 1e6))]
    lod_error_px: f64,
    /// With --render --compare: do not merge subtrees into simplified proxies
    /// (by default each subtree gets one, drawn in a single call instead of
    /// its chunks where its error projects within --lod-error-px).
    #[arg(long)]
    no_proxies: bool,
    /// With --render: a frame-time budget, ms. Each frame then chooses its LOD
    /// error (from 0, exact, up to 8 px) and coverage threshold after the last
    /// frame's time, and the report gives the choice per frame (the --compare
    /// reference stays exact).
    #[arg(long, value_parser = number_in(1.0, 1e6))]
    target_ms: Option<f64>,
    /// Turn off prefetching along the predicted path.
    #[arg(long)]
    no_prefetch: bool,
    /// Walk only frames START..END of the path (e.g. a stretch at full frame
    /// rate with --render, where every frame costs a second on lavapipe).
    #[arg(long, value_parser = parse_range)]
    range: Option<(usize, usize)>,
    /// Frames before the walk counts as warm.
    #[arg(long, default_value_t = 60, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1_000_000))]
    warmup_frames: usize,
    /// Frames drawn at the path's first camera before the walk, each followed
    /// by its loads, until one misses nothing, or three in a row miss no fewer
    /// than the fewest before them while the budget stalls the loads (the view
    /// does not fit), at most this many (0: none):
    /// the walk starts from a loaded view, as a viewer opening on one shows it
    /// once loaded. Not counted among the walk's frames (the report's
    /// `opening` says what they loaded and took).
    #[arg(long, default_value_t = 30, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=10_000))]
    opening_frames: usize,
    /// Print every frame (text mode).
    #[arg(long)]
    frames: bool,
    /// Render every frame of the path on the GPU instead (lavapipe where there
    /// is none), the whole model loaded, and report frame times and culling
    /// stats at --width x --height.
    #[arg(long)]
    render: bool,
    /// With --render (not --compare): a chunk wanted but not resident is
    /// drawn as its box (`box`, the default) or left out, a hole (`none`).
    #[arg(long, default_value = "box", value_parser = ["box", "none"], conflicts_with = "compare")]
    stand_ins: String,
    /// With --render (not --compare): each frame also draws the view from
    /// where the eye will be this many ms ahead (extrapolated from its last
    /// two frames, turning as it turns) with the same occlusion culling, and
    /// requests what that view draws as visible, so that what comes into
    /// view in numbers is loaded before it does. 0 turns it off.
    #[arg(long, default_value_t = 100.0, value_parser = number_in(0.0, 10_000.0), conflicts_with = "compare")]
    predict_ms: f64,
    /// With --render (not --compare): do not also draw the next frame's view
    /// (extrapolated as --predict-ms's), which finds a part about to show
    /// through a gap. Each predicted view costs about as much as the frame.
    #[arg(long, conflicts_with = "compare")]
    no_predict_next: bool,
    /// The predicted views' resolution as a share of --width and --height
    /// (0.5: a quarter of the pixels, cheaper views that miss what shows
    /// through gaps under two pixels wide).
    #[arg(long, default_value_t = 1.0, value_parser = number_in(0.05, 1.0), conflicts_with = "compare")]
    predict_resolution: f64,
    /// With --render: culling of the rendered frames.
    #[arg(long, default_value = "chc", value_parser = ["none", "frustum", "chc", "hzb", "auto"])]
    culling: String,
    /// With --render: run none, frustum, chc and hzb over the same frames in
    /// one run, compare each image with none's pixel for pixel, count chc's
    /// and hzb's triangles against the exactly visible chunks', and print the
    /// ratios.
    #[arg(long, requires = "render")]
    compare: bool,
    /// With --render --compare: draw the exact reference and the exactly
    /// visible chunks on every Nth frame only (1: every frame). The other
    /// modes are timed on every frame and their images compared on those;
    /// chunks more than one frame late are then not counted. On a 100M
    /// model the exact frame costs seconds.
    #[arg(long, default_value_t = 1, requires = "compare", value_parser = clap::value_parser!(u32).range(1..))]
    reference_every: u32,
    /// With --render --compare: draw the store's far fields (`dmu farfield
    /// build`) beyond each cell's cull box: `on`, or `auto` (only where they
    /// make frames faster, timed every 60 frames). The run then compares
    /// exact frustum culling (the reference), --culling without far fields
    /// and --culling with them, and reports each frame's pixels differing
    /// from the reference.
    #[arg(long, default_value = "off", value_parser = ["off", "on", "auto"])]
    far_field: String,
    /// With --render and chc: a chunk seen visible is assumed visible for this
    /// many frames before it is queried again (fewer: more queries, less
    /// over-draw when the view moves fast).
    #[arg(long, default_value_t = CullingOptions::default().requery_interval, value_parser = clap::value_parser!(u32).range(1..))]
    requery_interval: u32,
    /// Print the choices made by measurement and the figures behind them
    /// (with --render and chc: where occlusion queries were switched on or off,
    /// what they cost and saved); with --json, an "explain" array.
    #[arg(long)]
    explain: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

/// What --explain says of a walk without --render: nothing in it is chosen by
/// measurement.
const WALK_EXPLAIN: &str = "no choice made by measurement: the budget, load order and coverage are as given (occlusion is chosen per view with --render --culling chc)";

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Order {
    Visibility,
    Area,
    Fifo,
}

#[derive(Debug, Clone, Copy)]
enum Budget {
    Bytes(u64),
    Percent(f64),
}

pub fn parse_range(s: &str) -> anyhow::Result<(usize, usize)> {
    let (a, b) = s
        .split_once("..")
        .with_context(|| format!("{s:?}: expected START..END, e.g. 300..420"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<usize>()
            .with_context(|| format!("{s:?}: {v:?} is not a frame number"))
    };
    let (start, end) = (parse(a)?, parse(b)?);
    if start >= end {
        bail!("{s:?}: the range is empty (START must be below END)");
    }
    Ok((start, end))
}

fn parse_budget(s: &str) -> anyhow::Result<Budget> {
    match s.trim().strip_suffix('%') {
        Some(p) => {
            let p: f64 = p
                .trim()
                .parse()
                .with_context(|| format!("{s:?} is not a percentage"))?;
            if !(p > 0.0 && p <= 100.0) {
                bail!("{s:?}: a percentage must be in (0, 100]");
            }
            Ok(Budget::Percent(p))
        }
        None => match parse_bytes(s)? {
            0 => bail!("{s:?}: a memory budget must be more than 0 bytes"),
            b => Ok(Budget::Bytes(b)),
        },
    }
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let store = Arc::new(Store::open(&args.file)?);
    let open_ms = started.elapsed().as_secs_f64() * 1e3;
    let info = store.info();
    let budget_bytes = match args.memory_budget {
        Budget::Bytes(b) => b,
        Budget::Percent(p) => (info.geometry_resident_bytes as f64 * p / 100.0) as u64,
    };
    // Stored proxies, drawn by a rendered walk, take their share of the
    // budget from the chunks'.
    let proxy_bytes = match args.render && info.lod_nodes > 0 && args.lod_error_px > 0.0 {
        true => dmu_app::lod::proxy_budget(budget_bytes),
        false => 0,
    };
    let tree = Tree::build(store.skeleton(), TreeOptions::default());
    let path = camera_path(args.path.as_deref(), args.fps, args.range, &tree)?;
    let viewport = Viewport {
        width: args.width,
        height: args.height,
    };
    let prefetch = (!args.no_prefetch).then(|| PrefetchOptions::for_tree(&tree, args.min_pixels));
    let options = |order: &Order| WalkOptions {
        order: match order {
            Order::Visibility => LoadOrder::Visibility,
            Order::Area => LoadOrder::Area,
            Order::Fifo => LoadOrder::Fifo,
        },
        budget_bytes: budget_bytes - proxy_bytes,
        loader_threads: args
            .loader_threads
            .map_or_else(|| store.loader_threads(), |n| n as usize),
        disk_bytes_per_frame: (!args.real_time).then_some(args.disk_per_frame),
        frame_rate_hz: args.fps,
        viewport,
        min_pixels: args.min_pixels,
        prefetch,
        warmup_frames: args.warmup_frames,
        opening_frames: args.opening_frames,
        lod_cut: None,
    };
    if args.render {
        let culling: Culling = args.culling.parse().map_err(anyhow::Error::msg)?;
        let culling_options = CullingOptions {
            requery_interval: args.requery_interval,
            lod_error_px: args.lod_error_px,
            target_ms: args.target_ms,
            ..CullingOptions::default()
        };
        let far = match args.far_field.as_str() {
            "on" => FarUse::On,
            "auto" => FarUse::Auto,
            _ => FarUse::Off,
        };
        if far != FarUse::Off && !args.compare {
            bail!(
                "--far-field {} needs --compare (a walk within a memory budget does not draw far fields yet)",
                args.far_field
            );
        }
        let report = if args.compare {
            let scene = store
                .load_scene()
                .with_context(|| format!("loading {}", args.file.display()))?;
            let (modes, far_fields) = if far == FarUse::Off {
                (Culling::ALL.map(Mode::plain).to_vec(), None)
            } else {
                let set = FarFieldSet::open(&store, &scene)?.with_context(|| {
                    format!(
                        "{} has no far fields; make them with `dmu farfield build`",
                        args.file.display()
                    )
                })?;
                let modes = vec![
                    Mode::plain(Culling::Frustum),
                    Mode::plain(culling),
                    Mode { culling, far },
                ];
                (modes, Some(set))
            };
            crate::walk_render::run(
                &scene,
                &tree,
                &path,
                (args.width, args.height),
                &modes,
                Some(crate::walk_render::Compare {
                    reference_every: args.reference_every as usize,
                }),
                culling_options,
                !args.no_proxies,
                far_fields,
            )?
        } else {
            let order = args.order.first().unwrap_or(&Order::Visibility);
            crate::walk_render::run_resident(
                &store,
                &tree,
                &path,
                &options(order),
                crate::walk_render::Resident {
                    culling,
                    culling_options,
                    stand_ins: args.stand_ins == "box",
                    predict_s: args.predict_ms * 1e-3,
                    predict_next: !args.no_predict_next,
                    predict_scale: args.predict_resolution,
                    progress: true,
                    proxy_bytes,
                    started,
                },
            )?
        };
        let mut report = report;
        report["open_ms"] = serde_json::json!(open_ms);
        print_render(args, &report)?;
        return Ok(());
    }
    let mut reports = Vec::new();
    for order in &args.order {
        let report = walk(&store, &tree, &path, &options(order))?;
        reports.push(report);
    }
    if args.json {
        let mut value = serde_json::json!({
            "file": args.file.display().to_string(),
            "geometry_resident_bytes": info.geometry_resident_bytes,
            "geometry_file_bytes": info.geometry_file_bytes,
            "budget_bytes": budget_bytes,
            "frames": path.len(),
            "walks": reports,
        });
        if args.explain {
            value["explain"] = serde_json::json!([WALK_EXPLAIN]);
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    print_text(args, &info, budget_bytes, &reports);
    if args.explain {
        println!("explain: {WALK_EXPLAIN}");
    }
    Ok(())
}

/// The camera path of `path` (a JSON file) or the built-in plant walk at
/// `fps`, limited to `range` (frames START..END).
pub fn camera_path(
    path: Option<&std::path::Path>,
    fps: f64,
    range: Option<(usize, usize)>,
    tree: &Tree,
) -> anyhow::Result<Vec<CameraFrame>> {
    let path = match path {
        Some(p) => {
            let text = dmu_scene::read_regular_file(p)
                .with_context(|| format!("reading the path {}", p.display()))?;
            let frames: Vec<CameraFrame> = serde_json::from_slice(&text)
                .with_context(|| format!("{}: not a JSON list of camera frames", p.display()))?;
            frames
        }
        None => {
            let path = plant_path(fps);
            let bounds = tree.bounds();
            if !(bounds.contains_point(path[0].eye.with_z(bounds.center().z))) {
                bail!(
                    "the built-in path walks the plant of `dmu generate plant` at its default origin, \
                     outside this model; give --path"
                );
            }
            path
        }
    };
    let path = match range {
        Some((start, end)) => {
            if end > path.len() {
                bail!(
                    "--range {start}..{end}: past the end of the path, which has frames 0..{}",
                    path.len()
                );
            }
            path[start..end].to_vec()
        }
        None => path,
    };
    if path.is_empty() {
        bail!("the camera path has no frames");
    }
    Ok(path)
}

fn print_render(args: &Args, report: &serde_json::Value) -> anyhow::Result<()> {
    if args.json {
        let mut report = report.clone();
        if let (false, Some(object)) = (args.explain, report.as_object_mut()) {
            object.remove("explain");
        }
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    let walk = &report["walk"]["total"];
    let frames = if walk.is_null() {
        &report["frames"]
    } else {
        &walk["frames"]
    };
    println!(
        "{}: {frames} frames rendered at {}x{} on {}",
        args.file.display(),
        args.width,
        args.height,
        report["adapter"].as_str().unwrap_or("?")
    );
    let totals: Vec<&serde_json::Value> = match report["totals"].as_array() {
        Some(all) => all.iter().collect(),
        None => vec![&report["render"]["totals"]],
    };
    for t in totals {
        let differing = match t["frames_with_differing_pixels"].as_u64() {
            Some(n) => format!(
                "; {n} frames differ from the reference (worst {} pixels)",
                t["worst_differing_pixels"]
            ),
            None => String::new(),
        };
        println!(
            "  {:8} mean {:8.1} ms, median {:8.1}, p95 {:8.1}; {:.0} triangles, {:.0} queries a frame{differing}",
            t["culling"].as_str().unwrap_or("?"),
            t["mean_frame_ms"].as_f64().unwrap_or(f64::NAN),
            t["median_frame_ms"].as_f64().unwrap_or(f64::NAN),
            t["p95_frame_ms"].as_f64().unwrap_or(f64::NAN),
            t["mean_triangles_drawn"].as_f64().unwrap_or(f64::NAN),
            t["mean_queries"].as_f64().unwrap_or(f64::NAN),
        );
    }
    if !walk.is_null() {
        let mb = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN) / 1e6;
        println!(
            "  residency: {} frames with a miss ({} of {} warm), {} chunk instances missing; loaded {:.1} MB; peak resident {:.1} MB of {:.1} MB",
            walk["frames_with_miss"],
            walk["warm_frames_with_miss"],
            walk["warm_frames"],
            walk["missing_chunks"],
            mb(&walk["loaded_bytes"]),
            mb(&walk["peak_resident_bytes"]),
            mb(&walk["budget_bytes"]),
        );
        if let Ok(opening) = serde_json::from_value(report["walk"]["opening"].clone()) {
            print_opening(&opening);
        }
        if let Some(ms) = report["first_complete_image_ms"].as_f64() {
            println!(
                "  first complete image after {:.2} s (the store opened in {:.2} s)",
                ms / 1e3,
                report["open_ms"].as_f64().unwrap_or(f64::NAN) / 1e3
            );
        }
        print_remote(&report["walk"]["remote"], &walk["fetch_errors"]);
        let r = &report["render"];
        println!(
            "  drawn: {} frames with a hole, {} with a stand-in ({} of {} warm; stand-ins: {}); predicted view {} ms ahead, next frame's view: {}",
            r["frames_with_hole"],
            r["frames_with_standin"],
            r["warm_frames_with_standin"],
            r["warm_frames"],
            r["stand_ins"].as_str().unwrap_or("?"),
            r["prediction"]["ahead_ms"],
            r["prediction"]["next_frame"],
        );
    }
    if let Some(modes) = report["far_field"]["modes"].as_array() {
        let far = &report["far_field"];
        println!(
            "  far fields: {} cells, {:.0} kB and {:.1} s a cell",
            far["cells"],
            far["bytes_per_cell"].as_f64().unwrap_or(f64::NAN) / 1e3,
            far["build_ms_per_cell"].as_f64().unwrap_or(f64::NAN) / 1e3,
        );
        for m in modes {
            println!(
                "  {}: drawn in {} frames; differing pixels median {}, worst {}; {:.2}x faster than without",
                m["mode"].as_str().unwrap_or("?"),
                m["frames_with_far_field"],
                m["far_field_differing_pixels_median"],
                m["far_field_differing_pixels_worst"],
                m["without_over_with_median_frame_time"]
                    .as_f64()
                    .unwrap_or(f64::NAN),
            );
        }
    }
    for key in [
        "frustum_over_chc_frame_time",
        "none_over_chc_frame_time",
        "chc_over_hzb_frame_time",
        "frustum_over_hzb_frame_time",
        "chc_over_exact_triangles_mean",
        "chc_over_exact_triangles_worst",
        "hzb_over_exact_triangles_mean",
        "hzb_over_exact_triangles_worst",
        "chc_chunks_more_than_one_frame_late",
        "hzb_chunks_more_than_one_frame_late",
    ] {
        if !report[key].is_null() {
            println!("  {key}: {}", report[key]);
        }
    }
    if args.explain {
        for line in report["explain"].as_array().into_iter().flatten() {
            println!("explain: {}", line.as_str().unwrap_or_default());
        }
    }
    Ok(())
}

/// What reading a remote store cost, when it was one.
fn print_remote(remote: &serde_json::Value, fetch_errors: &serde_json::Value) {
    if remote.is_null() {
        return;
    }
    println!(
        "  remote: {} requests, {:.1} MB fetched, {:.1} MB from the cache; {} retries, {} timeouts, {} failed; {} loads failed for I/O and were tried again",
        remote["requests"],
        remote["bytes_fetched"].as_f64().unwrap_or(f64::NAN) / 1e6,
        remote["cache_hit_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6,
        remote["retries"],
        remote["timeouts"],
        remote["failed_requests"],
        fetch_errors,
    );
}

/// The frames before the walk, when there were any.
fn print_opening(o: &dmu_store::Opening) {
    if o.frames > 0 {
        println!(
            "  opening: {} frames at the first view, {:.1} MB loaded in {:.1} s (counted in the totals below); {} chunk instances still missing",
            o.frames,
            o.loaded_bytes as f64 / 1e6,
            o.wall_ms / 1e3,
            o.missing_chunks
        );
    }
}

fn print_text(args: &Args, info: &dmu_store::StoreInfo, budget: u64, reports: &[WalkReport]) {
    let mb = |b: u64| b as f64 / 1e6;
    println!(
        "{}: {:.1} MB of geometry decoded; budget {:.1} MB ({:.1}%)",
        args.file.display(),
        mb(info.geometry_resident_bytes),
        mb(budget),
        100.0 * budget as f64 / info.geometry_resident_bytes.max(1) as f64
    );
    for r in reports {
        let t = &r.total;
        print_opening(&r.opening);
        if args.frames {
            println!("  frame  wanted  wanted MB  missing  loaded MB  resident MB  queue");
            for (i, f) in r.frames.iter().enumerate() {
                println!(
                    "  {i:5}  {:6}  {:9.1}  {:7}  {:9.1}  {:11.1}  {:5}{}",
                    f.wanted_chunks,
                    mb(f.wanted_bytes),
                    f.missing_chunks,
                    mb(f.loaded_bytes),
                    mb(f.resident_bytes),
                    f.queue_len,
                    if f.prefetch_rebuilt {
                        "  prefetch rebuilt"
                    } else {
                        ""
                    }
                );
            }
        }
        println!(
            "  {:?}: {} frames, {} with a miss; warm: {} of {} ({:.2}%); {} misses; loaded {:.1} MB in {} chunks; peak resident {:.1} MB; most wanted {:.1} MB; mean queue {:.0}; {:.1} s",
            r.options.order,
            t.frames,
            t.frames_with_miss,
            t.warm_frames_with_miss,
            t.warm_frames,
            100.0 * t.warm_miss_fraction,
            t.missing_chunks,
            mb(t.loaded_bytes),
            t.loads,
            mb(t.peak_resident_bytes),
            mb(t.max_wanted_bytes),
            t.mean_queue_len,
            t.wall_ms / 1e3
        );
        if let Some(e) = &r.first_error {
            println!("  load errors: {} (first: {e})", t.failed_loads);
        }
        if let Ok(remote) = serde_json::to_value(&r.remote) {
            print_remote(&remote, &serde_json::json!(t.fetch_errors));
        }
    }
}

/// A walk through the plant of `dmu generate plant` (default origin, 48 m plots
/// in rows along X; each plot has its pipe rack at 2-10 m from its front edge
/// and its building from 14 m): along the first row's aisle between racks and
/// buildings at 3 m/s, a look around, a snap turn into the gap between two
/// plots, across to the next row, a fast run along that row's aisle at 12 m/s
/// with a snap turn before it, and a last look back. Eye height 1.7 m, 60 degree
/// field of view; millimetres.
fn plant_path(fps: f64) -> Vec<CameraFrame> {
    /// Must match `dmu_samples::plant`'s plot size.
    const PLOT: f64 = 48_000.0;
    const AISLE: f64 = 12_000.0;
    const EYE: f64 = 1_700.0;
    let origin = dmu_samples::PlantOptions::default().origin;
    let at = |x: f64, y: f64| origin + DVec3::new(x, y, EYE);
    let mut path = Vec::new();
    let mut push = |eye: DVec3, heading_deg: f64| {
        let h = heading_deg.to_radians();
        path.push(CameraFrame {
            eye,
            target: eye + DVec3::new(h.cos(), h.sin(), 0.0) * 1_000.0,
            up: DVec3::Z,
            fov_y_deg: 60.0,
        });
    };
    let frames = |seconds: f64| (seconds * fps).round().max(1.0) as usize;
    let walk = |push: &mut dyn FnMut(DVec3, f64), from: DVec3, to: DVec3, speed: f64| {
        let heading = (to.y - from.y).atan2(to.x - from.x).to_degrees();
        let n = frames(from.distance(to) / 1_000.0 / speed);
        for i in 0..n {
            push(from.lerp(to, i as f64 / n as f64), heading);
        }
    };
    // Along the first row's aisle.
    let a = at(4_000.0, AISLE);
    let b = at(PLOT, AISLE);
    walk(&mut push, a, b, 3.0);
    // Look around: a full turn to the left in 4 s.
    let n = frames(4.0);
    for i in 0..n {
        push(b, 360.0 * i as f64 / n as f64);
    }
    // Snap turn (90 degrees in one frame), then across to the next row.
    let c = at(PLOT, PLOT + AISLE);
    walk(&mut push, b, c, 3.0);
    // Snap turn, then fast along the second row's aisle.
    let d = at(4.0 * PLOT, PLOT + AISLE);
    walk(&mut push, c, d, 12.0);
    // Look back over 2 s.
    let n = frames(2.0);
    for i in 0..n {
        push(d, 180.0 * i as f64 / n as f64);
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_and_budgets_parse() {
        assert_eq!(parse_range("300..420").unwrap(), (300, 420));
        assert_eq!(parse_range(" 0 .. 7 ").unwrap(), (0, 7));
        assert!(parse_range("300").is_err());
        assert!(parse_range("a..b").is_err());
        assert!(parse_range("-1..4").is_err());
        assert!(matches!(parse_budget("10%").unwrap(), Budget::Percent(p) if p == 10.0));
        assert!(matches!(parse_budget("256MiB").unwrap(), Budget::Bytes(b) if b == 256 << 20));
        assert!(parse_budget("0%").is_err());
        assert!(parse_budget("150%").is_err());
    }
}
