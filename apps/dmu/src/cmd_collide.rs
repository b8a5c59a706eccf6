//! `dmu collide`: replay recorded manipulations and report every clash.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context as _, bail};
use dmu_collide::{AllowList, Checker, Finding, Settings, read_record, replay};
use dmu_scene::Scene;
use dmu_tree::{Tree, TreeOptions};
use serde_json::json;

use crate::load::{ModelArgs, load};

/// Replay a record of part moves and report the clashes at every step.
///
/// The record is JSON Lines, one absolute world pose per line:
/// `{"t": 0.0, "part": "name or #id", "translation": [x,y,z], "rotation": [x,y,z,w]}`
/// (see docs/record-format.md). At each step the moved parts are checked
/// against everything else: `hard` (interpenetrating), `contact` (touching
/// within the contact tolerance), `soft` (closer than --clearance). With
/// --continuous each move is also swept from the pose before, and the first
/// `impact` along the way is reported.
///
/// Exit status: 0 when clear, 1 when any step has a clash or impact, 2 on error.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    model: ModelArgs,
    /// The record (JSON Lines).
    #[arg(long)]
    record: PathBuf,
    /// Soft clash below this distance, model units (millimetres in the plant);
    /// 0 reports hard clashes and contacts only.
    #[arg(long, default_value_t = 5.0, value_parser = crate::units::number_in(0.0, crate::units::MAX_LENGTH))]
    clearance: f64,
    /// Also sweep every move from the part's pose before it and report the time
    /// of first impact, so a fast move cannot pass through a thin plate.
    #[arg(long)]
    continuous: bool,
    /// Two parts that may touch, `A,B` (names, paths or #ids); repeatable.
    #[arg(long, value_name = "A,B")]
    allow: Vec<String>,
    /// Print one JSON document.
    #[arg(long, conflicts_with = "csv")]
    json: bool,
    /// Print CSV, one row per finding; the summary goes to standard error.
    #[arg(long)]
    csv: bool,
}

fn allow_list(scene: &Scene, pairs: &[String]) -> anyhow::Result<AllowList> {
    let mut list = AllowList::default();
    for pair in pairs {
        let Some((a, b)) = pair.split_once(',') else {
            bail!("--allow {pair:?}: expected two parts A,B");
        };
        let find = |key: &str| {
            scene
                .find_part(key.trim())
                .with_context(|| format!("--allow {pair:?}"))
        };
        let (a, b) = (find(a)?, find(b)?);
        if a == b {
            bail!("--allow {pair:?}: names one part twice (a part never clashes with itself)");
        }
        list.allow(a, b);
    }
    Ok(list)
}

/// A CSV field, quoted when it must be.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// A finding as one CSV row.
fn csv_row(f: &Finding<'_>) -> String {
    let p = f.point;
    format!(
        "{},{},{},{},{},{},{},{},{},{}",
        f.step,
        f.t,
        f.kind,
        csv_field(f.a),
        csv_field(f.b),
        f.distance,
        f.toi.map_or(String::new(), |t| t.to_string()),
        p[0],
        p[1],
        p[2]
    )
}

/// A finding as one line of text.
fn text_line(f: &Finding<'_>) -> String {
    let what = match f.toi {
        Some(toi) => format!("toi {toi:.6}"),
        None => format!("distance {:.6}", f.distance),
    };
    let p = f.point;
    format!(
        "t={} {:<7} {} {} {what} at [{:.3}, {:.3}, {:.3}]",
        f.t, f.kind, f.a, f.b, p[0], p[1], p[2]
    )
}

/// Replays the record; `Ok` carries the exit status (0 clear, 1 clashes).
/// Errors (model, record, arguments) are for the caller to report with status 2.
pub fn run(args: &Args) -> anyhow::Result<ExitCode> {
    let mut loaded = load(&args.model)?;
    let scene = &mut loaded.scene;
    let steps = read_record(&args.record, scene)
        .with_context(|| format!("record {}", args.record.display()))?;
    let settings = Settings {
        clearance: args.clearance,
        allow: allow_list(scene, &args.allow)?,
        ..Settings::default()
    };
    let start = Instant::now();
    let mut tree = Tree::build(scene, TreeOptions::default());
    let tree_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut checker = Checker::new(scene);

    let mut all = Vec::new();
    if args.csv {
        println!("step,t,kind,part_a,part_b,distance,toi,x,y,z");
    }
    let summary = replay(
        scene,
        &mut tree,
        &mut checker,
        &steps,
        &settings,
        args.continuous,
        |o| {
            for f in o.findings() {
                if args.json {
                    all.push(serde_json::to_value(&f).expect("a finding serializes"));
                } else if args.csv {
                    println!("{}", csv_row(&f));
                } else {
                    println!("{}", text_line(&f));
                }
            }
        },
    );
    let summary_json = json!({
        "steps": summary.steps,
        "part_pairs_tested": summary.part_pairs_tested,
        "chunk_pairs_tested": summary.chunk_pairs_tested,
        "clashes": summary.clashes,
        "impacts": summary.impacts,
        "check_ms": summary.seconds * 1e3,
        "load_ms": loaded.load_ms,
        "tree_build_ms": tree_ms,
    });
    if args.json {
        let out = json!({
            "model": loaded.source.as_ref().map_or_else(|| "built-in plant".to_owned(), |p| p.display().to_string()),
            "record": args.record.display().to_string(),
            "clearance": args.clearance,
            "continuous": args.continuous,
            "clashes": all,
            "summary": summary_json,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let line = format!(
            "{} steps, {} part pairs ({} chunk pairs) tested, {} clashes, {} impacts, {:.1} ms",
            summary.steps,
            summary.part_pairs_tested,
            summary.chunk_pairs_tested,
            summary.clashes,
            summary.impacts,
            summary.seconds * 1e3
        );
        if args.csv {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    }
    Ok(if summary.clashes + summary.impacts > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
