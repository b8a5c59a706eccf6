//! `dmu pick`: the nearest part along a ray, or along each of many rays.

use std::io::{BufRead, BufReader, Read, Write as _};
use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use dmu_geom::Ray3d;
use dmu_scene::Scene;
use dmu_tree::{HitReport, Tree, TreeOptions};
use rayon::prelude::*;
use serde::Deserialize;
use serde_json::{Value, json};

use crate::load::{ModelArgs, load};

/// The longest line of a `--rays` file, in bytes: a ray of six 17-digit
/// numbers with field names is about 150, so a longer line is not a ray, and
/// the reader never buffers more than this of a line without a newline.
const MAX_RAY_LINE_BYTES: u64 = 4096;

/// Rays picked in parallel per block: the results of a block are printed in
/// input order before the next block is read, so memory stays bounded however
/// many rays come.
const RAYS_PER_BLOCK: usize = 4096;

/// Files of `--rays` larger than this show a progress bar (on a terminal).
const PROGRESS_MIN_BYTES: u64 = 1 << 20;

/// Cast rays into the model and report the nearest part hit (or every hit).
///
/// A ray is `origin + t * direction` in world units; `distance` is reported in
/// world units whatever the direction's length. Exit code 0 whether or not it
/// hits.
///
/// Many rays: `--rays FILE` (or `--rays -` for standard input) reads one ray
/// per line, `{"origin": [x,y,z], "direction": [dx,dy,dz]}` or
/// `[ox,oy,oz,dx,dy,dz]`; blank lines are skipped. The model is opened once and
/// the rays are picked in parallel, the results printed one per ray in input
/// order (JSON Lines with --json, each line what `--ray --json` prints, compact)
/// as they come, in blocks of 4096 rays. A bad line stops the run with an error
/// naming the file and line (exit 2); the blocks before it have been printed.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["ray", "rays"])))]
pub struct Args {
    #[command(flatten)]
    model: ModelArgs,
    /// The ray: origin and direction, `ox,oy,oz,dx,dy,dz`.
    #[arg(long, allow_hyphen_values = true)]
    ray: Option<String>,
    /// A file of rays, one per line (JSON Lines), or `-` for standard input.
    #[arg(long, value_name = "FILE|-")]
    rays: Option<PathBuf>,
    /// Report every hit along the ray, nearest first.
    #[arg(long)]
    all: bool,
    /// Print JSON instead of text (JSON Lines with --rays).
    #[arg(long)]
    json: bool,
}

/// What a ray of six numbers must be, in every refusal of one.
const RAY_RULE: &str = "origin and direction must be finite and the direction non-zero";

/// The ray of `[ox, oy, oz, dx, dy, dz]`; a direction too short or too long to
/// square is scaled by a power of two ([`Ray3d::with_safe_dir`]).
fn ray_of(v: [f64; 6]) -> Option<Ray3d> {
    let [ox, oy, oz, dx, dy, dz] = v;
    Ray3d::with_safe_dir(glam::DVec3::new(ox, oy, oz), glam::DVec3::new(dx, dy, dz))
}

/// Parses `ox,oy,oz,dx,dy,dz` (see [`ray_of`]).
fn parse_ray(s: &str) -> anyhow::Result<Ray3d> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--ray {s:?}: expected six numbers ox,oy,oz,dx,dy,dz"))?;
    let Ok(v) = <[f64; 6]>::try_from(v.as_slice()) else {
        bail!("--ray {s:?}: expected six numbers, got {}", v.len())
    };
    ray_of(v).ok_or_else(|| anyhow::anyhow!("--ray {s:?}: {RAY_RULE}"))
}

/// A line of a `--rays` file in its object form.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RayLine {
    origin: [f64; 3],
    direction: [f64; 3],
}

