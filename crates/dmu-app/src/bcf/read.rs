//! Reading a `.bcfzip` written by dmu or any other tool: BCF 2.0, 2.1 and 3.0
//! markup, unknown elements ignored, every size capped.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::io::{Read, Seek};
use std::path::Path;
use std::sync::Arc;

use dmu_geom::Short;
use glam::DVec3;

use super::xml::{self, Element};
use super::{
    BcfError, Camera, ClippingPlane, Component, MAX_ENTRIES, MAX_SNAPSHOT_BYTES, MAX_TOTAL_BYTES,
    MAX_XML_BYTES, Projection, Topic, Viewpoint, Visibility,
};

/// Reads every topic of the BCF archive at `path`, in the archive's order,
/// with positions multiplied by `model_units_per_metre` (1000 for a millimetre
/// model), since BCF is in metres.
///
/// Accepts BCF 2.0, 2.1 and 3.0 (`bcf.version` may be missing); ignores what
/// dmu does not use (comments, documents, bitmaps, colours, unknown elements).
/// Refuses, with the file, the entry and the reason: a file that is not a zip
/// archive, more than [`MAX_ENTRIES`](super::MAX_ENTRIES) entries, an entry
/// path leaving its folder, an entry over its size cap, bad XML, a missing
/// markup, viewpoint or snapshot, a number that is not one, or a position
/// beyond [`dmu_scene::MAX_WORLD_COORDINATE`] model units.
///
/// # Panics
/// When `model_units_per_metre` is not finite and positive (a caller's bug).
pub fn read_bcfzip(path: &Path, model_units_per_metre: f64) -> Result<Vec<Topic>, BcfError> {
    assert!(
        model_units_per_metre.is_finite() && model_units_per_metre > 0.0,
        "model_units_per_metre must be finite and positive, not {model_units_per_metre}"
    );
    let file = dmu_scene::open_regular_file(path).map_err(|cause| BcfError::Io {
        path: path.to_owned(),
        cause,
    })?;
    Archive::open(file, path)?.topics(model_units_per_metre)
}

/// An open archive and what has been read from it so far.
struct Archive<'p, R> {
    zip: zip::ZipArchive<R>,
    /// The entries' paths, in the archive's order.
    names: Vec<String>,
    path: &'p Path,
    /// Uncompressed bytes read so far, against [`MAX_TOTAL_BYTES`].
    read: u64,
    /// Snapshots read so far, by entry: viewpoints naming the same snapshot
    /// share one copy (40 viewpoints of one 63 MiB snapshot took 2.1 GB).
    snapshots: HashMap<String, Arc<[u8]>>,
}

impl<'p, R: Read + Seek> Archive<'p, R> {
    fn open(reader: R, path: &'p Path) -> Result<Self, BcfError> {
        let zip = zip::ZipArchive::new(reader).map_err(|e| BcfError::Archive {
            path: path.to_owned(),
            reason: e.to_string(),
        })?;
        if zip.len() > MAX_ENTRIES {
            return Err(BcfError::Archive {
                path: path.to_owned(),
                reason: format!("{} entries, more than the {MAX_ENTRIES} read", zip.len()),
            });
        }
        let mut names = Vec::with_capacity(zip.len());
        for (index, name) in zip.file_names().enumerate() {
            let name = name.map_err(|e| BcfError::Archive {
                path: path.to_owned(),
                reason: format!("entry {index}: {e}"),
            })?;
            if !is_enclosed(&name) {
                return Err(BcfError::Entry {
                    path: path.to_owned(),
                    entry: name.into_owned(),
                    reason: "the path leaves the archive's folder (absolute, '..', '\\' or a drive): refused".to_owned(),
                });
            }
            names.push(name.into_owned());
        }
        Ok(Self {
            zip,
            names,
            path,
            read: 0,
            snapshots: HashMap::new(),
        })
    }

    fn entry_error(&self, entry: &str, reason: impl Into<String>) -> BcfError {
        BcfError::Entry {
            path: self.path.to_owned(),
            entry: entry.to_owned(),
            reason: reason.into(),
        }
    }

    /// The entry's bytes, refused beyond `cap` (whatever its header claims)
    /// or beyond the archive's total.
    fn bytes(&mut self, name: &str, cap: u64) -> Result<Vec<u8>, BcfError> {
        let total_left = MAX_TOTAL_BYTES.saturating_sub(self.read);
        let limit = cap.min(total_left);
        let result = (|| {
            let file = self.zip.by_name(name).map_err(|e| e.to_string())?;
            let mut bytes = Vec::new();
            file.take(limit + 1)
                .read_to_end(&mut bytes)
                .map_err(|e| e.to_string())?;
            if bytes.len() as u64 > limit {
                return Err(if limit == cap {
                    format!("larger than the {cap} bytes read for such an entry")
                } else {
                    format!("the archive holds more than the {MAX_TOTAL_BYTES} bytes read in all")
                });
            }
            Ok(bytes)
        })();
        let bytes = result.map_err(|reason| self.entry_error(name, reason))?;
        self.read += bytes.len() as u64;
        Ok(bytes)
    }

