//! Fuzz body of `bcf_read`: the bytes as a `.bcfzip` issue file, read with
//! `dmu_app::bcf::read_bcfzip` for a millimetre model (1000 units a metre).
//! Errors are fine; a panic is a finding.
//!
//! Before reading, the CRC-32 of every entry stored uncompressed is recomputed
//! ([`reseal_stored`]): the zip reader checks an entry's CRC when it has read
//! it to the end, so a mutated XML entry would otherwise be refused before the
//! XML parser and the BCF reader saw it. The seed corpus holds archives with
//! stored XML for that reason, beside deflated ones as dmu writes them (whose
//! mutations mostly test the zip reader and inflater).

/// Reads `data` (its stored entries' CRCs resealed) as a `.bcfzip`.
pub fn run(data: &[u8]) {
    let mut data = data.to_vec();
    reseal_stored(&mut data);
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("issues.bcfzip");
    std::fs::write(&path, &data).expect("temporary file");
    let _ = dmu_app::bcf::read_bcfzip(&path, 1000.0);
}

/// Sets the CRC-32 of every stored (method 0) entry, in its central directory
/// record and its local header, to that of its bytes: for each central record
/// found anywhere in `data` (`PK\1\2`) whose local header (`PK\3\4`) and bytes
/// lie within `data`. Deflated entries, zip64 sizes and records out of range
/// are left as they are.
pub fn reseal_stored(data: &mut [u8]) {
    const CENTRAL: &[u8] = b"PK\x01\x02";
    const LOCAL: &[u8] = b"PK\x03\x04";
    let u16_at = |d: &[u8], at: usize| {
        d.get(at..at + 2)
            .map(|b| usize::from(u16::from_le_bytes([b[0], b[1]])))
    };
    let u32_at = |d: &[u8], at: usize| {
        d.get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    let mut from = 0;
    while let Some(found) = data
        .get(from..)
        .and_then(|d| d.windows(4).position(|w| w == CENTRAL))
    {
        let central = from + found;
        from = central + 4;
        let (Some(0), Some(size), Some(local)) = (
            u16_at(data, central + 10),
            u32_at(data, central + 20),
            u32_at(data, central + 42),
        ) else {
            continue;
        };
        if data.get(local..local.saturating_add(4)) != Some(LOCAL) {
            continue;
        }
        let (Some(name), Some(extra)) = (u16_at(data, local + 26), u16_at(data, local + 28)) else {
            continue;
        };
        let start = local + 30 + name + extra;
        let Some(bytes) = data.get(start..start.saturating_add(size)) else {
            continue;
        };
        let crc = crc32(bytes).to_le_bytes();
        data[central + 16..central + 20].copy_from_slice(&crc);
        data[local + 14..local + 18].copy_from_slice(&crc);
    }
}

/// The zip CRC-32 (IEEE 802.3, reflected) of `bytes`, bit by bit: inputs are
/// small, and it needs no table or dependency.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = (crc >> 1) ^ (0xEDB8_8320 & (crc & 1).wrapping_neg());
        }
    }
    !crc
}

/// The committed corpus replayed through [`run`], in the test suite of the
/// crate that includes this file (with `fuzz/replay.rs` as `fuzz_replay`).
#[cfg(test)]
#[test]
fn corpus_never_panics() {
    crate::fuzz_replay::corpus("bcf_read", run);
}

/// The CRC is zip's, and resealing leaves an archive as written unchanged.
#[cfg(test)]
#[test]
fn resealing_keeps_valid_archives() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/bcf_read");
    for name in ["dmu_written.bcfzip", "stored_xml.bcfzip"] {
        let bytes = std::fs::read(dir.join(name)).expect(name);
        let mut resealed = bytes.clone();
        reseal_stored(&mut resealed);
        assert_eq!(resealed, bytes, "{name}");
    }
}

/// The seeds are what their names say: `broken_*` refused, the rest read.
#[cfg(test)]
#[test]
fn seeds_read_as_named() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/bcf_read");
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let read = dmu_app::bcf::read_bcfzip(&path, 1000.0);
        if name.starts_with("broken_") {
            let err = read.expect_err(&name);
            eprintln!("{name}: {err}");
        } else {
            let topics = read.unwrap_or_else(|e| panic!("{e}"));
            assert!(!topics.is_empty(), "{name}");
            eprintln!("{name}: {} topics", topics.len());
        }
    }
}

