//! `dmu collide`: replay recorded manipulations and report every clash.

use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context as _, bail};
use dmu_collide::{AllowList, Finding, Settings, StepOutcome, Summary, SweepMode, read_record};
use dmu_scene::Scene;
use serde_json::json;

use crate::collide_batch::{Checked, Records, check_records};
use crate::collide_bcf::{BcfRequest, write_bcf};
use crate::load::{Loaded, ModelArgs, load};

/// Replay records of part moves and report the clashes at every step.
///
/// A record is JSON Lines, one absolute world pose per line:
/// `{"t": 0.0, "part": "name or #id", "translation": [x,y,z], "rotation": [x,y,z,w]}`
/// (see docs/record-format.md). At each step the moved parts are checked
/// against everything else: `hard` (interpenetrating), `contact` (touching
/// within the contact tolerance), `soft` (closer than --clearance). With
/// --continuous each move is also swept from the pose before, and the first
/// `impact` along the way is reported.
///
/// Several records (`--record a.jsonl b.jsonl`, or a folder: every `*.jsonl`
/// in it, by name) are checked in parallel, each from the model's own poses,
/// the model loaded once; every record is read before any is checked, so a bad
/// one stops the run before it starts. The report has a part per record, in
/// the order given: text prints a block per record under `record FILE`, CSV
/// adds a first column `record`, JSON prints `{"records": [...], "summary":
/// ...}`, each entry what one record alone prints with --json. One record
/// named as a file prints as it always has.
///
/// With --bcf FILE.bcfzip the clashes are also written as BCF 2.1 issues for
/// design-review tools (`dmu bcf show FILE` lists them): one topic per pair of
/// parts per record, at the first step of the pair's worst finding (hard over
/// impact over contact over soft; a record of 3,000 steps of one contact makes
/// one topic), titled with that kind, both parts, the step and its time (and
/// the record's file name when there are several), the other kinds listed in
/// its description; its viewpoint frames both parts as they stand at that step (for
/// an impact, the part hit and the point of impact), from the +X, -Y, +Z side,
/// with both selected (glTF node names in
/// AuthoringToolId) and a snapshot rendered offscreen, the pair tinted.
/// Without a GPU adapter the file is written without snapshots, with a
/// warning.
///
/// Exit status: 0 when clear, 1 when any step of any record has a clash or
/// impact, 2 on error.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    model: ModelArgs,
    /// The records (JSON Lines), or folders of them (every `*.jsonl` inside,
    /// sorted by name). Give the model FILE before them.
    #[arg(long, required = true, num_args = 1.., value_name = "RECORD")]
    record: Vec<PathBuf>,
    /// Soft clash below this distance, model units (millimetres in the plant);
    /// 0 reports hard clashes and contacts only.
    #[arg(long, default_value_t = 5.0, value_parser = crate::units::number_in(0.0, crate::units::MAX_LENGTH))]
    clearance: f64,
    /// Sweep every move from the part's pose before it and report the time of
    /// first impact, so a fast move cannot pass through a thin plate (default:
    /// only moves farther than the part's own thickness are swept).
    #[arg(long)]
    continuous: bool,
    /// Never sweep: check each step at its end poses only, even where a part
    /// jumps farther than its thickness (the fastest, and blind to tunnelling).
    #[arg(long, conflicts_with = "continuous")]
    discrete: bool,
    /// Print the choices made by measurement and the figures behind them (which
    /// steps were swept and why); with --json, an "explain" array.
    #[arg(long)]
    explain: bool,
    /// Two parts that may touch, `A,B` (names, paths or #ids); repeatable.
    #[arg(long, value_name = "A,B")]
    allow: Vec<String>,
    /// Print one JSON document.
    #[arg(long, conflicts_with = "csv")]
    json: bool,
    /// Print CSV, one row per finding; the summary goes to standard error.
    #[arg(long)]
    csv: bool,
    /// Also write the clashes as BCF 2.1 issues to this `.bcfzip` (see above).
    #[arg(long, value_name = "FILE", value_parser = crate::units::output_with("bcfzip"))]
    bcf: Option<PathBuf>,
    /// Size of the BCF snapshots, `WIDTHxHEIGHT`, or `none` for none.
    #[arg(long, value_name = "SIZE", default_value = "1024x576", requires = "bcf", value_parser = parse_snapshot_size)]
    bcf_snapshot: SnapshotSize,
    /// The length of one model unit, for --bcf (BCF is in metres).
    #[arg(long, value_enum, default_value = "mm", requires = "bcf")]
    bcf_unit: crate::units::LengthUnit,
    /// Records checked at once (1 to 1024; default: the available cores, at
    /// most one per record). Each worker holds its own copy of the model, cell
    /// tree and collision meshes, so memory grows with --jobs.
    #[arg(long, value_parser = crate::units::count_in(1, MAX_JOBS))]
    jobs: Option<u64>,
}