    /// The entry parsed as XML, its root element checked to be `root`.
    fn xml(&mut self, name: &str, root: &str) -> Result<Element, BcfError> {
        let bytes = self.bytes(name, MAX_XML_BYTES)?;
        let element = xml::parse(&bytes).map_err(|reason| self.entry_error(name, reason))?;
        if element.name != root {
            return Err(self.entry_error(
                name,
                format!("the root element is <{}>, not <{root}>", element.name),
            ));
        }
        Ok(element)
    }

    /// The snapshot entry's bytes, read once however many viewpoints name it.
    fn snapshot(&mut self, entry: String) -> Result<Arc<[u8]>, BcfError> {
        if let Some(bytes) = self.snapshots.get(&entry) {
            return Ok(Arc::clone(bytes));
        }
        let bytes: Arc<[u8]> = self.bytes(&entry, MAX_SNAPSHOT_BYTES)?.into();
        self.snapshots.insert(entry, Arc::clone(&bytes));
        Ok(bytes)
    }

    fn has(&self, name: &str) -> bool {
        self.zip.index_for_name(name).is_some()
    }

    fn topics(mut self, scale: f64) -> Result<Vec<Topic>, BcfError> {
        let names = std::mem::take(&mut self.names);
        // The topic folders in the archive's order; folders with viewpoints.
        let mut folders = Vec::new();
        let mut with_viewpoints = BTreeSet::new();
        for name in &names {
            let Some((folder, file)) = name.split_once('/') else {
                continue;
            };
            if file == "markup.bcf" {
                folders.push(folder.to_owned());
            } else if file.ends_with(".bcfv") && !file.contains('/') {
                with_viewpoints.insert(folder.to_owned());
            }
        }
        // A set, not a scan of the folders per folder: 99,998 topics took
        // quadratic time.
        let with_markup: HashSet<&str> = folders.iter().map(String::as_str).collect();
        if let Some(orphan) = with_viewpoints
            .iter()
            .find(|f| !with_markup.contains(f.as_str()))
        {
            return Err(self.entry_error(
                &format!("{orphan}/markup.bcf"),
                "missing: the folder has viewpoints but no markup",
            ));
        }
        if self.has("bcf.version") {
            let version = self.xml("bcf.version", "Version")?;
            let id = version.attribute("VersionId").unwrap_or_default();
            if !(id.starts_with("2.") || id.starts_with("3.")) {
                return Err(self.entry_error(
                    "bcf.version",
                    format!("VersionId {id:?}: dmu reads BCF 2.0, 2.1 and 3.0"),
                ));
            }
        } else if folders.is_empty() {
            return Err(BcfError::Archive {
                path: self.path.to_owned(),
                reason: "no bcf.version and no topic folder with a markup.bcf".to_owned(),
            });
        }
        folders
            .iter()
            .map(|folder| self.topic(folder, scale))
            .collect()
    }

    fn topic(&mut self, folder: &str, scale: f64) -> Result<Topic, BcfError> {
        let entry = format!("{folder}/markup.bcf");
        let markup = self.xml(&entry, "Markup")?;
        let topic = markup
            .child("Topic")
            .ok_or_else(|| self.entry_error(&entry, "no <Topic> element"))?;
        let text = |name: &str| topic.child_text(name).unwrap_or_default().to_owned();
        // 2.x: repeated <Labels>text</Labels>; 3.0: <Labels><Label>text</Label>…</Labels>.
        let mut labels = Vec::new();
        for l in topic.children_named("Labels") {
            if l.child("Label").is_some() {
                labels.extend(l.children_named("Label").map(|c| c.text.trim().to_owned()));
            } else {
                labels.push(l.text.trim().to_owned());
            }
        }
        // 2.x: Markup/Viewpoints (one per viewpoint); 3.0: Topic/Viewpoints/ViewPoint.
        let mut references = Vec::new();
        for name in ["Viewpoints", "ViewPoint"] {
            markup.descendants_named(name, &mut references);
        }
        let mut viewpoints = Vec::new();
        for r in references {
            let Some(file) = r.child_text("Viewpoint") else {
                continue; // a 3.0 <Viewpoints> list, or a 2.x element without a file
            };
            let snapshot = r.child_text("Snapshot").filter(|s| !s.is_empty());
            let guid = r.attribute("Guid");
            viewpoints.push(self.viewpoint(folder, &entry, file, snapshot, guid, scale)?);
        }
        // BCF 2.0's default names, when the markup lists no viewpoint.
        if viewpoints.is_empty() && self.has(&format!("{folder}/viewpoint.bcfv")) {
            let snapshot = self
                .has(&format!("{folder}/snapshot.png"))
                .then_some("snapshot.png");
            viewpoints.push(self.viewpoint(
                folder,
                &entry,
                "viewpoint.bcfv",
                snapshot,
                None,
                scale,
            )?);
        }
        Ok(Topic {
            guid: topic
                .attribute("Guid")
                .map_or_else(|| folder.to_owned(), str::to_owned),
            title: text("Title"),
            description: text("Description"),
            author: text("CreationAuthor"),
            creation_date: text("CreationDate"),
            topic_type: topic.attribute("TopicType").unwrap_or_default().to_owned(),
            topic_status: topic
                .attribute("TopicStatus")
                .unwrap_or_default()
                .to_owned(),
            labels,
            viewpoints,
        })
    }