/// Writes the seed corpus into `fuzz/corpus/bcf_read/`, valid archives and
/// broken ones (each refused for one reason):
/// `cargo test -p dmu-app --test tests -- --ignored write_bcf_seed_corpus`.
#[cfg(test)]
#[test]
#[ignore = "rewrites the committed seed corpus"]
fn write_bcf_seed_corpus() {
    use dmu_app::bcf::{
        Camera, ClippingPlane, Component, Projection, Topic, Viewpoint, Visibility, write_bcfzip,
    };
    use glam::DVec3;
    use std::io::{Read as _, Write as _};

    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/bcf_read");
    std::fs::create_dir_all(&dir).unwrap();
    let mut png = std::io::Cursor::new(Vec::new());
    image::RgbaImage::from_pixel(2, 2, image::Rgba([200, 30, 30, 255]))
        .write_to(&mut png, image::ImageFormat::Png)
        .unwrap();
    let mut clash = Topic::new("hard: pump_3 × pipe_17", "dmu collide");
    clash.guid = "7d1c0e52-0b7e-4d55-9f0c-000000000001".into();
    clash.creation_date = "2026-01-02T03:04:05Z".into();
    clash.topic_type = "Clash".into();
    clash.labels = vec!["mech".into(), "urgent".into()];
    clash.viewpoints.push(Viewpoint {
        guid: "7d1c0e52-0b7e-4d55-9f0c-0000000000a1".into(),
        camera: Some(Camera {
            eye: DVec3::new(5000.0, -3000.0, 2000.0),
            direction: DVec3::new(-0.6, 0.6, -0.3).normalize(),
            up: DVec3::Z,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        }),
        selected: vec![Component::part("pump_3"), Component::part("pipe_17")],
        visibility: Visibility {
            default_visible: false,
            exceptions: vec![Component::part("pump_3")],
        },
        clipping_planes: vec![
            ClippingPlane {
                location: DVec3::ZERO,
                direction: DVec3::Z,
            },
            ClippingPlane {
                location: DVec3::new(0.0, -2000.0, 0.0),
                direction: DVec3::NEG_Y,
            },
        ],
        // Collected: into a `Vec<u8>` or an `Arc<[u8]>`, whichever it holds.
        snapshot: Some(png.into_inner().into_iter().collect()),
    });
    let mut section = Topic::new("section & plan", "viewer");
    section.guid = "7d1c0e52-0b7e-4d55-9f0c-000000000002".into();
    section.creation_date = "2026-01-02T03:04:06Z".into();
    section.viewpoints.push(Viewpoint {
        guid: "7d1c0e52-0b7e-4d55-9f0c-0000000000b1".into(),
        camera: Some(Camera {
            eye: DVec3::new(0.0, 0.0, 1500.0),
            direction: DVec3::NEG_Z,
            up: DVec3::Y,
            projection: Projection::Orthogonal { view_height: 250.0 },
        }),
        ..Viewpoint::new()
    });
    let written = dir.join("dmu_written.bcfzip");
    write_bcfzip(&written, &[clash, section], Some("plant"), 1000.0).unwrap();

    // The same entries stored uncompressed, so that mutations of the XML reach
    // the parser (see `reseal_stored`).
    let mut from = zip::ZipArchive::new(std::fs::File::open(&written).unwrap()).unwrap();
    let entries: Vec<(String, Vec<u8>)> = (0..from.len())
        .map(|i| {
            let mut entry = from.by_index(i).unwrap();
            let mut bytes = Vec::new();
            entry.read_to_end(&mut bytes).unwrap();
            (entry.name().unwrap().into_owned(), bytes)
        })
        .collect();
    let stored = |entries: &[(&str, &[u8])]| {
        let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .last_modified_time(zip::DateTime::default());
        for (name, bytes) in entries {
            zip.start_file(*name, options).unwrap();
            zip.write_all(bytes).unwrap();
        }
        zip.finish().unwrap().into_inner()
    };
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).unwrap();
    let all: Vec<(&str, &[u8])> = entries.iter().map(|(n, b)| (n.as_str(), &b[..])).collect();
    write("stored_xml.bcfzip", &stored(&all));

    // BCF 3.0 (viewpoints inside the topic, labels in a list, a JPEG) and 2.0
    // (components flagged `Selected`, the default file names).
    let markup3 = r#"<?xml version="1.0" encoding="UTF-8"?>
<Markup><Topic Guid="a1" TopicType="Clash" TopicStatus="Open"><Title> Pipe &amp; duct </Title>
<CreationAuthor>bob@example.com</CreationAuthor><Labels><Label>mech</Label></Labels>
<Viewpoints><ViewPoint Guid="b2"><Viewpoint>b2.bcfv</Viewpoint><Snapshot>b2.jpg</Snapshot></ViewPoint></Viewpoints>
</Topic></Markup>"#;
    let visinfo3 = r#"<VisualizationInfo Guid="b2"><Components><Selection>