/// `--bcf-snapshot`: a size in pixels, or none.
#[derive(Clone, Copy, Debug)]
struct SnapshotSize(Option<(u32, u32)>);

fn parse_snapshot_size(s: &str) -> anyhow::Result<SnapshotSize> {
    if s.eq_ignore_ascii_case("none") {
        return Ok(SnapshotSize(None));
    }
    crate::cmd_render::parse_size(s).map(|size| SnapshotSize(Some(size)))
}

/// The most workers `--jobs` may ask for.
const MAX_JOBS: u64 = 1024;

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
        csv_field(&f.a),
        csv_field(&f.b),
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

/// The record files the arguments name: files as given, folders as the
/// `*.jsonl` files in them sorted by name; and whether a folder was named.
fn record_files(args: &[PathBuf]) -> anyhow::Result<(Vec<PathBuf>, bool)> {
    let mut files = Vec::new();
    let mut folder = false;
    for path in args {
        if !path.is_dir() {
            files.push(path.clone());
            continue;
        }
        folder = true;
        let context = || format!("record folder {}", path.display());
        let mut found = Vec::new();
        for entry in std::fs::read_dir(path).with_context(context)? {
            let file = entry.with_context(context)?.path();
            if file.extension().is_some_and(|e| e == "jsonl") {
                found.push(file);
            }
        }
        if found.is_empty() {
            bail!("{}: no *.jsonl records in it", context());
        }
        found.sort();
        files.extend(found);
    }
    Ok((files, folder))
}

/// A record's totals, as the text report's last line.
fn summary_line(summary: &Summary) -> String {
    format!(
        "{} steps, {} part pairs ({} chunk pairs) tested, {} clashes, {} impacts, {:.1} ms",
        summary.steps,
        summary.part_pairs_tested,
        summary.chunk_pairs_tested,
        summary.clashes,
        summary.impacts,
        summary.seconds * 1e3
    )
}

/// Whether a replay found anything (exit status 1).
fn found_any(summary: &Summary) -> bool {
    summary.clashes + summary.impacts > 0
}