    /// The viewpoint in `folder/file` with its snapshot, as the markup `entry`
    /// names them.
    fn viewpoint(
        &mut self,
        folder: &str,
        markup: &str,
        file: &str,
        snapshot: Option<&str>,
        guid: Option<&str>,
        scale: f64,
    ) -> Result<Viewpoint, BcfError> {
        let inside = |what: &str, name: &str| -> Result<String, BcfError> {
            let entry = format!("{folder}/{name}");
            if name.is_empty() || name.contains(['/', '\\']) || name == ".." {
                return Err(self.entry_error(
                    markup,
                    format!("<{what}> {name:?} is not a file name in the topic's folder"),
                ));
            }
            if !self.has(&entry) {
                return Err(self.entry_error(
                    markup,
                    format!("<{what}> names {entry:?}, which the archive lacks"),
                ));
            }
            Ok(entry)
        };
        let entry = inside("Viewpoint", file)?;
        let snapshot_entry = snapshot.map(|s| inside("Snapshot", s)).transpose()?;
        let info = self.xml(&entry, "VisualizationInfo")?;
        let fail = |reason: String| self.entry_error(&entry, reason);
        let guid = guid
            .or_else(|| info.attribute("Guid"))
            .map_or_else(|| file.trim_end_matches(".bcfv").to_owned(), str::to_owned);
        let mut selected = Vec::new();
        let mut visibility = Visibility::default();
        if let Some(components) = info.child("Components") {
            if let Some(selection) = components.child("Selection") {
                selected.extend(selection.children_named("Component").map(component));
            }
            if let Some(v) = components.child("Visibility") {
                // The 2.1 schema's default is false.
                visibility.default_visible = boolean(v.attribute("DefaultVisibility"))
                    .map_err(|r| fail(format!("Components/Visibility: {r}")))?
                    .unwrap_or(false);
                if let Some(exceptions) = v.child("Exceptions") {
                    visibility.exceptions = exceptions
                        .children_named("Component")
                        .map(component)
                        .collect();
                }
            }
            // BCF 2.0: <Component Selected="true"> directly under <Components>.
            for c in components.children_named("Component") {
                let flag = boolean(c.attribute("Selected"))
                    .map_err(|r| fail(format!("Components/Component: {r}")))?;
                if flag == Some(true) {
                    selected.push(component(c));
                }
            }
        }
        let camera = camera(&info, scale).map_err(fail)?;
        let mut clipping_planes = Vec::new();
        if let Some(planes) = info.child("ClippingPlanes") {
            for p in planes.children_named("ClippingPlane") {
                let at = "ClippingPlanes/ClippingPlane";
                let location =
                    position(p, "Location", scale).map_err(|r| fail(format!("{at}/{r}")))?;
                let direction = direction(p, "Direction").map_err(|r| fail(format!("{at}/{r}")))?;
                clipping_planes.push(ClippingPlane {
                    location,
                    direction,
                });
            }
        }
        let snapshot = match snapshot_entry {
            Some(s) => Some(self.snapshot(s)?),
            None => None,
        };
        Ok(Viewpoint {
            guid,
            camera,
            selected,
            visibility,
            clipping_planes,
            snapshot,
        })
    }
}

/// Whether an entry's path stays in the archive's folder once extracted: not
/// absolute, no `..`, no backslash, no drive.
fn is_enclosed(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('/')
        && !name.contains(['\\', '\0'])
        && !name
            .split('/')
            .any(|part| part == ".." || part.contains(':'))
}

