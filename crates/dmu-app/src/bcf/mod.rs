//! BCF 2.1 issues (`.bcfzip`, buildingSMART's BIM Collaboration Format):
//! topics with viewpoints (camera, selected components, clipping planes) and
//! snapshots, written by `dmu collide --bcf` and the viewer and read back from
//! any tool that writes BCF.
//!
//! Design choices:
//! - The types hold what dmu shows and nothing else (no comments, documents,
//!   bitmaps, lines or colouring): an issue list needs a title, a camera, the
//!   parts concerned and the sections; everything else in a file read is
//!   ignored, so a file from any tool opens.
//! - Coordinates are in model units in memory and metres in the file (BCF's
//!   unit); both [`write_bcfzip`] and [`read_bcfzip`] take the model's units
//!   per metre (1000 for millimetre models such as the plant), so the viewer
//!   and the command line never convert by hand.
//! - Parts are named by their IFC `GlobalId` in `IfcGuid` when they have
//!   one (an imported IFC element), and always by their node name in
//!   `AuthoringToolId` with `OriginatingSystem` "dmu" ([`Component::of`]):
//!   CAD models carry no IFC GUIDs, and the node name is what survives from
//!   export to export. Components are found by `IfcGuid` first, then by
//!   name ([`Component::find`]).
//! - The reader is lenient in what it accepts (BCF 2.0, 2.1 and 3.0 markup,
//!   any element order, unknown elements, JPEG snapshots) and strict in what
//!   it refuses: a damaged archive, bad XML, an entry path that escapes its
//!   folder ("zip slip"), an entry larger than its cap ([`MAX_SNAPSHOT_BYTES`],
//!   [`MAX_XML_BYTES`]) or more than [`MAX_ENTRIES`] entries is a
//!   [`BcfError`] naming the file, the entry and the reason, never a panic.
//! - The archive is streamed into a temporary file renamed into place
//!   ([`dmu_scene::AtomicFile`]): a kill or a full disk leaves the previous
//!   file whole, and the snapshots are not copied into a second buffer.
//!
//! Conventions: right-handed world coordinates as in the model (Z up in the
//! plant); a camera's field of view is vertical, in degrees; a clipping plane
//! hides the half-space its direction points into (BCF's rule); GUIDs are
//! lower-case UUIDs ([`new_guid`]); dates are ISO 8601 in UTC.
//!
//! ```
//! use dmu_app::bcf::{Camera, ClippingPlane, Component, Projection, Topic, Viewpoint};
//! use glam::DVec3;
//!
//! let mut topic = Topic::new("hard: pump_3 × pipe_17", "dmu collide");
//! topic.viewpoints.push(Viewpoint {
//!     camera: Some(Camera {
//!         eye: DVec3::new(5000.0, -3000.0, 2000.0),
//!         direction: DVec3::new(-0.6, 0.6, -0.3).normalize(),
//!         up: DVec3::Z,
//!         projection: Projection::Perspective { fov_y_deg: 60.0 },
//!     }),
//!     selected: vec![Component::part("pump_3"), Component::part("pipe_17")],
//!     clipping_planes: vec![ClippingPlane { location: DVec3::ZERO, direction: DVec3::Z }],
//!     ..Viewpoint::new()
//! });
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("issues.bcfzip");
//! // The model is in millimetres: 1000 model units per metre.
//! dmu_app::bcf::write_bcfzip(&path, &[topic.clone()], Some("plant"), 1000.0)?;
//! let read = dmu_app::bcf::read_bcfzip(&path, 1000.0)?;
//! assert_eq!(read[0].title, topic.title);
//! assert_eq!(read[0].viewpoints[0].selected[1].authoring_tool_id.as_deref(), Some("pipe_17"));
//! assert!((read[0].viewpoints[0].camera.unwrap().eye - DVec3::new(5000.0, -3000.0, 2000.0)).length() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod clash;
mod read;
mod write;
mod xml;

use std::path::PathBuf;
use std::sync::Arc;

use dmu_scene::{PartId, Scene};
use glam::DVec3;

pub use clash::{CLASH_FOV_Y_DEG, CLASH_VIEW_FORWARD, ClashIssue, at_step, clash_camera};
pub use read::read_bcfzip;
pub use write::{check_output_name, write_bcfzip};

