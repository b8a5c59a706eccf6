//! BCF archives: random topics survive a write and a read; hand-written BCF
//! 2.0 and 3.0 files read as their text says; hostile archives are refused
//! with one clear line, and mangled ones never panic. (The third-party reader
//! and writer, IfcOpenShell's bcf-client, is in crates/dmu-py/tests/test_bcf.py.)

use std::io::Write as _;
use std::path::{Path, PathBuf};

use dmu_app::bcf::{
    BcfError, Camera, ClippingPlane, Component, Projection, Topic, Viewpoint, Visibility,
    read_bcfzip, write_bcfzip,
};
use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// A zip of `(name, bytes)` entries, deflated.
fn zip_of(entries: &[(&str, &[u8])]) -> Vec<u8> {
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        zip.start_file(*name, options).unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

/// `bytes` saved as `name` in `dir`.
fn file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The error reading `bytes` as an archive, as one line.
fn read_error(bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = file(dir.path(), "hostile.bcfzip", bytes);
    let message = read_bcfzip(&path, 1000.0).unwrap_err().to_string();
    assert!(
        message.starts_with(&path.display().to_string()),
        "{message}"
    );
    assert!(!message.contains('\n'), "{message}");
    message
}

const VERSION: &[u8] = br#"<?xml version="1.0"?><Version VersionId="2.1"/>"#;
const MARKUP: &str = r#"<Markup><Topic Guid="t1"><Title>x</Title></Topic>
<Viewpoints Guid="v1"><Viewpoint>v1.bcfv</Viewpoint></Viewpoints></Markup>"#;

fn visinfo(camera: &str) -> String {
    format!(r#"<VisualizationInfo Guid="v1">{camera}</VisualizationInfo>"#)
}

const PERSPECTIVE: &str = "<PerspectiveCamera><CameraViewPoint><X>1</X><Y>2</Y><Z>3</Z></CameraViewPoint>\
<CameraDirection><X>0</X><Y>1</Y><Z>0</Z></CameraDirection>\
<CameraUpVector><X>0</X><Y>0</Y><Z>1</Z></CameraUpVector><FieldOfView>FOV</FieldOfView></PerspectiveCamera>";

// Strategies for random topics.

/// Text with XML's special characters, control characters, non-ASCII and
/// whitespace inside.
fn text() -> impl Strategy<Value = String> {
    proptest::collection::vec(
        prop_oneof![
            Just('a'),
            Just('Z'),
            Just('7'),
            Just(' '),
            Just('<'),
            Just('>'),
            Just('&'),
            Just('"'),
            Just('\''),
            Just('\n'),
            Just('\t'),
            Just('\r'),
            Just('\u{1}'),
            Just('é'),
            Just('×'),
            Just('\u{1F600}'),
            Just('\u{FFFF}'),
        ],
        0..12,
    )
    .prop_map(|chars| chars.into_iter().collect())
}

/// What a string reads back as: the characters XML cannot hold replaced by
/// U+FFFD, then trimmed (readers trim element text; dmu writes nothing that
/// needs leading or trailing blanks).
fn as_read(s: &str) -> String {
    s.chars()
        .map(|c| match c {
            '\u{1}' | '\u{FFFF}' => '\u{FFFD}',
            c => c,
        })
        .collect::<String>()
        .trim()
        .to_owned()
}

fn vector(range: f64) -> impl Strategy<Value = DVec3> {
    (-range..range, -range..range, -range..range).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn direction() -> impl Strategy<Value = DVec3> {
    vector(1.0).prop_filter("non-zero", |v| v.length() > 1e-3)
}

fn component() -> impl Strategy<Value = Component> {
    (
        proptest::option::of("[0-9A-Za-z_$]{22}"),
        proptest::option::of(text()),
        proptest::option::of(text()),
    )
        .prop_map(
            |(ifc_guid, originating_system, authoring_tool_id)| Component {
                ifc_guid,
                originating_system,
                authoring_tool_id,
            },
        )
}

fn camera() -> impl Strategy<Value = Camera> {
    (
        vector(1e6),
        direction(),
        direction(),
        prop_oneof![
            (0.5..179.5f64).prop_map(|fov_y_deg| Projection::Perspective { fov_y_deg }),
            (1e-3..1e5f64).prop_map(|view_height| Projection::Orthogonal { view_height }),
        ],
    )
        .prop_map(|(eye, direction, up, projection)| Camera {
            eye,
            direction,
            up,
            projection,
        })
}

fn viewpoint() -> impl Strategy<Value = Viewpoint> {
    (
        proptest::option::of(camera()),
        proptest::collection::vec(component(), 0..4),
        any::<bool>(),
        proptest::collection::vec(component(), 0..3),
        proptest::collection::vec((vector(1e6), direction()), 0..4),
        proptest::option::of(proptest::collection::vec(any::<u8>(), 0..300)),
    )
        .prop_map(
            |(camera, selected, default_visible, exceptions, planes, snapshot)| Viewpoint {
                camera,
                selected,
                visibility: Visibility {
                    default_visible,
                    exceptions,
                },
                clipping_planes: planes
                    .into_iter()
                    .map(|(location, direction)| ClippingPlane {
                        location,
                        direction,
                    })
                    .collect(),
                snapshot: snapshot.map(Into::into),
                ..Viewpoint::new()
            },
        )
}

fn topic() -> impl Strategy<Value = Topic> {
    (
        text(),
        text(),
        text(),
        text(),
        text(),
        proptest::collection::vec(text(), 0..3),
        proptest::collection::vec(viewpoint(), 0..3),
    )
        .prop_map(
            |(title, description, author, topic_type, topic_status, labels, viewpoints)| Topic {
                description,
                topic_type,
                topic_status,
                labels,
                viewpoints,
                ..Topic::new(title, author)
            },
        )
}

fn close(a: DVec3, b: DVec3, what: &str) -> Result<(), TestCaseError> {
    let tolerance = 1e-12 * a.abs().max_element().max(1.0);
    prop_assert!(
        (a - b).abs().max_element() <= tolerance,
        "{what}: {a} read back as {b}"
    );
    Ok(())
}

/// What a component reads back as.
fn component_as_read(c: &Component) -> Component {
    Component {
        ifc_guid: c.ifc_guid.clone(),
        originating_system: c.originating_system.as_deref().map(as_read),
        authoring_tool_id: c.authoring_tool_id.as_deref().map(as_read),
    }
}

fn check_viewpoint(w: &Viewpoint, r: &Viewpoint, scale: f64) -> Result<(), TestCaseError> {
    prop_assert_eq!(&w.guid, &r.guid);
    prop_assert_eq!(&w.snapshot, &r.snapshot);
    let selected: Vec<_> = w.selected.iter().map(component_as_read).collect();
    prop_assert_eq!(selected, r.selected.clone());
    let exceptions: Vec<_> = w
        .visibility
        .exceptions
        .iter()
        .map(component_as_read)
        .collect();
    // Nothing selected and everything shown: no <Components> at all.
    prop_assert_eq!(w.visibility.default_visible, r.visibility.default_visible);
    prop_assert_eq!(exceptions, r.visibility.exceptions.clone());
    prop_assert_eq!(w.clipping_planes.len(), r.clipping_planes.len());
    for (a, b) in w.clipping_planes.iter().zip(&r.clipping_planes) {
        close(a.location, b.location, "clipping plane location")?;
        prop_assert_eq!(a.direction, b.direction, "directions are written exactly");
    }
    match (&w.camera, &r.camera) {
        (None, None) => {}
        (Some(a), Some(b)) => {
            close(a.eye, b.eye, "eye")?;
            prop_assert_eq!(a.direction, b.direction);
            prop_assert_eq!(a.up, b.up);
            match (a.projection, b.projection) {
                (
                    Projection::Perspective { fov_y_deg: x },
                    Projection::Perspective { fov_y_deg: y },
                ) => prop_assert_eq!(x, y),
                (
                    Projection::Orthogonal { view_height: x },
                    Projection::Orthogonal { view_height: y },
                ) => prop_assert!(
                    (x - y).abs() <= 1e-12 * x,
                    "{x} read as {y} (scale {scale})"
                ),
                (a, b) => prop_assert!(false, "{a:?} read back as {b:?}"),
            }
        }
        (a, b) => prop_assert!(false, "camera {a:?} read back as {b:?}"),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Whatever is written reads back: text (escaped, control characters
    /// replaced, trimmed), GUIDs, labels, components, visibility, snapshots
    /// exactly; positions through the unit scale to 1e-12.
    #[test]
    fn topics_round_trip(
        topics in proptest::collection::vec(topic(), 0..4),
        scale in prop_oneof![Just(1.0), Just(1000.0), Just(25.4), 1e-3..1e4f64],
        project in proptest::option::of(text()),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("round.bcfzip");
        write_bcfzip(&path, &topics, project.as_deref(), scale).unwrap();
        let read = read_bcfzip(&path, scale).unwrap();
        prop_assert_eq!(read.len(), topics.len());
        for (w, r) in topics.iter().zip(&read) {
            prop_assert_eq!(&w.guid, &r.guid);
            prop_assert_eq!(as_read(&w.title), r.title.clone());
            prop_assert_eq!(as_read(&w.description), r.description.clone());
            prop_assert_eq!(as_read(&w.author), r.author.clone());
            prop_assert_eq!(&w.creation_date, &r.creation_date);
            // Attributes keep their blanks (written as character references).
            let attribute = |s: &str| s.replace(['\u{1}', '\u{FFFF}'], "\u{FFFD}");
            prop_assert_eq!(attribute(&w.topic_type), r.topic_type.clone());
            prop_assert_eq!(attribute(&w.topic_status), r.topic_status.clone());
            let labels: Vec<_> = w.labels.iter().map(|l| as_read(l)).collect();
            prop_assert_eq!(labels, r.labels.clone());
            prop_assert_eq!(w.viewpoints.len(), r.viewpoints.len());
            for (a, b) in w.viewpoints.iter().zip(&r.viewpoints) {
                check_viewpoint(a, b, scale)?;
            }
        }
    }

    /// A written archive with bytes overwritten or cut short reads as topics
    /// or as an error, never a panic.
    #[test]
    fn mangled_archives_never_panic(
        topics in proptest::collection::vec(topic(), 1..3),
        cuts in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        truncate in proptest::option::of(any::<prop::sample::Index>()),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mangled.bcfzip");
        write_bcfzip(&path, &topics, None, 1.0).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        for (at, value) in cuts {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if let Some(at) = truncate {
            bytes.truncate(at.index(bytes.len()));
        }
        std::fs::write(&path, &bytes).unwrap();
        if let Err(e) = read_bcfzip(&path, 1.0) {
            prop_assert!(!e.to_string().contains('\n'), "{e}");
        }
    }
}

/// Millimetre models: a camera 1.5 m up is 1500 model units, and the file says
/// 1.5 (the unit conversion is read from the file's text, not from our own
/// reader).
#[test]
fn millimetres_become_metres_in_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("units.bcfzip");
    let mut topic = Topic::new("units", "test");
    let vp = Viewpoint {
        camera: Some(Camera {
            eye: DVec3::new(0.0, 0.0, 1500.0),
            direction: DVec3::X,
            up: DVec3::Z,
            projection: Projection::Orthogonal { view_height: 250.0 },
        }),
        clipping_planes: vec![ClippingPlane {
            location: DVec3::new(0.0, -2000.0, 0.0),
            direction: DVec3::NEG_Y,
        }],
        ..Viewpoint::new()
    };
    topic.viewpoints.push(vp.clone());
    write_bcfzip(&path, &[topic.clone()], None, 1000.0).unwrap();
    let mut zip = zip::ZipArchive::new(std::fs::File::open(&path).unwrap()).unwrap();
    let mut xml = String::new();
    std::io::Read::read_to_string(
        &mut zip
            .by_name(&format!("{}/{}.bcfv", topic.guid, vp.guid))
            .unwrap(),
        &mut xml,
    )
    .unwrap();
    let squeezed: String = xml.split_whitespace().collect();
    assert!(
        squeezed.contains("<CameraViewPoint><X>0</X><Y>0</Y><Z>1.5</Z></CameraViewPoint>"),
        "{xml}"
    );
    assert!(
        squeezed.contains("<ViewToWorldScale>0.25</ViewToWorldScale>"),
        "{xml}"
    );
    assert!(
        squeezed.contains("<Location><X>0</X><Y>-2</Y><Z>0</Z></Location>"),
        "{xml}"
    );
    // No stray file is left beside the archive (written through a temporary).
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1);
}

/// A BCF 3.0 markup (viewpoints inside the topic, labels in a list) and a BCF
/// 2.0 one (components flagged `Selected`, the default file names) read as
/// their text says.
#[test]
fn bcf_3_0_and_2_0_read_as_written() {
    let markup3 = r#"<?xml version="1.0" encoding="UTF-8"?>
<Markup xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <Topic Guid="a1" TopicType="Clash" TopicStatus="Open" ServerAssignedId="X-1">
    <Title> Pipe &amp; duct </Title>
    <Priority>High</Priority>
    <CreationDate>2026-01-02T03:04:05Z</CreationDate>
    <CreationAuthor>bob@example.com</CreationAuthor>
    <Labels><Label>mech</Label><Label>urgent</Label></Labels>
    <Viewpoints>
      <ViewPoint Guid="b2"><Viewpoint>b2.bcfv</Viewpoint><Snapshot>b2.jpg</Snapshot></ViewPoint>
    </Viewpoints>
    <Comments><Comment Guid="c"><Date>2026-01-02T03:04:05Z</Date><Author>x</Author><Comment>hi</Comment><Viewpoint Guid="b2"/></Comment></Comments>
  </Topic>
</Markup>"#;
    let visinfo3 = r#"<VisualizationInfo Guid="b2">
  <Components><Selection><Component IfcGuid="0123456789abcdefghijkl"><AuthoringToolId>pump_3</AuthoringToolId></Component></Selection>
  <Visibility DefaultVisibility="false"><Exceptions><Component><AuthoringToolId>pump_3</AuthoringToolId></Component></Exceptions></Visibility></Components>
  <PerspectiveCamera><CameraViewPoint><X>1</X><Y>2</Y><Z>3</Z></CameraViewPoint>
    <CameraDirection><X>0</X><Y>1</Y><Z>0</Z></CameraDirection>
    <CameraUpVector><X>0</X><Y>0</Y><Z>1</Z></CameraUpVector>
    <FieldOfView>45</FieldOfView><AspectRatio>1.5</AspectRatio></PerspectiveCamera>
  <Lines><Line><StartPoint><X>0</X><Y>0</Y><Z>0</Z></StartPoint><EndPoint><X>1</X><Y>0</Y><Z>0</Z></EndPoint></Line></Lines>
  <ClippingPlanes><ClippingPlane><Location><X>0.5</X><Y>0</Y><Z>0</Z></Location><Direction><X>-1</X><Y>0</Y><Z>0</Z></Direction></ClippingPlane></ClippingPlanes>
</VisualizationInfo>"#;
    let jpeg = [0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3];
    let markup2 = r#"<Markup><Topic Guid="c3"><Title>old</Title></Topic></Markup>"#;
    let visinfo2 = r#"<VisualizationInfo><Components>
  <Component IfcGuid="g1" Selected="true"><AuthoringToolId>a</AuthoringToolId></Component>
  <Component IfcGuid="g2" Selected="false"/></Components></VisualizationInfo>"#;
    let bytes = zip_of(&[
        ("bcf.version", br#"<Version VersionId="3.0"/>"#),
        ("a1/markup.bcf", markup3.as_bytes()),
        ("a1/b2.bcfv", visinfo3.as_bytes()),
        ("a1/b2.jpg", &jpeg),
        ("c3/markup.bcf", markup2.as_bytes()),
        ("c3/viewpoint.bcfv", visinfo2.as_bytes()),
        ("c3/snapshot.png", b"\x89PNG"),
    ]);
    let dir = tempfile::tempdir().unwrap();
    let path = file(dir.path(), "v3.bcfzip", &bytes);
    let topics = read_bcfzip(&path, 1000.0).unwrap();
    assert_eq!(topics.len(), 2);
    let t = &topics[0];
    assert_eq!(
        (t.guid.as_str(), t.title.as_str(), t.author.as_str()),
        ("a1", "Pipe & duct", "bob@example.com")
    );
    assert_eq!(
        (t.topic_type.as_str(), t.topic_status.as_str()),
        ("Clash", "Open")
    );
    assert_eq!(t.creation_date, "2026-01-02T03:04:05Z");
    assert_eq!(t.labels, ["mech", "urgent"]);
    assert_eq!(
        t.viewpoints.len(),
        1,
        "the comment's viewpoint reference is no viewpoint"
    );
    let v = &t.viewpoints[0];
    assert_eq!(v.guid, "b2");
    assert_eq!(v.snapshot.as_deref(), Some(&jpeg[..]));
    assert_eq!(
        v.selected,
        [Component {
            ifc_guid: Some("0123456789abcdefghijkl".into()),
            originating_system: None,
            authoring_tool_id: Some("pump_3".into()),
        }]
    );
    assert!(!v.visibility.default_visible);
    assert_eq!(v.visibility.exceptions.len(), 1);
    assert_eq!(
        v.camera,
        Some(Camera {
            eye: DVec3::new(1000.0, 2000.0, 3000.0),
            direction: DVec3::Y,
            up: DVec3::Z,
            projection: Projection::Perspective { fov_y_deg: 45.0 },
        })
    );
    assert_eq!(
        v.clipping_planes,
        [ClippingPlane {
            location: DVec3::new(500.0, 0.0, 0.0),
            direction: DVec3::NEG_X,
        }]
    );
    let old = &topics[1];
    assert_eq!(old.viewpoints.len(), 1);
    assert_eq!(old.viewpoints[0].selected.len(), 1);
    assert_eq!(
        old.viewpoints[0].selected[0].ifc_guid.as_deref(),
        Some("g1")
    );
    assert_eq!(old.viewpoints[0].snapshot.as_deref(), Some(&b"\x89PNG"[..]));
}

/// A dmu camera becomes a BCF one and back: the same eye, direction and field
/// of view; the up made perpendicular.
#[test]
fn cameras_convert_both_ways() {
    let view = dmu_geom::Camera {
        eye: DVec3::new(1e6, 2e6, 300.0),
        target: DVec3::new(1e6 + 30.0, 2e6 + 40.0, 300.0),
        up: DVec3::new(0.0, 0.3, 1.0),
        fov_y_rad: 1.0,
        near: 0.5,
    };
    let bcf = Camera::perspective(&view);
    assert!((bcf.direction - DVec3::new(0.6, 0.8, 0.0)).length() < 1e-15);
    assert!(bcf.up.dot(bcf.direction).abs() < 1e-15);
    // Gram–Schmidt: the up less its part along the direction.
    let d = DVec3::new(0.6, 0.8, 0.0);
    let expected_up = (view.up - view.up.dot(d) * d).normalize();
    assert!((bcf.up - expected_up).length() < 1e-15, "{}", bcf.up);
    let back = bcf.to_view(50.0, 0.5).unwrap();
    assert!((back.target - view.target).length() < 1e-9);
    assert!((back.fov_y_rad - 1.0).abs() < 1e-15);
    let ortho = Camera {
        projection: Projection::Orthogonal { view_height: 1.0 },
        ..bcf
    };
    assert_eq!(ortho.to_view(50.0, 0.5), None);
    let along = Camera {
        up: bcf.direction,
        ..bcf
    };
    assert_eq!(
        along.to_view(50.0, 0.5),
        None,
        "up along the view direction"
    );
}

#[test]
fn not_a_zip_is_refused() {
    let message = read_error(b"this is not a zip file at all");
    assert!(message.contains("not a BCF archive"), "{message}");
    let message = read_error(&[]);
    assert!(message.contains("not a BCF archive"), "{message}");
}

#[test]
fn a_zip_without_bcf_is_refused() {
    let message = read_error(&zip_of(&[("readme.txt", b"hello")]));
    assert!(
        message.contains("no bcf.version and no topic folder"),
        "{message}"
    );
}

#[test]
fn entries_escaping_the_folder_are_refused() {
    for name in [
        "../evil.png",
        "t1/../../evil",
        "/etc/passwd",
        "t1\\..\\evil",
        "C:/evil",
    ] {
        let message = read_error(&zip_of(&[("bcf.version", VERSION), (name, b"x")]));
        assert!(
            message.contains(name) && message.contains("leaves the archive's folder"),
            "{name}: {message}"
        );
    }
}

#[test]
fn viewpoints_without_markup_are_refused() {
    let message = read_error(&zip_of(&[
        ("bcf.version", VERSION),
        ("t1/v1.bcfv", visinfo("").as_bytes()),
    ]));
    assert!(message.contains("t1/markup.bcf: missing"), "{message}");
}

#[test]
fn bad_xml_names_the_entry() {
    for (markup, reason) in [
        (
            "<Markup><Topic Guid='t1'><Title>x</Topic></Markup>",
            "bad XML",
        ),
        ("<Markup><Topic Guid='t1'>", "ends inside <Topic>"),
        ("<Markup>&bogus;</Markup>", "unknown entity"),
        ("<Other/>", "root element is <Other>, not <Markup>"),
        ("<Markup/>", "no <Topic>"),
        ("", "no root element"),
        (&"<a>".repeat(100), "nested more than 64"),
    ] {
        let message = read_error(&zip_of(&[
            ("bcf.version", VERSION),
            ("t1/markup.bcf", markup.as_bytes()),
        ]));
        assert!(
            message.contains("t1/markup.bcf") && message.contains(reason),
            "{reason}: {message}"
        );
    }
}

#[test]
fn bad_numbers_name_the_element() {
    for (fov, reason) in [
        (
            "abc",
            "PerspectiveCamera/FieldOfView: \"abc\" is not a finite number",
        ),
        ("NaN", "is not a finite number"),
        ("200", "not in (0, 180) degrees"),
    ] {
        let vi = visinfo(&PERSPECTIVE.replace("FOV", fov));
        let message = read_error(&zip_of(&[
            ("bcf.version", VERSION),
            ("t1/markup.bcf", MARKUP.as_bytes()),
            ("t1/v1.bcfv", vi.as_bytes()),
        ]));
        assert!(
            message.contains("t1/v1.bcfv") && message.contains(reason),
            "{reason}: {message}"
        );
    }
    let far = visinfo(
        &PERSPECTIVE
            .replace("FOV", "60")
            .replace("<X>1</X>", "<X>1e300</X>"),
    );
    let message = read_error(&zip_of(&[
        ("bcf.version", VERSION),
        ("t1/markup.bcf", MARKUP.as_bytes()),
        ("t1/v1.bcfv", far.as_bytes()),
    ]));
    assert!(
        message.contains("CameraViewPoint") && message.contains("beyond"),
        "{message}"
    );
}

#[test]
fn missing_and_escaping_references_are_refused() {
    let message = read_error(&zip_of(&[
        ("bcf.version", VERSION),
        ("t1/markup.bcf", MARKUP.as_bytes()),
    ]));
    assert!(
        message.contains("t1/markup.bcf") && message.contains("which the archive lacks"),
        "{message}"
    );
    let sneaky = MARKUP.replace("v1.bcfv", "../t2/v1.bcfv");
    let message = read_error(&zip_of(&[
        ("bcf.version", VERSION),
        ("t1/markup.bcf", sneaky.as_bytes()),
    ]));
    assert!(
        message.contains("not a file name in the topic's folder"),
        "{message}"
    );
}

#[test]
fn unknown_versions_are_refused() {
    let message = read_error(&zip_of(&[(
        "bcf.version",
        br#"<Version VersionId="9.9"/>"#,
    )]));
    assert!(
        message.contains("bcf.version") && message.contains("\"9.9\""),
        "{message}"
    );
}

/// A snapshot that inflates past its cap is refused whatever its header
/// says, and so is an archive of too many entries.
#[test]
fn oversized_entries_are_refused() {
    let big = vec![0u8; (dmu_app::bcf::MAX_SNAPSHOT_BYTES + 1) as usize];
    let markup = MARKUP.replace("</Viewpoint>", "</Viewpoint><Snapshot>s.png</Snapshot>");
    let message = read_error(&zip_of(&[
        ("bcf.version", VERSION),
        ("t1/markup.bcf", markup.as_bytes()),
        ("t1/v1.bcfv", visinfo("").as_bytes()),
        ("t1/s.png", &big),
    ]));
    assert!(
        message.contains("t1/s.png") && message.contains("larger than"),
        "{message}"
    );

    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let stored =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for i in 0..=dmu_app::bcf::MAX_ENTRIES {
        zip.start_file(format!("f{i}"), stored).unwrap();
    }
    let message = read_error(&zip.finish().unwrap().into_inner());
    assert!(message.contains("entries, more than"), "{message}");
}

/// Topics that cannot be written are refused before anything is written.
#[test]
fn unwritable_topics_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.bcfzip");
    let check = |topics: &[Topic], reason: &str| {
        let e = write_bcfzip(&path, topics, None, 1.0).unwrap_err();
        assert!(matches!(e, BcfError::Topic { .. }), "{e}");
        assert!(e.to_string().contains(reason), "{reason}: {e}");
        assert!(!path.exists());
    };
    let t = Topic::new("t", "a");
    check(
        &[Topic {
            guid: "../x".into(),
            ..t.clone()
        }],
        "must be 1 to 64 letters",
    );
    check(&[t.clone(), t.clone()], "two topics have this GUID");
    let mut nan = t.clone();
    nan.viewpoints.push(Viewpoint {
        clipping_planes: vec![ClippingPlane {
            location: DVec3::NAN,
            direction: DVec3::X,
        }],
        ..Viewpoint::new()
    });
    check(&[nan], "not finite");
}

/// A missing file's error names the file and the cause once, even printed
/// with its chain (`{:#}` as the applications print errors): the cause was
/// both the message's and the error's source, and showed twice.
#[test]
fn a_missing_file_says_why_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("absent.bcfzip");
    let err = anyhow::Error::from(read_bcfzip(&path, 1000.0).unwrap_err());
    let text = format!("{err:#}");
    assert!(text.starts_with(&path.display().to_string()), "{text}");
    assert_eq!(text.matches("No such file").count(), 1, "{text}");
}

// Issue 48: the BCF classes of the second hostile sweep.

/// A topic with one viewpoint of `camera` and `planes`.
fn topic_with(camera: Option<Camera>, planes: Vec<ClippingPlane>) -> Topic {
    let mut t = Topic::new("t", "a");
    t.viewpoints.push(Viewpoint {
        camera,
        clipping_planes: planes,
        ..Viewpoint::new()
    });
    t
}

/// A coordinate anywhere from 1e-320 to 1e300 in size, either sign, or 0.
fn any_scale() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        (-1.0f64..1.0, -320i32..300).prop_map(|(m, e)| m * 10f64.powi(e)),
        (-2e15..2e15f64),
    ]
}

fn any_vector() -> impl Strategy<Value = DVec3> {
    (any_scale(), any_scale(), any_scale()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// What dmu writes, dmu reads: the viewer exported section planes and
    /// cameras beyond ±1e15 that its own reader then refused. Whatever the
    /// numbers, a write either refuses the topic (naming it, writing nothing)
    /// or gives a file that reads back.
    #[test]
    fn issue_48_what_dmu_writes_dmu_reads(
        eye in any_vector(),
        direction in any_vector(),
        up in any_vector(),
        fov in prop_oneof![Just(60.0), -1.0..200.0f64, any_scale()],
        location in any_vector(),
        plane in any_vector(),
        scale in prop_oneof![Just(1.0), Just(1000.0), Just(25.4), 1e-3..1e4f64],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("round.bcfzip");
        let camera = Camera {
            eye,
            direction,
            up,
            projection: Projection::Perspective { fov_y_deg: fov },
        };
        let topic = topic_with(Some(camera), vec![ClippingPlane { location, direction: plane }]);
        match write_bcfzip(&path, &[topic], None, scale) {
            Ok(()) => {
                let read = read_bcfzip(&path, scale);
                prop_assert!(read.is_ok(), "written but not read: {}", read.unwrap_err());
            }
            Err(e) => {
                prop_assert!(matches!(e, BcfError::Topic { .. }), "{e}");
                prop_assert!(!path.exists());
                prop_assert!(!e.to_string().contains("0000000000000000"), "short numbers: {e}");
            }
        }
    }
}

/// A camera direction of length 1e300 normalised to zero, and the viewer
/// skipped the topic without a word: it is a direction like any other.
#[test]
fn issue_48_a_huge_camera_direction_is_a_direction() {
    let camera = "<PerspectiveCamera><CameraViewPoint><X>1</X><Y>2</Y><Z>3</Z></CameraViewPoint>\
<CameraDirection><X>1e300</X><Y>0</Y><Z>0</Z></CameraDirection>\
<CameraUpVector><X>0</X><Y>0</Y><Z>1e-320</Z></CameraUpVector><FieldOfView>60</FieldOfView></PerspectiveCamera>";
    let bytes = zip_of(&[
        ("bcf.version", VERSION),
        ("t1/markup.bcf", MARKUP.as_bytes()),
        ("t1/v1.bcfv", visinfo(camera).as_bytes()),
    ]);
    let dir = tempfile::tempdir().unwrap();
    let topics = read_bcfzip(&file(dir.path(), "huge.bcfzip", &bytes), 1.0).unwrap();
    let view = topics[0].viewpoints[0]
        .camera
        .unwrap()
        .to_view(10.0, 0.1)
        .expect("a view along +X");
    assert_eq!(view.eye, DVec3::new(1.0, 2.0, 3.0));
    assert_eq!(view.target, DVec3::new(11.0, 2.0, 3.0));
    assert_eq!(view.up, DVec3::Z);
}

/// Viewpoints naming one snapshot shared it in one copy each: 40 of one 63
/// MiB snapshot took `bcf show` to 2.1 GB. Each is read once and shared.
#[test]
fn issue_48_a_shared_snapshot_is_read_once() {
    let snapshot = vec![7u8; 1 << 20];
    let mut markup = String::from(r#"<Markup><Topic Guid="t1"><Title>x</Title></Topic>"#);
    let mut entries: Vec<(String, Vec<u8>)> = vec![
        ("bcf.version".into(), VERSION.to_vec()),
        ("t1/shared.png".into(), snapshot.clone()),
    ];
    for i in 0..40 {
        markup.push_str(&format!(
            r#"<Viewpoints Guid="v{i}"><Viewpoint>v{i}.bcfv</Viewpoint><Snapshot>shared.png</Snapshot></Viewpoints>"#
        ));
        entries.push((format!("t1/v{i}.bcfv"), visinfo("").into_bytes()));
    }
    markup.push_str("</Markup>");
    entries.push(("t1/markup.bcf".into(), markup.into_bytes()));
    let refs: Vec<(&str, &[u8])> = entries
        .iter()
        .map(|(n, b)| (n.as_str(), b.as_slice()))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let topics = read_bcfzip(&file(dir.path(), "shared.bcfzip", &zip_of(&refs)), 1.0).unwrap();
    let views = &topics[0].viewpoints;
    assert_eq!(views.len(), 40);
    let first = views[0].snapshot.as_ref().unwrap();
    assert_eq!(&first[..], &snapshot[..]);
    for v in views {
        assert!(
            std::sync::Arc::ptr_eq(first, v.snapshot.as_ref().unwrap()),
            "one copy"
        );
    }
}

/// 99,998 topics took quadratic time (5k: 0.5 s, 40k: 23.5 s, so about
/// 150 s for 100k): each folder with viewpoints was looked for in a scan of
/// every topic folder. With the folders in a set the read is linear; the
/// minute allowed here is a hang guard, far above either.
#[test]
fn issue_48_many_topics_read_in_linear_time() {
    let n = 99_998;
    let markup = |i: usize| {
        format!(
            r#"<Markup><Topic Guid="t{i}"><Title>x</Title></Topic><Viewpoints Guid="v"><Viewpoint>v.bcfv</Viewpoint></Viewpoints></Markup>"#
        )
    };
    let visinfo = visinfo("");
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let stored =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for i in 0..n / 2 {
        zip.start_file(format!("t{i}/markup.bcf"), stored).unwrap();
        zip.write_all(markup(i).as_bytes()).unwrap();
        zip.start_file(format!("t{i}/v.bcfv"), stored).unwrap();
        zip.write_all(visinfo.as_bytes()).unwrap();
    }
    let bytes = zip.finish().unwrap().into_inner();
    let dir = tempfile::tempdir().unwrap();
    let path = file(dir.path(), "many.bcfzip", &bytes);
    let started = std::time::Instant::now();
    let topics = read_bcfzip(&path, 1.0).unwrap();
    assert_eq!(topics.len(), n / 2);
    assert!(
        started.elapsed().as_secs() < 60,
        "{n} entries took {:?}",
        started.elapsed()
    );
}

/// The viewer's BCF export wrote a zip over any existing file: a `.glb`
/// model, or the `.dmu` store it had open. A BCF file is written only to a
/// `.bcfzip` name, as `dmu collide --bcf` requires.
#[test]
fn issue_48_a_bcf_file_never_replaces_a_model() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["model.dmu", "model.glb", "model.gltf", "shot.png", "noext"] {
        let path = file(dir.path(), name, b"PRECIOUS");
        let e = write_bcfzip(&path, &[Topic::new("t", "a")], None, 1.0).unwrap_err();
        assert!(matches!(e, BcfError::Name { .. }), "{name}: {e}");
        assert!(e.to_string().contains(".bcfzip"), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), b"PRECIOUS", "{name}");
    }
    let ok = dir.path().join("Issues.BCFZIP");
    write_bcfzip(&ok, &[Topic::new("t", "a")], None, 1.0).unwrap();
    assert_eq!(read_bcfzip(&ok, 1.0).unwrap().len(), 1);
}