/// Replays the records; `Ok` carries the exit status (0 clear, 1 clashes).
/// Errors (model, records, arguments) are for the caller to report with status 2.
pub fn run(args: &Args) -> anyhow::Result<ExitCode> {
    let Loaded {
        scene,
        source,
        load_ms,
        ..
    } = load(&args.model)?;
    let (files, folder) = record_files(&args.record)?;
    // One record named as a file prints as it always has.
    let batch = folder || files.len() > 1;
    // Every record is read before any is replayed, so that a bad one stops
    // the batch before its work; the workers read each again as they take it
    // and hold only the records under way.
    let read = |index: usize, scene: &Scene| {
        let file = &files[index];
        read_record(file, scene).with_context(|| format!("record {}", file.display()))
    };
    for index in 0..files.len() {
        read(index, &scene)?;
    }
    let settings = Settings {
        clearance: args.clearance,
        allow: allow_list(&scene, &args.allow)?,
        ..Settings::default()
    };
    let model = source.map_or_else(|| "built-in plant".to_owned(), |p| p.display().to_string());
    let names: Vec<String> = scene
        .part_ids()
        .map(|p| scene.part_name(p).to_owned())
        .collect();
    let jobs = args.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, std::num::NonZero::get),
        |jobs| jobs as usize,
    );

    let sweep = if args.continuous {
        SweepMode::Always
    } else if args.discrete {
        SweepMode::Off
    } else {
        SweepMode::Auto
    };
    let sweep_name = match sweep {
        SweepMode::Off => "never",
        SweepMode::Auto => "auto",
        SweepMode::Always => "always",
    };
    // The BCF topics are made after the run, on a copy of the model at its
    // own poses (the workers consume theirs).
    let bcf_scene = args.bcf.as_ref().map(|_| scene.clone());
    let mut bcf_clashes = Vec::new();
    let start = Instant::now();
    let mut reports = Vec::new();
    let mut totals = Summary::default();
    let mut records_with_findings = 0;
    if args.csv {
        let record_column = if batch { "record," } else { "" };
        println!("{record_column}step,t,kind,part_a,part_b,distance,toi,x,y,z");
    }
    let emit = |index: usize, checked: Checked<Finding>| -> anyhow::Result<()> {
        let record = files[index].display().to_string();
        let Checked {
            findings,
            summary,
            tree_build_ms,
            explain,
        } = checked;
        totals.steps += summary.steps;
        totals.part_pairs_tested += summary.part_pairs_tested;
        totals.chunk_pairs_tested += summary.chunk_pairs_tested;
        totals.clashes += summary.clashes;
        totals.impacts += summary.impacts;
        totals.seconds += summary.seconds;
        records_with_findings += usize::from(found_any(&summary));
        if args.bcf.is_some() {
            bcf_clashes.push(crate::collide_bcf::pair_clashes(&findings));
        }
        let mut out = std::io::stdout().lock();
        if args.json {
            reports.push(json!({
                "model": model,
                "record": record,
                "clearance": args.clearance,
                "continuous": args.continuous,
                "sweep": sweep_name,
                "clashes": findings,
                "summary": {
                    "steps": summary.steps,
                    "part_pairs_tested": summary.part_pairs_tested,
                    "chunk_pairs_tested": summary.chunk_pairs_tested,
                    "clashes": summary.clashes,
                    "impacts": summary.impacts,
                    "check_ms": summary.seconds * 1e3,
                    "load_ms": load_ms,
                    "tree_build_ms": tree_build_ms,
                },
            }));
            if args.explain {
                reports.last_mut().expect("just pushed")["explain"] = json!(explain);
            }
        } else if args.csv {
            let record_field = if batch {
                format!("{},", csv_field(&record))
            } else {
                String::new()
            };
            for f in &findings {
                writeln!(out, "{record_field}{}", csv_row(f))?;
            }
            let record_name = if batch {
                format!("{record}: ")
            } else {
                String::new()
            };
            eprintln!("{record_name}{}", summary_line(&summary));
            if args.explain {
                for line in &explain {
                    eprintln!("{record_name}explain: {line}");
                }
            }
        } else {
            if batch {
                writeln!(out, "record {record}")?;
            }
            for f in &findings {
                writeln!(out, "{}", text_line(f))?;
            }
            writeln!(out, "{}", summary_line(&summary))?;
            if args.explain {
                if explain.is_empty() {
                    writeln!(
                        out,
                        "explain: no step moved a part farther than its thickness{}",
                        match sweep {
                            SweepMode::Auto => ": discrete checks only",
                            SweepMode::Always => " (every step swept: --continuous)",
                            SweepMode::Off => " (never swept: --discrete)",
                        }
                    )?;
                }
                for line in &explain {
                    writeln!(out, "explain: {line}")?;
                }
            }
        }
        Ok(())
    };
    // Findings name parts by the model's names, which outlive the workers'
    // copies of the scene.
    let collect = |o: &StepOutcome<'_>, found: &mut Vec<_>| {
        found.extend(o.findings().map(|f| Finding {
            a: names[f.a_id as usize].as_str().into(),
            b: names[f.b_id as usize].as_str().into(),
            step: f.step,
            t: f.t,
            kind: f.kind,
            a_id: f.a_id,
            b_id: f.b_id,
            distance: f.distance,
            toi: f.toi,
            point: f.point,
            normal: f.normal,
        }));
    };
    let records = Records {
        count: files.len(),
        load: read,
    };
    let workers = check_records(scene, records, &settings, sweep, jobs, collect, emit)?;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let bcf = match (&args.bcf, bcf_scene) {
        (Some(path), Some(scene)) => {
            let request = BcfRequest {
                path,
                unit: args.bcf_unit,
                snapshot: args.bcf_snapshot.0,
                clearance: args.clearance,
            };
            let written = write_bcf(scene, read, &files, &bcf_clashes, batch, &request)
                .with_context(|| format!("--bcf {}", path.display()))?;
            Some(json!({
                "path": path.display().to_string(),
                "topics": written.topics,
                "snapshots": written.snapshots,
            }))
        }
        _ => None,
    };

    if args.json {
        let out = if batch {
            json!({
                "model": model,
                "clearance": args.clearance,
                "continuous": args.continuous,
                "jobs": workers,
                "records": reports,
                "summary": {
                    "records": files.len(),
                    "records_with_findings": records_with_findings,
                    "steps": totals.steps,
                    "part_pairs_tested": totals.part_pairs_tested,
                    "chunk_pairs_tested": totals.chunk_pairs_tested,
                    "clashes": totals.clashes,
                    "impacts": totals.impacts,
                    "check_ms": totals.seconds * 1e3,
                    "load_ms": load_ms,
                    "wall_ms": wall_ms,
                },
            })
        } else {
            reports.pop().expect("one record, one report")
        };
        let mut out = out;
        if let Some(bcf) = &bcf {
            out["bcf"] = bcf.clone();
        }
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else if batch {
        let line = format!(
            "{} records ({records_with_findings} with clashes or impacts), {} steps, {} clashes, {} impacts, {workers} jobs, {wall_ms:.1} ms",
            files.len(),
            totals.steps,
            totals.clashes,
            totals.impacts,
        );
        if args.csv {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    }
    if !args.json
        && let Some(bcf) = &bcf
    {
        let line = format!(
            "bcf: {} topics ({} with snapshots) written to {}",
            bcf["topics"],
            bcf["snapshots"],
            bcf["path"].as_str().unwrap_or_default()
        );
        if args.csv {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    }
    Ok(if found_any(&totals) {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