/// Most entries an archive may hold (a topic is a few: markup, viewpoints,
/// snapshots).
pub const MAX_ENTRIES: usize = 100_000;
/// Largest snapshot read, bytes uncompressed.
pub const MAX_SNAPSHOT_BYTES: u64 = 64 << 20;
/// Largest XML file (version, project, markup, viewpoint) read, bytes
/// uncompressed.
pub const MAX_XML_BYTES: u64 = 16 << 20;
/// Most bytes read from one archive in all, uncompressed.
pub const MAX_TOTAL_BYTES: u64 = 2 << 30;
/// Largest position coordinate written or read, model units: the world's
/// ([`dmu_scene::MAX_WORLD_COORDINATE`]). The writer refuses what the reader
/// would, so a file dmu writes is a file dmu reads.
pub const POSITION_LIMIT: f64 = dmu_scene::MAX_WORLD_COORDINATE;
/// What `OriginatingSystem` says for the parts dmu names.
pub const ORIGINATING_SYSTEM: &str = "dmu";

/// One issue: a title, who raised it and when, its state, and the views that
/// show it.
#[derive(Clone, Debug, PartialEq)]
pub struct Topic {
    /// The topic's GUID, also its folder in the archive (letters, digits and
    /// `-` only, so it is a safe folder name).
    pub guid: String,
    /// One line saying what is wrong.
    pub title: String,
    /// Any details; empty for none.
    pub description: String,
    /// Who raised it (BCF's `CreationAuthor`, usually an e-mail address).
    pub author: String,
    /// When it was raised, ISO 8601 (`2026-12-02T07:28:12Z`); written as the
    /// time of writing when empty.
    pub creation_date: String,
    /// `TopicType` (e.g. "Clash", "Issue"); empty for none.
    pub topic_type: String,
    /// `TopicStatus` (e.g. "Open", "Closed"); empty for none.
    pub topic_status: String,
    /// Free labels (BCF's `Labels`).
    pub labels: Vec<String>,
    /// The views of the issue, the first being the main one.
    pub viewpoints: Vec<Viewpoint>,
}

impl Topic {
    /// An open issue raised now by `author`, with a fresh GUID and no
    /// viewpoint.
    pub fn new(title: impl Into<String>, author: impl Into<String>) -> Self {
        Self {
            guid: new_guid(),
            title: title.into(),
            description: String::new(),
            author: author.into(),
            creation_date: write::utc_now_iso8601(),
            topic_type: "Issue".to_owned(),
            topic_status: "Open".to_owned(),
            labels: Vec::new(),
            viewpoints: Vec::new(),
        }
    }
}

/// One view of an issue: where the camera is, which parts are selected or
/// hidden, the section planes, and a picture.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    /// The viewpoint's GUID (letters, digits and `-`: it names its files).
    pub guid: String,
    /// The camera; none when the issue has no particular view.
    pub camera: Option<Camera>,
    /// The selected parts.
    pub selected: Vec<Component>,
    /// Which parts are shown.
    pub visibility: Visibility,
    /// Section planes, each hiding what lies on its direction's side.
    pub clipping_planes: Vec<ClippingPlane>,
    /// The picture of the view: PNG as dmu writes it, PNG or JPEG as other
    /// tools may (the first bytes say which). Shared: viewpoints of a file
    /// read that name the same snapshot hold one copy.
    pub snapshot: Option<Arc<[u8]>>,
}

impl Viewpoint {
    /// An empty view (no camera, nothing selected, everything shown) with a
    /// fresh GUID.
    pub fn new() -> Self {
        Self {
            guid: new_guid(),
            camera: None,
            selected: Vec::new(),
            visibility: Visibility::default(),
            clipping_planes: Vec::new(),
            snapshot: None,
        }
    }
}

impl Default for Viewpoint {
    fn default() -> Self {
        Self::new()
    }
}

/// Which parts a view shows: all but the exceptions, or only the exceptions.
#[derive(Clone, Debug, PartialEq)]
pub struct Visibility {
    /// Whether parts not among the exceptions are shown.
    pub default_visible: bool,
    /// The parts shown or hidden against the default.
    pub exceptions: Vec<Component>,
}

impl Default for Visibility {
    /// Everything shown.
    fn default() -> Self {
        Self {
            default_visible: true,
            exceptions: Vec::new(),
        }
    }
}

/// A part as BCF names it: an IFC GUID, or the authoring tool's own id.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Component {
    /// The IFC `GlobalId` (22 characters), when the part has one.
    pub ifc_guid: Option<String>,
    /// The tool that named the part (`"dmu"` for ours).
    pub originating_system: Option<String>,
    /// The tool's own id: for dmu, the glTF node name.
    pub authoring_tool_id: Option<String>,
}

impl Component {
    /// A dmu part named by its glTF node name.
    pub fn part(name: impl Into<String>) -> Self {
        Self {
            ifc_guid: None,
            originating_system: Some(ORIGINATING_SYSTEM.to_owned()),
            authoring_tool_id: Some(name.into()),
        }
    }