/// One line of a `--rays` file (not blank) as a ray, or why it is not one.
fn parse_ray_line(text: &str) -> Result<Ray3d, String> {
    // serde_json counts lines within the one line it was given: say the column.
    let reason = |e: serde_json::Error| {
        let mut message = e.to_string();
        if let Some(at) = message.rfind(" at line ") {
            message.truncate(at);
        }
        format!("{message} (column {})", e.column())
    };
    let v: [f64; 6] = match text.trim_start().as_bytes().first() {
        Some(b'{') => {
            let line: RayLine = serde_json::from_str(text).map_err(reason)?;
            let [ox, oy, oz] = line.origin;
            let [dx, dy, dz] = line.direction;
            [ox, oy, oz, dx, dy, dz]
        }
        Some(b'[') => serde_json::from_str(text).map_err(reason)?,
        _ => {
            return Err(
                "expected {\"origin\": [x,y,z], \"direction\": [dx,dy,dz]} or [ox,oy,oz,dx,dy,dz]"
                    .into(),
            );
        }
    };
    ray_of(v).ok_or_else(|| RAY_RULE.to_owned())
}

/// The rays of a `--rays` input, read a block at a time with lines numbered
/// from 1.
struct RayReader {
    input: Box<dyn BufRead>,
    /// The file as errors name it (`<stdin>` for `-`).
    name: String,
    /// The last line read.
    line: usize,
    /// Bytes read so far.
    bytes: u64,
    buf: Vec<u8>,
}

impl RayReader {
    /// Opens the input: a regular file, or standard input for `-`; its length
    /// when known.
    fn open(path: &Path) -> anyhow::Result<(Self, Option<u64>)> {
        let (input, name, len): (Box<dyn BufRead>, _, _) = if path == Path::new("-") {
            (
                Box::new(std::io::stdin().lock()),
                "<stdin>".to_owned(),
                None,
            )
        } else {
            let name = path.display().to_string();
            let file = dmu_scene::open_regular_file(path)
                .and_then(|f| Ok((f.metadata()?.len(), f)))
                .with_context(|| format!("rays {name}"));
            let (len, file) = file?;
            (Box::new(BufReader::new(file)), name, Some(len))
        };
        let reader = Self {
            input,
            name,
            line: 0,
            bytes: 0,
            buf: Vec::new(),
        };
        Ok((reader, len))
    }

    /// Fills `rays` (cleared first) with up to `max` rays and their line
    /// numbers; fewer only at the end of the input. A bad line is an error
    /// at once, naming it.
    fn read_block(&mut self, rays: &mut Vec<(usize, Ray3d)>, max: usize) -> anyhow::Result<()> {
        rays.clear();
        while rays.len() < max {
            self.buf.clear();
            let read = Read::take(&mut self.input, MAX_RAY_LINE_BYTES + 1)
                .read_until(b'\n', &mut self.buf)
                .with_context(|| {
                    format!("rays {}: cannot read line {}", self.name, self.line + 1)
                })?;
            if read == 0 {
                break;
            }
            self.line += 1;
            self.bytes += read as u64;
            let error =
                |reason: &str| anyhow::anyhow!("rays {}: line {}: {reason}", self.name, self.line);
            let content = self.buf.strip_suffix(b"\n").unwrap_or(&self.buf);
            if content.len() as u64 > MAX_RAY_LINE_BYTES {
                return Err(error(&format!(
                    "longer than {MAX_RAY_LINE_BYTES} bytes (a ray is one line of six numbers)"
                )));
            }
            let text = std::str::from_utf8(content).map_err(|_| error("not UTF-8"))?;
            // Editors on some systems start UTF-8 files with a byte-order mark.
            let text = match self.line {
                1 => text.strip_prefix('\u{feff}').unwrap_or(text),
                _ => text,
            };
            if text.trim().is_empty() {
                continue;
            }
            rays.push((self.line, parse_ray_line(text).map_err(|r| error(&r))?));
        }
        Ok(())
    }
}

/// The pick of one ray as JSON: the nearest hit (`{"hit": false}` for none),
/// or with `all` every hit, nearest first (`{"hits": [...]}`).
fn pick_json(scene: &Scene, tree: &Tree, ray: &Ray3d, all: bool) -> Value {
    let length = ray.dir.length();
    let describe = |h: &dmu_tree::Hit| dmu_app::hits::hit_json(scene, h, length);
    if all {
        json!({ "hits": tree.pick_all(scene, ray).iter().map(describe).collect::<Vec<_>>() })
    } else {
        tree.pick(scene, ray)
            .as_ref()
            .map_or_else(|| json!({ "hit": false }), describe)
    }
}

