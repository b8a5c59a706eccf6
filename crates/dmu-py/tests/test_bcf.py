"""BCF files against an independent reader and writer, IfcOpenShell's
bcf-client (`import bcf`): what `dmu collide --bcf` writes reads there with
the topics, cameras, components and snapshots it should have, and what
bcf-client writes (BCF 2.1 and 3.0) reads in dmu (`dmu bcf show --json`) with
its camera and clipping planes. Under CI=true a missing bcf-client fails; elsewhere it skips,
saying so."""

import json
import math
import struct
import uuid
import zlib

import pytest

from conftest import require, run_cli, run_viewer, step_of

# box_x_y_z of the 4×4×4 grid spans 10·(x, y, z) ± 2.
HALF = 2.0


def bcf_client():
    """The bcf-client package, or a failure (CI) / skip (elsewhere)."""
    try:
        import bcf.bcfxml
        import bcf.v2.model
        import bcf.v3.model
    except ImportError as e:
        require(False, f"bcf-client is not installed (pip install bcf-client): {e}")
    return bcf


def png_info(data):
    """(width, height) of a PNG, after checking it the long way: signature,
    every chunk's CRC, an 8-bit RGBA or RGB header, and IDAT data that inflates
    to exactly one filter byte plus a row of pixels per line."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG signature"
    at, chunks = 8, []
    while at < len(data):
        (length,) = struct.unpack(">I", data[at:at + 4])
        kind, body = data[at + 4:at + 8], data[at + 8:at + 8 + length]
        (crc,) = struct.unpack(">I", data[at + 8 + length:at + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"bad CRC in {kind}"
        chunks.append((kind, body))
        at += 12 + length
    assert chunks[0][0] == b"IHDR" and chunks[-1][0] == b"IEND"
    width, height, depth, colour = struct.unpack(">IIBB", chunks[0][1][:10])
    assert depth == 8 and colour in (2, 6), (depth, colour)
    channels = 4 if colour == 6 else 3
    pixels = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    assert len(pixels) == height * (1 + width * channels)
    return width, height


def in_view(camera, corner, aspect):
    """Whether a point is inside a perspective camera's view (eye, unit-free
    direction and up, vertical field of view in degrees, width/height)."""
    def sub(a, b):
        return [a[i] - b[i] for i in range(3)]

    def dot(a, b):
        return sum(a[i] * b[i] for i in range(3))

    def cross(a, b):
        return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

    def unit(a):
        n = math.sqrt(dot(a, a))
        return [x / n for x in a]

    forward = unit(camera["direction"])
    right = unit(cross(forward, camera["up"]))
    up = cross(right, forward)
    v = sub(corner, camera["eye"])
    depth = dot(v, forward)
    tan = math.tan(math.radians(camera["fov"]) / 2)
    return depth > 0 and abs(dot(v, up)) <= tan * depth * (1 + 1e-9) and abs(dot(v, right)) <= tan * aspect * depth * (1 + 1e-9)


def box_corners(center):
    return [[center[0] + sx * HALF, center[1] + sy * HALF, center[2] + sz * HALF]
            for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]


def xyz(p):
    return [p.x, p.y, p.z]


def collide_bcf(dmu_bin, model, record, poses, clearance, out_path, snapshot):
    """`dmu collide --bcf` of box_0_0_0 moved to `poses` (one a step), which
    clash: its JSON report."""
    record.write_text("".join(
        json.dumps({"t": float(t), "part": "box_0_0_0", "translation": p, "rotation": [0, 0, 0, 1]}) + "\n"
        for t, p in enumerate(poses)))
    code, out = run_cli(dmu_bin, "collide", model, "--record", record, "--clearance", clearance, "--discrete",
                        "--json", "--bcf", out_path, "--bcf-snapshot", snapshot)
    assert code == 1
    return json.loads(out)


def test_collide_bcf_reads_in_bcf_client(grid_glb, dmu_bin, tmp_path):
    bcf = bcf_client()
    # box_0_0_0: clear, into box_1_0_0 (steps 1 and 2: one topic), into box_0_1_0.
    poses = [[-30.0, 0.0, 0.0], [7.0, 0.0, 0.0], [7.0, 0.0, 0.0], [0.0, 7.0, 0.0]]
    out_path = tmp_path / "clashes.bcfzip"
    report = collide_bcf(dmu_bin, grid_glb, tmp_path / "moves.jsonl", poses, 0, out_path, "320x240")
    assert report["bcf"]["topics"] == 2
    if report["bcf"]["snapshots"] == 0:
        require(False, "no Vulkan adapter: dmu collide wrote no snapshots")

    expected = {  # title: (other part, its centre, box_0_0_0's centre at that step)
        "hard: box_0_0_0 × box_1_0_0 at step 1 (t=1)": ("box_1_0_0", [10.0, 0.0, 0.0], poses[1]),
        "hard: box_0_0_0 × box_0_1_0 at step 3 (t=3)": ("box_0_1_0", [0.0, 10.0, 0.0], poses[3]),
    }
    archive = bcf.bcfxml.load(out_path)
    assert archive.version.version_id == "2.1"
    topics = list(archive.topics.values())
    assert sorted(t.topic.title for t in topics) == sorted(expected)
    for topic in topics:
        other, other_center, moved_center = expected[topic.topic.title]
        assert topic.topic.topic_type == "Clash" and topic.topic.topic_status == "Open"
        assert topic.topic.creation_author == "dmu collide"
        assert len(topic.viewpoints) == 1
        (viewpoint,) = topic.viewpoints.values()
        info = viewpoint.visualization_info
        components = info.components.selection.component
        assert [c.authoring_tool_id for c in components] == ["box_0_0_0", other]
        assert all(c.originating_system == "dmu" for c in components)
        cam = info.perspective_camera
        # BCF is in metres; the model's unit is taken as the millimetre.
        camera = {"eye": [v * 1000.0 for v in xyz(cam.camera_view_point)], "direction": xyz(cam.camera_direction),
                  "up": xyz(cam.camera_up_vector), "fov": cam.field_of_view}
        assert camera["fov"] == pytest.approx(60.0)
        assert sum(a * b for a, b in zip(camera["direction"], camera["up"])) == pytest.approx(0.0, abs=1e-12)
        for corner in box_corners(moved_center) + box_corners(other_center):
            assert in_view(camera, corner, 320 / 240), (topic.topic.title, corner)
        assert png_info(viewpoint.snapshot) == (320, 240)


def test_collide_bcf_titles_a_pair_with_its_worst_finding(grid_glb, dmu_bin, tmp_path):
    """Issue 47: a pair going from a 0.05 soft clash to a hard clash and back
    is one topic, titled with its hard clash and listing the soft one, as
    bcf-client reads it (it was titled "soft", the pair's first finding)."""
    bcf = bcf_client()
    # box_1_0_0 spans x 8..12: box_0_0_0 (side 4) at x 5.95 is 0.05 away.
    poses = [[-30.0, 0.0, 0.0], [5.95, 0.0, 0.0], [7.0, 0.0, 0.0], [5.95, 0.0, 0.0]]
    out_path = tmp_path / "closer.bcfzip"
    report = collide_bcf(dmu_bin, grid_glb, tmp_path / "closer.jsonl", poses, 0.1, out_path, "none")
    assert [f["kind"] for f in report["clashes"]] == ["soft", "hard", "soft"]
    archive = bcf.bcfxml.load(out_path)  # kept open: bcf-client reads topics lazily
    (topic,) = archive.topics.values()
    assert topic.topic.title == "hard: box_0_0_0 × box_1_0_0 at step 2 (t=2)"
    assert "Also soft at 2 steps from step 1 (t=1)." in topic.topic.description
    assert list(topic.topic.labels) == ["hard", "soft", "dmu collide"]


def tiny_png(width, height):
    """A grey RGB PNG written from scratch."""
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    rows = b"".join(b"\x00" + b"\x80" * (3 * width) for _ in range(height))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")


PLANES = [((1.25, 2.0, -0.5), (1.0, 0.0, 0.0)), ((0.0, 0.0, 3.75), (0.0, 0.6, -0.8))]


def client_file(tmp_path, version):
    """A BCF file written by bcf-client: one topic, a perspective camera, box_1_0_0
    selected, the two clipping planes of PLANES (metres). Returns (path, topic, info)."""
    bcf_client()
    import importlib

    package = "bcf.v2" if version == "2.1" else "bcf.v3"
    mdl = importlib.import_module(package + ".model")
    visinfo = importlib.import_module(package + ".visinfo")
    BcfXml = importlib.import_module(package + ".bcfxml").BcfXml

    def point(x, y, z):
        return mdl.Point(x=x, y=y, z=z)

    def direction(x, y, z):
        return mdl.Direction(x=x, y=y, z=z)

    archive = BcfXml.create_new("review")
    topic = archive.add_topic("Valve & flange <too close>", "Seen on site", "ann@example.com", "Issue", "Open")
    info = mdl.VisualizationInfo(
        guid=str(uuid.uuid4()),
        components=mdl.Components(
            selection=mdl.ComponentSelection(component=[
                mdl.Component(ifc_guid="2O2Fr$t4X7Zf8NOew3FNr2", authoring_tool_id="box_1_0_0", originating_system="other")]),
            visibility=mdl.ComponentVisibility(default_visibility=True)),
        perspective_camera=mdl.PerspectiveCamera(
            camera_view_point=point(1.5, -2.5, 3.25), camera_direction=direction(0.0, 1.0, 0.0),
            camera_up_vector=direction(0.0, 0.0, 1.0), field_of_view=55.0,
            **({"aspect_ratio": 1.5} if version == "3.0" else {})),
        clipping_planes=mdl.VisualizationInfoClippingPlanes(clipping_plane=[
            mdl.ClippingPlane(location=point(*loc), direction=direction(*d)) for loc, d in PLANES]))
    handler = visinfo.VisualizationInfoHandler(visualization_info=info, snapshot=tiny_png(40, 30))
    topic.add_visinfo_handler(handler, "snapshot.png")
    path = tmp_path / f"from_bcf_client_{version}.bcfzip"
    archive.save(path)
    assert bcf_client().bcfxml.load(path).version.version_id == version
    return path, topic, info


@pytest.mark.parametrize("version", ["2.1", "3.0"])
def test_bcf_client_file_reads_in_dmu(dmu_bin, tmp_path, version):
    path, topic, info = client_file(tmp_path, version)
    planes = PLANES
    _, out = run_cli(dmu_bin, "bcf", "show", path, "--json", "--unit", "mm")
    shown = json.loads(out)
    assert shown["unit"] == "mm"
    (t,) = shown["topics"]
    assert t["guid"] == topic.guid
    assert (t["title"], t["description"], t["author"]) == ("Valve & flange <too close>", "Seen on site", "ann@example.com")
    assert (t["topic_type"], t["topic_status"]) == ("Issue", "Open")
    (v,) = t["viewpoints"]
    assert v["guid"] == info.guid
    camera = v["camera"]
    assert camera["projection"] == "perspective"
    assert camera["eye"] == pytest.approx([1500.0, -2500.0, 3250.0], abs=1e-9)
    assert camera["direction"] == pytest.approx([0.0, 1.0, 0.0])
    assert camera["up"] == pytest.approx([0.0, 0.0, 1.0])
    assert camera["fov_y_deg"] == pytest.approx(55.0)
    assert len(v["clipping_planes"]) == 2
    for got, (loc, d) in zip(v["clipping_planes"], planes):
        assert got["location"] == pytest.approx([c * 1000.0 for c in loc], abs=1e-9)
        assert got["direction"] == pytest.approx(list(d))
    assert v["selected"] == [{"ifc_guid": "2O2Fr$t4X7Zf8NOew3FNr2", "originating_system": "other",
                              "authoring_tool_id": "box_1_0_0"}]
    assert v["visibility"] == {"default_visible": True, "exceptions": []}
    assert v["snapshot"] == {"format": "png", "bytes": len(tiny_png(40, 30)), "width": 40, "height": 30}

    # In metres the same file reads 1000 times smaller.
    _, out = run_cli(dmu_bin, "bcf", "show", path, "--json", "--unit", "m")
    assert json.loads(out)["topics"][0]["viewpoints"][0]["camera"]["eye"] == pytest.approx([1.5, -2.5, 3.25])


def test_viewer_bcf_reads_in_bcf_client(grid_glb, viewer_bin, tmp_path):
    """The viewer's issues, a clash found live and a saved viewpoint with a
    section plane, read in bcf-client with their cameras, components,
    visibility, clipping planes and snapshots."""
    bcf = bcf_client()
    out_path = tmp_path / "review.bcfzip"
    report = run_viewer(viewer_bin, grid_glb, [
        {"select": "box_0_0_0"},
        {"move": [7.0, 0.0, 0.0]},
        {"section_plane": {"point": [0.0, 0.0, 25.0], "normal": [0.0, 0.0, -1.0]}},
        {"save_viewpoint": "level 2 cut"},
        {"export_bcf": str(out_path)},
    ], tmp_path)
    assert step_of(report, "export_bcf")["topics"] == 2
    assert report["bcf_export"]["topics"] == 2
    view = report["viewport"]

    archive = bcf.bcfxml.load(out_path)
    assert archive.version.version_id == "2.1"
    topics = {t.topic.title: t for t in archive.topics.values()}
    assert sorted(topics) == ["hard: box_0_0_0 × box_1_0_0", "level 2 cut"]
    for title, topic in topics.items():
        assert topic.topic.creation_author == "dmu-viewer"
        (viewpoint,) = topic.viewpoints.values()
        info = viewpoint.visualization_info
        assert [c.authoring_tool_id for c in info.components.selection.component] == ["box_0_0_0"]
        assert info.perspective_camera.field_of_view == pytest.approx(60.0)
        assert png_info(viewpoint.snapshot) == (view["width"], view["height"])

    clash = topics["hard: box_0_0_0 × box_1_0_0"]
    assert clash.topic.topic_type == "Clash"
    (viewpoint,) = clash.viewpoints.values()
    visibility = viewpoint.visualization_info.components.visibility
    assert visibility.default_visibility is False
    assert sorted(c.authoring_tool_id for c in visibility.exceptions.component) == ["box_0_0_0", "box_1_0_0"]
    cam = viewpoint.visualization_info.perspective_camera
    camera = {"eye": [v * 1000.0 for v in xyz(cam.camera_view_point)], "direction": xyz(cam.camera_direction),
              "up": xyz(cam.camera_up_vector), "fov": cam.field_of_view}
    for corner in box_corners([7.0, 0.0, 0.0]) + box_corners([10.0, 0.0, 0.0]):
        assert in_view(camera, corner, view["width"] / view["height"]), corner

    cut = topics["level 2 cut"]
    (viewpoint,) = cut.viewpoints.values()
    (plane,) = viewpoint.visualization_info.clipping_planes.clipping_plane
    # The plane keeps z <= 25 mm; BCF's direction points into what is hidden.
    assert plane.location.z == pytest.approx(0.025)
    assert xyz(plane.direction) == pytest.approx([0.0, 0.0, 1.0])


@pytest.mark.parametrize("version", ["2.1", "3.0"])
def test_bcf_client_file_imports_in_viewer(grid_glb, viewer_bin, tmp_path, version):
    """A file bcf-client wrote opens in the viewer at its camera, with its
    clipping planes as the section and its component selected."""
    path, _, _ = client_file(tmp_path, version)
    report = run_viewer(viewer_bin, grid_glb, [{"import_bcf": str(path)}, {"frames": 2}], tmp_path)
    imported = step_of(report, "import_bcf")
    assert (imported["topics"], imported["viewpoints"], imported["unknown_components"]) == (1, 1, 0)
    first = imported["first"]
    assert first["selected"] == "box_1_0_0"
    assert first["view"]["name"] == "Valve & flange <too close>"
    assert first["view"]["eye"] == pytest.approx([1500.0, -2500.0, 3250.0], abs=1e-9)
    assert first["view"]["forward"] == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    assert first["view"]["fov_y_deg"] == pytest.approx(55.0)
    planes = first["section"]["planes"]
    assert len(planes) == 2
    for got, (loc, d) in zip(planes, PLANES):
        n = [-c / math.sqrt(sum(x * x for x in d)) for c in d]
        assert got["normal"] == pytest.approx(n, abs=1e-12)
        assert got["d"] == pytest.approx(-sum(n[i] * loc[i] * 1000.0 for i in range(3)), abs=1e-9)
    # The view the run ended on is the imported camera.
    assert report["camera"]["eye"] == pytest.approx([1500.0, -2500.0, 3250.0], abs=1e-9)
    assert report["camera"]["fov_y_deg"] == pytest.approx(55.0)