    /// A part of `scene`: its IFC `GlobalId` when it has one (an imported
    /// IFC element), and its node name.
    pub fn of(scene: &Scene, part: PartId) -> Self {
        let node = scene.part(part).node;
        Self {
            ifc_guid: scene
                .node_properties(node)
                .find(|&(k, _)| k == dmu_scene::properties::GLOBAL_ID)
                .map(|(_, v)| v.to_owned()),
            ..Self::part(scene.part_name(part))
        }
    }

    /// The part of `scene` it names: by `IfcGuid` first (among the parts'
    /// GlobalIds), then by node name ([`Scene::find_part`]).
    pub fn find(&self, scene: &Scene) -> Option<PartId> {
        let by_guid =
            self.ifc_guid
                .as_deref()
                .and_then(|g| match scene.parts_with_global_id(g).as_slice() {
                    [one] => Some(*one),
                    _ => None,
                });
        by_guid.or_else(|| {
            self.authoring_tool_id
                .as_deref()
                .and_then(|n| scene.find_part(n).ok())
        })
    }
}

/// A BCF camera: an eye, a view direction, a screen up and a projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, model units.
    pub eye: DVec3,
    /// View direction (unit length when dmu writes it).
    pub direction: DVec3,
    /// Screen up (perpendicular to `direction` when dmu writes it).
    pub up: DVec3,
    /// Perspective or orthographic.
    pub projection: Projection,
}

/// How a [`Camera`] projects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// BCF's `PerspectiveCamera`.
    Perspective {
        /// Vertical field of view, degrees, in (0, 180).
        fov_y_deg: f64,
    },
    /// BCF's `OrthogonalCamera`.
    Orthogonal {
        /// Height of the view, model units (BCF's `ViewToWorldScale`, in
        /// metres in the file).
        view_height: f64,
    },
}

impl Camera {
    /// The BCF camera of a dmu camera: the direction to the target, the up
    /// made perpendicular to it, the field of view in degrees.
    pub fn perspective(view: &dmu_geom::Camera) -> Self {
        let direction = (view.target - view.eye).normalize();
        let up = direction.cross(view.up).cross(direction).normalize();
        Self {
            eye: view.eye,
            direction,
            up,
            projection: Projection::Perspective {
                fov_y_deg: view.fov_y_rad.to_degrees(),
            },
        }
    }

    /// The dmu camera looking from the eye along the direction, its target
    /// `distance` ahead (where orbiting pivots), with the given near plane;
    /// none for an orthographic camera (dmu draws in perspective) or one whose
    /// direction or up is zero or whose up is along the direction.
    pub fn to_view(&self, distance: f64, near: f64) -> Option<dmu_geom::Camera> {
        let Projection::Perspective { fov_y_deg } = self.projection else {
            return None;
        };
        let view = dmu_geom::Camera {
            eye: self.eye,
            target: self.eye + dmu_geom::unit_vector(self.direction)? * distance,
            up: dmu_geom::unit_vector(self.up)?,
            fov_y_rad: fov_y_deg.to_radians(),
            near,
        };
        view.is_valid().then_some(view)
    }
}

/// A section plane: a point on it and the direction of the half-space it
/// hides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClippingPlane {
    /// A point on the plane, model units.
    pub location: DVec3,
    /// Points into the hidden half-space.
    pub direction: DVec3,
}

/// A fresh random (version 4) UUID, lower case, as BCF's GUIDs are written.
pub fn new_guid() -> String {
    uuid::Uuid::new_v4().to_string()
}

/// What went wrong reading or writing a BCF archive.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BcfError {
    /// The file could not be opened, read or written.
    // The cause is in the message and not a `source`: `{:#}` would print it
    // twice.
    #[error("{}: {cause}", path.display())]
    Io {
        /// The archive.
        path: PathBuf,
        /// The cause.
        cause: std::io::Error,
    },
    /// The file is not a zip archive dmu can read as BCF.
    #[error("{}: not a BCF archive: {reason}", path.display())]
    Archive {
        /// The archive.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// One entry of the archive is wrong.
    #[error("{}: {entry}: {reason}", path.display())]
    Entry {
        /// The archive.
        path: PathBuf,
        /// The entry's path in the archive.
        entry: String,
        /// What is wrong, naming the element.
        reason: String,
    },
    /// The name to write does not end in `.bcfzip`: a BCF file never
    /// replaces a model, a store or an image (the viewer's export wrote over
    /// the `.dmu` it had open).
    #[error("{}: a BCF file is written only to a name ending in .bcfzip", path.display())]
    Name {
        /// The name refused.
        path: PathBuf,
    },
    /// A topic cannot be written as given.
    #[error("{}: topic {topic:?}: {reason}", path.display())]
    Topic {
        /// The archive being written.
        path: PathBuf,
        /// The topic's GUID.
        topic: String,
        /// What is wrong.
        reason: String,
    },
}