/// The nearest hit of one ray as a line of JSON, the bytes of [`pick_json`]'s
/// (the report's fields are in the order a `Value` prints them), serialized
/// straight from the report: the bulk of `--rays --json`, without building
/// a `Value` for each ray.
fn nearest_json_line(scene: &Scene, tree: &Tree, ray: &Ray3d) -> String {
    let mut line = match tree.pick(scene, ray) {
        Some(hit) => serde_json::to_string(&HitReport::new(scene, &hit, ray.dir.length()))
            .expect("a hit report serializes"),
        None => r#"{"hit":false}"#.to_owned(),
    };
    line.push('\n');
    line
}

/// A pick as text, one entry per hit (`no hit` for none), each entry starting
/// with `prefix` and ending with a newline.
fn pick_text(out: &Value, prefix: &str) -> String {
    let hit = |h: &Value| {
        format!(
            "{prefix}{} (#{}) at distance {} point {} triangle {}\n  path {}\n",
            h["part"].as_str().unwrap_or_default(),
            h["part_id"],
            h["distance"],
            h["point"],
            h["triangle"],
            h["path"].as_str().unwrap_or_default()
        )
    };
    match (&out["hits"], &out["hit"]) {
        (Value::Array(hits), _) if !hits.is_empty() => hits.iter().map(hit).collect(),
        (Value::Array(_), _) | (_, Value::Bool(false)) => format!("{prefix}no hit\n"),
        _ => hit(out),
    }
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    match (&args.ray, &args.rays) {
        (Some(ray), _) => run_one(args, ray),
        (None, Some(rays)) => run_many(args, rays),
        (None, None) => unreachable!("clap requires --ray or --rays"),
    }
}

fn run_one(args: &Args, ray: &str) -> anyhow::Result<()> {
    let ray = parse_ray(ray)?;
    let loaded = load(&args.model)?;
    let scene = &loaded.scene;
    let tree = Tree::build(scene, TreeOptions::default());
    let out = pick_json(scene, &tree, &ray, args.all);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print!("{}", pick_text(&out, ""));
    }
    Ok(())
}

fn run_many(args: &Args, path: &Path) -> anyhow::Result<()> {
    // The input is opened first, so a missing file is named before a large
    // model is loaded.
    let (mut reader, len) = RayReader::open(path)?;
    let loaded = load(&args.model)?;
    let scene = &loaded.scene;
    let tree = Tree::build(scene, TreeOptions::default());
    let bar = match len {
        Some(len) if len < PROGRESS_MIN_BYTES => indicatif::ProgressBar::hidden(),
        _ => indicatif::ProgressBar::new(len.unwrap_or(0)),
    };
    dmu_app::progress::style_input_bar(&bar, "picking rays", len.is_some());
    let mut stdout = std::io::stdout().lock();
    let mut rays = Vec::with_capacity(RAYS_PER_BLOCK);
    loop {
        reader.read_block(&mut rays, RAYS_PER_BLOCK)?;
        // Picked and written out on all threads, collected in input order;
        // each result is one or more whole lines.
        let results: Vec<String> = rays
            .par_iter()
            .map(|(line, ray)| {
                if args.json && !args.all {
                    return nearest_json_line(scene, &tree, ray);
                }
                let out = pick_json(scene, &tree, ray, args.all);
                if args.json {
                    format!("{out}\n")
                } else {
                    pick_text(&out, &format!("line {line}: "))
                }
            })
            .collect();
        for result in &results {
            stdout.write_all(result.as_bytes())?;
        }
        stdout.flush()?;
        bar.set_position(reader.bytes);
        if rays.len() < RAYS_PER_BLOCK {
            break;
        }
    }
    bar.finish_and_clear();
    Ok(())
}
