//! Writing a `.bcfzip`: `bcf.version`, `project.bcfp`, and a folder per topic
//! with its `markup.bcf`, a `.bcfv` per viewpoint and the snapshots.

use std::collections::HashSet;
use std::io::Write as _;
use std::path::Path;

use dmu_geom::Short;
use glam::DVec3;
use zip::write::SimpleFileOptions;

use super::xml::XmlWriter;
use super::{BcfError, Camera, Component, POSITION_LIMIT, Projection, Topic, Viewpoint};

/// Writes `topics` to a BCF 2.1 archive at `path`, streamed into a temporary
/// file renamed into place ([`dmu_scene::AtomicFile`]). Positions are divided
/// by `model_units_per_metre` (1000 for a millimetre model), since BCF is in
/// metres. `project_name`, when given, goes into `project.bcfp` with a fresh
/// project GUID.
///
/// Fails, writing nothing, when the name does not end in `.bcfzip`
/// ([`check_output_name`]), when a topic or viewpoint GUID is not a safe folder
/// or file name (letters, digits, `-`), when two topics (or two viewpoints of
/// a topic) share a GUID, or when a number is one [`read_bcfzip`] would
/// refuse (not finite, a position beyond ±[`POSITION_LIMIT`], a zero
/// direction): what dmu writes, dmu reads.
///
/// [`read_bcfzip`]: super::read_bcfzip
///
/// # Panics
/// When `model_units_per_metre` is not finite and positive (a caller's bug).
pub fn write_bcfzip(
    path: &Path,
    topics: &[Topic],
    project_name: Option<&str>,
    model_units_per_metre: f64,
) -> Result<(), BcfError> {
    assert!(
        model_units_per_metre.is_finite() && model_units_per_metre > 0.0,
        "model_units_per_metre must be finite and positive, not {model_units_per_metre}"
    );
    check_output_name(path)?;
    check(topics).map_err(|(topic, reason)| BcfError::Topic {
        path: path.to_owned(),
        topic,
        reason,
    })?;
    let io = |cause| BcfError::Io {
        path: path.to_owned(),
        cause,
    };
    let mut file = dmu_scene::AtomicFile::create(path).map_err(io)?;
    write_archive(
        file.file(),
        topics,
        project_name,
        1.0 / model_units_per_metre,
    )
    .map_err(|e| io(std::io::Error::other(e)))?;
    // Dropped uncommitted on an error above: the temporary file goes.
    file.commit().map_err(io)
}

/// Refuses a name to write that does not end in `.bcfzip` (any case), as
/// [`write_bcfzip`] does: callers that take frames to gather topics (the
/// viewer's snapshots) ask first.
pub fn check_output_name(path: &Path) -> Result<(), BcfError> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bcfzip"))
    {
        Ok(())
    } else {
        Err(BcfError::Name {
            path: path.to_owned(),
        })
    }
}

/// Why a topic cannot be written: its GUID and the reason.
type Refusal = (String, String);

/// Whether every topic can be written: GUIDs safe as names and unique,
/// numbers finite.
fn check(topics: &[Topic]) -> Result<(), Refusal> {
    let mut seen = HashSet::new();
    for topic in topics {
        let fail = |reason: String| (topic.guid.clone(), reason);
        check_guid(&topic.guid).map_err(|r| fail(format!("topic GUID {r}")))?;
        if !seen.insert(topic.guid.to_ascii_lowercase()) {
            return Err(fail("two topics have this GUID".to_owned()));
        }
        let mut viewpoints = HashSet::new();
        for v in &topic.viewpoints {
            check_guid(&v.guid).map_err(|r| fail(format!("viewpoint GUID {r}")))?;
            if !viewpoints.insert(v.guid.to_ascii_lowercase()) {
                return Err(fail(format!("two viewpoints have the GUID {:?}", v.guid)));
            }
            check_readable(v).map_err(|r| fail(format!("viewpoint {}: {r}", v.guid)))?;
        }
    }
    Ok(())
}

/// The archive, written to `out`; metres are model units times
/// `metres_per_unit`.
fn write_archive<W: std::io::Write + std::io::Seek>(
    out: W,
    topics: &[Topic],
    project_name: Option<&str>,
    metres_per_unit: f64,
) -> zip::result::ZipResult<()> {
    let mut zip = zip::ZipWriter::new(out);
    let now = utc_now();
    let modified = zip::DateTime::from_date_and_time(
        now.year.clamp(1980, 2107) as u16,
        now.month,
        now.day,
        now.hour,
        now.minute,
        now.second,
    )
    .unwrap_or_default();
    let deflated = SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .last_modified_time(modified);
    // Snapshots are compressed already.
    let stored = deflated.compression_method(zip::CompressionMethod::Stored);
    let mut add = |name: &str, bytes: &[u8], options| -> zip::result::ZipResult<()> {
        zip.start_file(name, options)?;
        Ok(zip.write_all(bytes)?)
    };
    add("bcf.version", version().as_bytes(), deflated)?;
    if let Some(name) = project_name {
        add("project.bcfp", project(name).as_bytes(), deflated)?;
    }
    let date = iso8601(now);
    for topic in topics {
        let folder = &topic.guid;
        add(
            &format!("{folder}/markup.bcf"),
            markup(topic, &date).as_bytes(),
            deflated,
        )?;
        for v in &topic.viewpoints {
            let visinfo = visualization_info(v, metres_per_unit);
            add(
                &format!("{folder}/{}.bcfv", v.guid),
                visinfo.as_bytes(),
                deflated,
            )?;
            if let Some(png) = &v.snapshot {
                add(&format!("{folder}/{}", snapshot_name(v, png)), png, stored)?;
            }
        }
    }
    zip.finish()?;
    Ok(())
}