<Component IfcGuid="0123456789abcdefghijkl"><AuthoringToolId>pump_3</AuthoringToolId></Component></Selection>
<Visibility DefaultVisibility="false"><Exceptions><Component><AuthoringToolId>pump_3</AuthoringToolId></Component></Exceptions></Visibility></Components>
<PerspectiveCamera><CameraViewPoint><X>1</X><Y>2</Y><Z>3</Z></CameraViewPoint>
<CameraDirection><X>0</X><Y>1</Y><Z>0</Z></CameraDirection><CameraUpVector><X>0</X><Y>0</Y><Z>1</Z></CameraUpVector>
<FieldOfView>45</FieldOfView></PerspectiveCamera>
<ClippingPlanes><ClippingPlane><Location><X>0.5</X><Y>0</Y><Z>0</Z></Location><Direction><X>-1</X><Y>0</Y><Z>0</Z></Direction></ClippingPlane></ClippingPlanes>
</VisualizationInfo>"#;
    let markup2 = r#"<Markup><Topic Guid="c3"><Title>old</Title></Topic></Markup>"#;
    let visinfo2 = r#"<VisualizationInfo><Components>
<Component IfcGuid="g1" Selected="true"><AuthoringToolId>a</AuthoringToolId></Component>
<Component IfcGuid="g2" Selected="0"/></Components>
<OrthogonalCamera><CameraViewPoint><X>1</X><Y>2</Y><Z>3</Z></CameraViewPoint>
<CameraDirection><X>0</X><Y>0</Y><Z>-1</Z></CameraDirection><ViewToWorldScale>2</ViewToWorldScale></OrthogonalCamera>
</VisualizationInfo>"#;
    write(
        "bcf_3_0_and_2_0.bcfzip",
        &stored(&[
            ("bcf.version", br#"<Version VersionId="3.0"/>"#),
            ("a1/markup.bcf", markup3.as_bytes()),
            ("a1/b2.bcfv", visinfo3.as_bytes()),
            ("a1/b2.jpg", &[0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3]),
            ("c3/markup.bcf", markup2.as_bytes()),
            ("c3/viewpoint.bcfv", visinfo2.as_bytes()),
            ("c3/snapshot.png", b"\x89PNG"),
        ]),
    );

    // Broken ones: each refused for one reason.
    let deflated = std::fs::read(&written).unwrap();
    write("broken_truncated.bcfzip", &deflated[..deflated.len() / 2]);
    let markup = r#"<Markup><Topic Guid="t1"><Title>x</Title></Topic>
<Viewpoints Guid="v1"><Viewpoint>v1.bcfv</Viewpoint><Snapshot>v1.png</Snapshot></Viewpoints></Markup>"#;
    write(
        "broken_zip_slip.bcfzip",
        &stored(&[
            ("t1/markup.bcf", markup.as_bytes()),
            ("t1/../../v1.bcfv", b"<VisualizationInfo/>"),
        ]),
    );
    write(
        "broken_missing_snapshot.bcfzip",
        &stored(&[
            ("t1/markup.bcf", markup.as_bytes()),
            ("t1/v1.bcfv", b"<VisualizationInfo/>"),
        ]),
    );
    let numbers = r#"<VisualizationInfo><PerspectiveCamera>
<CameraViewPoint><X>1e300</X><Y>NaN</Y><Z>inf</Z></CameraViewPoint>
<CameraDirection><X>0</X><Y>0</Y><Z>0</Z></CameraDirection><FieldOfView>180</FieldOfView></PerspectiveCamera>
<ClippingPlanes><ClippingPlane><Location><X>1</X><Y>1</Y></Location></ClippingPlane></ClippingPlanes>
</VisualizationInfo>"#;
    write(
        "broken_numbers.bcfzip",
        &stored(&[
            ("bcf.version", br#"<Version VersionId="2.1"/>"#),
            ("t1/markup.bcf", markup.as_bytes()),
            ("t1/v1.bcfv", numbers.as_bytes()),
            ("t1/v1.png", b"\x89PNG"),
        ]),
    );
    let deep = format!(
        "<VisualizationInfo>{}&unknown;{}</VisualizationInfo>",
        "<a>".repeat(70),
        "</a>".repeat(70)
    );
    write(
        "broken_deep_xml.bcfzip",
        &stored(&[
            ("t1/markup.bcf", markup.as_bytes()),
            ("t1/v1.bcfv", deep.as_bytes()),
            ("t1/v1.png", b"\x89PNG"),
        ]),
    );
}