fn component(c: &Element) -> Component {
    let text = |name: &str| c.child_text(name).map(str::to_owned);
    Component {
        ifc_guid: c.attribute("IfcGuid").map(str::to_owned),
        // BCF 2.0 allowed these as attributes too.
        originating_system: text("OriginatingSystem")
            .or_else(|| c.attribute("OriginatingSystem").map(str::to_owned)),
        authoring_tool_id: text("AuthoringToolId")
            .or_else(|| c.attribute("AuthoringToolId").map(str::to_owned)),
    }
}

/// An `xs:boolean` attribute, none when absent.
fn boolean(value: Option<&str>) -> Result<Option<bool>, String> {
    match value.map(str::trim) {
        None => Ok(None),
        Some("true" | "1") => Ok(Some(true)),
        Some("false" | "0") => Ok(Some(false)),
        Some(other) => Err(format!("{other:?} is not true or false")),
    }
}

/// The finite number in the child `name` of `parent`; the error names the
/// element path from `parent`.
fn number(parent: &Element, name: &str) -> Result<f64, String> {
    let text = parent
        .child_text(name)
        .ok_or_else(|| format!("{}: no <{name}>", parent.name))?;
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!(
            "{}/{name}: {:?} is not a finite number",
            parent.name,
            crate::text::printable(text, 40)
        )),
    }
}

fn vector(parent: &Element, name: &str) -> Result<DVec3, String> {
    let v = parent
        .child(name)
        .ok_or_else(|| format!("{}: no <{name}>", parent.name))?;
    let with_path = |r: String| format!("{}/{r}", parent.name);
    Ok(DVec3::new(
        number(v, "X").map_err(with_path)?,
        number(v, "Y").map_err(with_path)?,
        number(v, "Z").map_err(with_path)?,
    ))
}

/// A point, metres in the file, model units back, within the world's range
/// ([`super::POSITION_LIMIT`], which the writer keeps too, and a rounding of
/// the unit conversion above it).
fn position(parent: &Element, name: &str, scale: f64) -> Result<DVec3, String> {
    let p = vector(parent, name)? * scale;
    let limit = super::POSITION_LIMIT;
    if !dmu_geom::is_within(p, limit * (1.0 + 1e-12)) {
        return Err(format!(
            "{}/{name}: {} is beyond ±{limit:e} model units",
            parent.name,
            Short(p)
        ));
    }
    Ok(p)
}

/// A direction: any non-zero vector, kept as written. Whatever its length it
/// has a unit vector ([`dmu_geom::unit_vector`]: `[1e300, 0, 0]` is X, where
/// a plain normalisation gave the zero vector and the viewer skipped the
/// topic).
fn direction(parent: &Element, name: &str) -> Result<DVec3, String> {
    let d = vector(parent, name)?;
    match dmu_geom::unit_vector(d) {
        Some(_) => Ok(d),
        None => Err(format!(
            "{}/{name}: the zero vector is no direction",
            parent.name
        )),
    }
}

/// The viewpoint's camera: the perspective one, else the orthogonal one.
fn camera(info: &Element, scale: f64) -> Result<Option<Camera>, String> {
    let (c, perspective) = match (
        info.child("PerspectiveCamera"),
        info.child("OrthogonalCamera"),
    ) {
        (Some(c), _) => (c, true),
        (None, Some(c)) => (c, false),
        (None, None) => return Ok(None),
    };
    let eye = position(c, "CameraViewPoint", scale)?;
    let direction = direction(c, "CameraDirection")?;
    let up = direction_or_z(c)?;
    let projection = if perspective {
        let fov_y_deg = number(c, "FieldOfView")?;
        if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) {
            return Err(format!(
                "PerspectiveCamera/FieldOfView: {} is not in (0, 180) degrees",
                Short(fov_y_deg)
            ));
        }
        Projection::Perspective { fov_y_deg }
    } else {
        let view_height = number(c, "ViewToWorldScale")? * scale;
        if !(view_height > 0.0 && view_height.is_finite()) {
            return Err(format!(
                "OrthogonalCamera/ViewToWorldScale: {} model units is not a positive size",
                Short(view_height)
            ));
        }
        Projection::Orthogonal { view_height }
    };
    Ok(Some(Camera {
        eye,
        direction,
        up,
        projection,
    }))
}

/// The camera's up vector; Z when the file gives none (the schema requires
/// one, but a missing up has an obvious meaning in a Z-up world).
fn direction_or_z(c: &Element) -> Result<DVec3, String> {
    if c.child("CameraUpVector").is_some() {
        direction(c, "CameraUpVector")
    } else {
        Ok(DVec3::Z)
    }
}