/// Whether a GUID can name a folder or file: letters, digits and `-`, 1 to 64
/// of them.
fn check_guid(guid: &str) -> Result<(), String> {
    if (1..=64).contains(&guid.len())
        && guid.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
    {
        Ok(())
    } else {
        Err(format!(
            "{guid:?} must be 1 to 64 letters, digits or '-' (it names a folder or file)"
        ))
    }
}

/// Whether the reader would take every number of a viewpoint
/// ([`read_bcfzip`](super::read_bcfzip)'s rules): positions within
/// ±[`POSITION_LIMIT`] model units, directions finite and not zero, a field
/// of view in (0, 180) degrees, an orthogonal view's height positive (XML has
/// no NaN a reader would take, and the viewer exported sections beyond ±1e15
/// that its own reader refused).
fn check_readable(v: &Viewpoint) -> Result<(), String> {
    let position = |p: DVec3, what: &str| {
        if dmu_geom::is_within(p, POSITION_LIMIT) {
            Ok(())
        } else {
            Err(format!(
                "{what} {} is not finite or beyond ±{POSITION_LIMIT:e} model units",
                Short(p)
            ))
        }
    };
    let direction = |d: DVec3, what: &str| match dmu_geom::unit_vector(d) {
        Some(_) => Ok(()),
        None => Err(format!("{what} {} is no direction", Short(d))),
    };
    if let Some(c) = &v.camera {
        position(c.eye, "the camera's eye")?;
        direction(c.direction, "the camera's direction")?;
        direction(c.up, "the camera's up")?;
        match c.projection {
            Projection::Perspective { fov_y_deg } if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) => {
                return Err(format!(
                    "the field of view {} is not in (0, 180) degrees",
                    Short(fov_y_deg)
                ));
            }
            Projection::Orthogonal { view_height }
                if !(view_height > 0.0 && view_height.is_finite()) =>
            {
                return Err(format!(
                    "the view height {} is not a positive size",
                    Short(view_height)
                ));
            }
            _ => {}
        }
    }
    for p in &v.clipping_planes {
        position(p.location, "a clipping plane's location")?;
        direction(p.direction, "a clipping plane's direction")?;
    }
    Ok(())
}

/// The snapshot's file name: the viewpoint's GUID, `.jpg` for JPEG bytes read
/// from another tool, else `.png`.
fn snapshot_name(v: &Viewpoint, bytes: &[u8]) -> String {
    let ext = if bytes.starts_with(&[0xFF, 0xD8]) {
        "jpg"
    } else {
        "png"
    };
    format!("{}.{ext}", v.guid)
}

fn version() -> String {
    let mut x = XmlWriter::new();
    x.open("Version", &[("VersionId", "2.1")]);
    x.leaf("DetailedVersion", "2.1");
    x.close();
    x.finish()
}

fn project(name: &str) -> String {
    let mut x = XmlWriter::new();
    x.open("ProjectExtension", &[]);
    x.open("Project", &[("ProjectId", &super::new_guid())]);
    x.leaf("Name", name);
    x.close();
    x.empty("ExtensionSchema", &[]);
    x.close();
    x.finish()
}

/// `markup.bcf`, its elements in the order of the 2.1 schema.
fn markup(topic: &Topic, now: &str) -> String {
    let mut x = XmlWriter::new();
    x.open("Markup", &[]);
    let mut attributes = vec![("Guid", topic.guid.as_str())];
    if !topic.topic_type.is_empty() {
        attributes.push(("TopicType", &topic.topic_type));
    }
    if !topic.topic_status.is_empty() {
        attributes.push(("TopicStatus", &topic.topic_status));
    }
    x.open("Topic", &attributes);
    x.leaf("Title", &topic.title);
    for label in &topic.labels {
        x.leaf("Labels", label);
    }
    let date = if topic.creation_date.is_empty() {
        now
    } else {
        &topic.creation_date
    };
    x.leaf("CreationDate", date);
    x.leaf("CreationAuthor", &topic.author);
    if !topic.description.is_empty() {
        x.leaf("Description", &topic.description);
    }
    x.close();
    for v in &topic.viewpoints {
        x.open("Viewpoints", &[("Guid", &v.guid)]);
        x.leaf("Viewpoint", &format!("{}.bcfv", v.guid));
        if let Some(png) = &v.snapshot {
            x.leaf("Snapshot", &snapshot_name(v, png));
        }
        x.close();
    }
    x.close();
    x.finish()
}

