//! `dmu bcf`: BCF issue files (`.bcfzip`), as `dmu collide --bcf` and the
//! viewer write them and other design-review tools exchange them.

use std::path::PathBuf;

use dmu_app::bcf::{Camera, Component, Projection, Topic, Viewpoint, read_bcfzip};
use dmu_app::text::{MESSAGE_CHARS, printable};
use dmu_app::units::LengthUnit;
use dmu_geom::Short;
use glam::DVec3;
use serde_json::{Value, json};

/// Read BCF issue files (`.bcfzip`, BCF 2.0, 2.1 or 3.0).
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    Show(ShowArgs),
}

/// List the topics of a BCF file: title, type, status, author and date, and
/// each viewpoint's camera, selected parts, clipping planes and snapshot.
/// Positions are shown in model units (--unit; BCF stores metres).
#[derive(Debug, clap::Args)]
struct ShowArgs {
    /// The `.bcfzip` file.
    file: PathBuf,
    /// The length of one model unit: positions are shown in it.
    #[arg(long, value_enum, default_value = "mm")]
    unit: LengthUnit,
    /// Print one JSON document.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    match &args.command {
        Command::Show(show) => run_show(show),
    }
}

fn run_show(args: &ShowArgs) -> anyhow::Result<()> {
    let topics = read_bcfzip(&args.file, args.unit.per_metre())?;
    if args.json {
        let out = json!({
            "file": args.file.display().to_string(),
            "unit": args.unit.name(),
            "topics": topics.iter().map(topic_json).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    // Every line is escaped as a whole: titles, names and GUIDs are the
    // file's text, which must neither reach the terminal as control codes
    // nor start lines of their own.
    let line = |text: String| println!("{}", printable(&text, MESSAGE_CHARS));
    line(format!("{}: {} topics", args.file.display(), topics.len()));
    for t in &topics {
        let state: Vec<&str> = [t.topic_type.as_str(), t.topic_status.as_str()]
            .into_iter()
            .filter(|s| !s.is_empty())
            .collect();
        line(format!(
            "{} {} [{}] by {} on {}",
            t.guid,
            t.title,
            state.join(", "),
            t.author,
            t.creation_date
        ));
        for v in &t.viewpoints {
            line(format!(
                "  viewpoint {}: {}",
                v.guid,
                viewpoint_line(v, args.unit)
            ));
        }
    }
    Ok(())
}

fn v3(v: DVec3) -> [f64; 3] {
    v.to_array()
}

fn component_json(c: &Component) -> Value {
    json!({
        "ifc_guid": c.ifc_guid,
        "originating_system": c.originating_system,
        "authoring_tool_id": c.authoring_tool_id,
    })
}

/// How a component is named on one line: its tool id, else its IFC GUID.
fn component_name(c: &Component) -> &str {
    c.authoring_tool_id
        .as_deref()
        .or(c.ifc_guid.as_deref())
        .unwrap_or("?")
}

fn camera_json(c: &Camera) -> Value {
    let mut out = json!({
        "eye": v3(c.eye),
        "direction": v3(c.direction),
        "up": v3(c.up),
    });
    match c.projection {
        Projection::Perspective { fov_y_deg } => {
            out["projection"] = json!("perspective");
            out["fov_y_deg"] = json!(fov_y_deg);
        }
        Projection::Orthogonal { view_height } => {
            out["projection"] = json!("orthogonal");
            out["view_height"] = json!(view_height);
        }
    }
    out
}

/// A snapshot's format and size: PNG (width and height from its header),
/// JPEG or unknown.
fn snapshot_json(bytes: &[u8]) -> Value {
    match png_size(bytes) {
        Some((w, h)) => json!({"format": "png", "bytes": bytes.len(), "width": w, "height": h}),
        None if bytes.starts_with(&[0xFF, 0xD8]) => json!({"format": "jpeg", "bytes": bytes.len()}),
        None => json!({"format": "unknown", "bytes": bytes.len()}),
    }
}

/// Width and height from a PNG's IHDR chunk, which the signature must be
/// followed by.
fn png_size(bytes: &[u8]) -> Option<(u32, u32)> {
    const SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
    let rest = bytes.strip_prefix(SIGNATURE)?;
    if rest.get(4..8)? != b"IHDR" {
        return None;
    }
    let word = |at: usize| Some(u32::from_be_bytes(rest.get(at..at + 4)?.try_into().ok()?));
    Some((word(8)?, word(12)?))
}

fn viewpoint_json(v: &Viewpoint) -> Value {
    json!({
        "guid": v.guid,
        "camera": v.camera.as_ref().map(camera_json),
        "selected": v.selected.iter().map(component_json).collect::<Vec<_>>(),
        "visibility": {
            "default_visible": v.visibility.default_visible,
            "exceptions": v.visibility.exceptions.iter().map(component_json).collect::<Vec<_>>(),
        },
        "clipping_planes": v.clipping_planes.iter().map(|p| json!({
            "location": v3(p.location),
            "direction": v3(p.direction),
        })).collect::<Vec<_>>(),
        "snapshot": v.snapshot.as_deref().map(snapshot_json),
    })
}

fn topic_json(t: &Topic) -> Value {
    json!({
        "guid": t.guid,
        "title": t.title,
        "description": t.description,
        "author": t.author,
        "creation_date": t.creation_date,
        "topic_type": t.topic_type,
        "topic_status": t.topic_status,
        "labels": t.labels,
        "viewpoints": t.viewpoints.iter().map(viewpoint_json).collect::<Vec<_>>(),
    })
}

/// A viewpoint in one line of text.
fn viewpoint_line(v: &Viewpoint, unit: LengthUnit) -> String {
    let mut parts = Vec::new();
    let p = |v: DVec3| format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z);
    if let Some(c) = &v.camera {
        let projection = match c.projection {
            Projection::Perspective { fov_y_deg } => format!("fov {fov_y_deg:.1}°"),
            Projection::Orthogonal { view_height } => {
                format!("orthogonal, {} {} high", Short(view_height), unit.name())
            }
        };
        parts.push(format!(
            "eye {} {} looking {} up {}, {projection}",
            p(c.eye),
            unit.name(),
            p(c.direction),
            p(c.up)
        ));
    }
    if !v.selected.is_empty() {
        let names: Vec<&str> = v.selected.iter().map(component_name).collect();
        parts.push(format!("selected {}", names.join(", ")));
    }
    if !v.clipping_planes.is_empty() {
        parts.push(format!("{} clipping planes", v.clipping_planes.len()));
    }
    if let Some(s) = &v.snapshot {
        let info = snapshot_json(s);
        parts.push(match (info["width"].as_u64(), info["height"].as_u64()) {
            (Some(w), Some(h)) => format!("snapshot {w}x{h} PNG"),
            _ => format!("snapshot ({}, {} bytes)", info["format"], s.len()),
        });
    }
    if parts.is_empty() {
        "no camera, selection, section or snapshot".to_owned()
    } else {
        parts.join("; ")
    }
}