/// A `.bcfv`, in metres, its elements in the order of the 2.1 schema.
fn visualization_info(v: &Viewpoint, metres_per_unit: f64) -> String {
    let mut x = XmlWriter::new();
    x.open("VisualizationInfo", &[("Guid", &v.guid)]);
    let visibility_is_default = v.visibility == super::Visibility::default();
    if !v.selected.is_empty() || !visibility_is_default {
        x.open("Components", &[]);
        if !v.selected.is_empty() {
            x.open("Selection", &[]);
            components(&mut x, &v.selected);
            x.close();
        }
        let default = if v.visibility.default_visible {
            "true"
        } else {
            "false"
        };
        if v.visibility.exceptions.is_empty() {
            x.empty("Visibility", &[("DefaultVisibility", default)]);
        } else {
            x.open("Visibility", &[("DefaultVisibility", default)]);
            x.open("Exceptions", &[]);
            components(&mut x, &v.visibility.exceptions);
            x.close();
            x.close();
        }
        x.close();
    }
    if let Some(camera) = &v.camera {
        camera_xml(&mut x, camera, metres_per_unit);
    }
    if !v.clipping_planes.is_empty() {
        x.open("ClippingPlanes", &[]);
        for p in &v.clipping_planes {
            x.open("ClippingPlane", &[]);
            vector(&mut x, "Location", p.location * metres_per_unit);
            vector(&mut x, "Direction", p.direction);
            x.close();
        }
        x.close();
    }
    x.close();
    x.finish()
}

fn components(x: &mut XmlWriter, list: &[Component]) {
    for c in list {
        match &c.ifc_guid {
            Some(guid) => x.open("Component", &[("IfcGuid", guid)]),
            None => x.open("Component", &[]),
        }
        if let Some(s) = &c.originating_system {
            x.leaf("OriginatingSystem", s);
        }
        if let Some(id) = &c.authoring_tool_id {
            x.leaf("AuthoringToolId", id);
        }
        x.close();
    }
}

fn camera_xml(x: &mut XmlWriter, c: &Camera, metres_per_unit: f64) {
    let name = match c.projection {
        Projection::Perspective { .. } => "PerspectiveCamera",
        Projection::Orthogonal { .. } => "OrthogonalCamera",
    };
    x.open(name, &[]);
    vector(x, "CameraViewPoint", c.eye * metres_per_unit);
    vector(x, "CameraDirection", c.direction);
    vector(x, "CameraUpVector", c.up);
    match c.projection {
        Projection::Perspective { fov_y_deg } => x.leaf("FieldOfView", &fov_y_deg.to_string()),
        Projection::Orthogonal { view_height } => x.leaf(
            "ViewToWorldScale",
            &(view_height * metres_per_unit).to_string(),
        ),
    }
    x.close();
}

/// `<name><X>…</X><Y>…</Y><Z>…</Z></name>`, each number in Rust's shortest
/// form that reads back exactly.
fn vector(x: &mut XmlWriter, name: &'static str, v: DVec3) {
    x.open(name, &[]);
    x.leaf("X", &v.x.to_string());
    x.leaf("Y", &v.y.to_string());
    x.leaf("Z", &v.z.to_string());
    x.close();
}

/// A moment in UTC, to the second.
#[derive(Clone, Copy, Debug)]
struct UtcTime {
    year: i64,
    month: u8,
    day: u8,
    hour: u8,
    minute: u8,
    second: u8,
}

/// Now, in UTC (the Unix epoch if the clock is before it).
fn utc_now() -> UtcTime {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    utc_from_unix(secs)
}

/// The UTC calendar time `secs` seconds after 1970-01-01T00:00:00Z (Howard
/// Hinnant's `civil_from_days`).
fn utc_from_unix(secs: u64) -> UtcTime {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u8;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u8;
    let year = yoe + era * 400 + i64::from(month <= 2);
    UtcTime {
        year,
        month,
        day,
        hour: (rem / 3600) as u8,
        minute: (rem / 60 % 60) as u8,
        second: (rem % 60) as u8,
    }
}

fn iso8601(t: UtcTime) -> String {
    format!(
        "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}Z",
        t.year, t.month, t.day, t.hour, t.minute, t.second
    )
}

/// Now as BCF writes dates: `2026-12-02T07:28:12Z`.
pub(super) fn utc_now_iso8601() -> String {
    iso8601(utc_now())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Calendar dates against known Unix times (from `date -u -d @N`).
    #[test]
    fn unix_times_become_calendar_dates() {
        for (secs, expected) in [
            (0, "1970-01-01T00:00:00Z"),
            (951_782_400, "2000-02-29T00:00:00Z"),
            (1_709_251_199, "2024-02-29T23:59:59Z"),
            (1_796_196_492, "2026-12-02T07:28:12Z"),
            (4_102_444_800, "2100-01-01T00:00:00Z"),
        ] {
            assert_eq!(iso8601(utc_from_unix(secs)), expected, "{secs}");
        }
    }
}
