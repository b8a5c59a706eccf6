"""STEP and IFC opened by dmu (`dmu import`, `dmu info --parts`, `dmu pick`,
`dmu collide --bcf`, the viewer's search and BCF import, Python's
`dmu.open`), checked against independent readers: IfcOpenShell's own listing
of the IFC files' products, bcf-client for the BCF files, and OpenCascade for
the STEP assemblies the tests make. The converter runs with this interpreter
(DMU_PYTHON), which has the `dmu[cad]` packages; under CI=true a missing one
fails, elsewhere the test skips, saying so."""

import json
import os
import subprocess
import sys
import uuid

import pytest

from conftest import REPO, require, run_viewer, step_of

IFC = REPO.parent / "shared" / "data" / "ifc"
IFC_FILES = ["duplex.ifc", "fzk_haus.ifc", "mini_project.ifc"]
LEFT_OUT = {"IfcSpace", "IfcOpeningElement"}


def ifcopenshell():
    """ifcopenshell, with the IFC samples present, or a failure (CI) / skip."""
    from test_cad_convert import ifcos

    require(IFC.is_dir(), f"the IFC samples are missing: {IFC}")
    return ifcos()


def dmu(dmu_bin, *args, check=True):
    """The command line with this interpreter as the converter's: (status,
    stdout, stderr)."""
    env = dict(os.environ, DMU_PYTHON=sys.executable)
    out = subprocess.run([str(dmu_bin), *map(str, args)], capture_output=True, text=True, timeout=900, env=env)
    if check:
        assert out.returncode in (0, 1), f"dmu {' '.join(map(str, args))} failed: {out.stderr}"
    return out.returncode, out.stdout, out.stderr


def has_body(product):
    """Whether IfcOpenShell lists a 'Body' shape representation for it."""
    shape = product.Representation
    return shape is not None and any(r.RepresentationIdentifier == "Body" for r in shape.Representations)


@pytest.fixture(scope="module")
def imported(dmu_bin, tmp_path_factory):
    """Each IFC sample imported into a store: name -> (store, import summary, parts)."""
    ifcopenshell()
    out = {}
    folder = tmp_path_factory.mktemp("ifc")
    for name in IFC_FILES:
        store = folder / name.replace(".ifc", ".dmu")
        _, summary, _ = dmu(dmu_bin, "import", IFC / name, "-o", store, "--no-lod", "--json")
        _, lines, _ = dmu(dmu_bin, "info", store, "--parts", "--json")
        parts = [json.loads(line) for line in lines.splitlines()]
        out[name] = (store, json.loads(summary), parts)
    return out


@pytest.mark.parametrize("name", IFC_FILES)
def test_ifc_products_with_a_body_import_with_their_global_ids_and_classes(imported, name):
    ios = ifcopenshell()
    model = ios.open(str(IFC / name))
    expected = {(p.GlobalId, p.is_a()) for p in model.by_type("IfcProduct")
                if has_body(p) and p.is_a() not in LEFT_OUT}
    store, summary, parts = imported[name]
    assert summary["report"]["failed_products"] == []
    got = {(p["properties"]["GlobalId"], p["properties"]["IfcClass"]) for p in parts}
    assert len(got) == len(parts), "a GlobalId on two parts"
    assert got == expected
    assert summary["converted"]["products"] == len(expected)
    assert summary["converted"]["format"] == model.schema


@pytest.mark.parametrize("name", IFC_FILES)
def test_each_ifc_product_sits_under_its_storey(imported, name):
    ios = ifcopenshell()
    model = ios.open(str(IFC / name))
    _, _, parts = imported[name]
    placed = 0
    storeys = {s.Name for s in model.by_type("IfcBuildingStorey")}
    assert len(storeys) == len(model.by_type("IfcBuildingStorey")), "storey names are not unique"
    for p in parts:
        product = model.by_guid(p["properties"]["GlobalId"])
        storey = ios.util.element.get_container(product, ifc_class="IfcBuildingStorey")
        if storey is None:
            continue
        # The path runs through the storey's node and no other storey's
        # (names may hold "/": matched with the separators around them).
        above = p["path"][:-len(p["name"])]
        assert [s for s in storeys if f"/{s}/" in above] == [storey.Name], (p["path"], storey)
        placed += 1
    assert placed > len(parts) // 2


def test_python_opens_ifc_and_picks_report_properties(dmu_bin):
    """`dmu.open` on an IFC file lists the parts' properties, and a pick
    reports the properties of the part it hits."""
    ifcopenshell()
    import dmu as dmu_module
    import numpy as np

    model = dmu_module.open(str(IFC / "fzk_haus.ifc"))
    parts = model.parts()
    walls = [p for p in parts if p["properties"].get("IfcClass", "").startswith("IfcWall")]
    assert walls
    corners, ids = model.world_triangles()
    hits = 0
    for wall in walls[:10]:
        (rows,) = np.nonzero(ids == wall["id"])
        a, b, c = corners[rows[0]]
        normal = np.cross(b - a, c - a)
        normal /= np.linalg.norm(normal)
        centre = (a + b + c) / 3
        hit = model.pick((centre + 500 * normal).tolist(), (-normal).tolist())
        assert hit is not None
        assert hit["properties"] == parts[hit["part_id"]]["properties"]
        hits += hit["part_id"] == wall["id"]
    assert hits > 0


def test_collide_bcf_on_ifc_names_components_by_global_id(imported, dmu_bin, tmp_path):
    """`dmu collide --bcf` on an imported IFC writes components whose IfcGuid
    bcf-client reads back equal to the GlobalIds in the IFC file, the moved
    part named in the record by its GlobalId."""
    from test_bcf import bcf_client

    bcf = bcf_client()
    ios = ifcopenshell()
    import dmu as dmu_module

    model = ios.open(str(IFC / "duplex.ifc"))
    store, _, parts = imported["duplex.ifc"]
    walls = [p for p in parts if p["properties"]["IfcClass"].startswith("IfcWall")]
    moved, target = walls[0], walls[1]
    # The first wall put where the second stands (unturned): they clash.
    at = dmu_module.open(str(store)).world(target["id"])[:3, 3].tolist()
    record = tmp_path / "push.jsonl"
    record.write_text(json.dumps({"t": 0.0, "part": moved["properties"]["GlobalId"], "translation": at,
                                  "rotation": [0, 0, 0, 1]}) + "\n")
    out_path = tmp_path / "duplex.bcfzip"
    code, _, err = dmu(dmu_bin, "collide", store, "--record", record, "--clearance", 1, "--discrete", "--json",
                       "--bcf", out_path, "--bcf-snapshot", "none", check=False)
    assert code == 1, err
    archive = bcf.bcfxml.load(out_path)
    by_name = {p["name"]: p["properties"]["GlobalId"] for p in parts}
    components = [c for topic in archive.topics.values() for v in topic.viewpoints.values()
                  for c in v.visualization_info.components.selection.component]
    assert len(components) >= 2
    for c in components:
        assert c.ifc_guid == by_name[c.authoring_tool_id]
        assert model.by_guid(c.ifc_guid).GlobalId == c.ifc_guid
    assert moved["properties"]["GlobalId"] in {c.ifc_guid for c in components}


def test_viewer_finds_a_wall_by_global_id_and_selects_bcf_components_by_ifc_guid(imported, viewer_bin, tmp_path):
    """The viewer's structure search finds a wall by its GlobalId; a BCF file
    bcf-client wrote with only an IfcGuid selects that wall."""
    from test_bcf import bcf_client, tiny_png

    bcf_client()
    import importlib

    store, _, parts = imported["duplex.ifc"]
    wall = next(p for p in parts if p["properties"]["IfcClass"].startswith("IfcWall"))
    guid = wall["properties"]["GlobalId"]
    mdl = importlib.import_module("bcf.v2.model")
    BcfXml = importlib.import_module("bcf.v2.bcfxml").BcfXml
    visinfo = importlib.import_module("bcf.v2.visinfo")
    archive = BcfXml.create_new("review")
    topic = archive.add_topic("Wall to check", "by GlobalId only", "ann@example.com", "Issue", "Open")
    info = mdl.VisualizationInfo(
        guid=str(uuid.uuid4()),
        components=mdl.Components(selection=mdl.ComponentSelection(component=[mdl.Component(ifc_guid=guid)]),
                                  visibility=mdl.ComponentVisibility(default_visibility=True)),
        perspective_camera=mdl.PerspectiveCamera(
            camera_view_point=mdl.Point(x=20.0, y=-20.0, z=10.0), camera_direction=mdl.Direction(x=-1.0, y=1.0, z=-0.5),
            camera_up_vector=mdl.Direction(x=0.0, y=0.0, z=1.0), field_of_view=60.0))
    handler = visinfo.VisualizationInfoHandler(visualization_info=info, snapshot=tiny_png(40, 30))
    topic.add_visinfo_handler(handler, "snapshot.png")
    path = tmp_path / "by_guid.bcfzip"
    archive.save(path)
    report = run_viewer(viewer_bin, store, [{"search": guid}, {"import_bcf": str(path)}, {"frames": 2}], tmp_path)
    found = step_of(report, "search")
    assert found["count"] == 1
    assert found["parts"][0]["part_id"] == wall["id"]
    assert found["parts"][0]["properties"]["GlobalId"] == guid
    imported_bcf = step_of(report, "import_bcf")
    assert imported_bcf["unknown_components"] == 0
    assert imported_bcf["first"]["selected"] == wall["name"]


# ---- STEP ------------------------------------------------------------------

@pytest.mark.parametrize("unit", ["MM", "M"])
def test_step_assembly_imports_with_names_instancing_and_exact_far_picks(dmu_bin, tmp_path, unit):
    """An assembly made with OpenCascade (test_cad_convert.write_step: top
    {box 1, sub 1 {box in sub, pin A}, far box}, one 10 x 20 x 30 mm box part
    placed three times, the far one 1e7 mm out), written in mm and in metres:
    dmu keeps the instance paths, the product names, the instancing and the
    colours, in millimetres, and picks its planar faces exactly."""
    from test_cad_convert import FAR_MM, write_step

    step = write_step(tmp_path / f"asm_{unit}.step", unit)
    store = tmp_path / "asm.dmu"
    _, summary, _ = dmu(dmu_bin, "import", step, "-o", store, "--no-lod", "--json")
    summary = json.loads(summary)
    assert summary["converted"]["format"] == "STEP" and summary["report"]["failed_products"] == []
    _, info, _ = dmu(dmu_bin, "info", store, "--json")
    info = json.loads(info)
    assert (info["name"], info["parts"], info["meshes"]) == (f"asm_{unit}", 4, 2)
    assert info["materials"] >= 3
    _, lines, _ = dmu(dmu_bin, "info", store, "--parts", "--json")
    parts = {p["path"]: p["properties"] for p in map(json.loads, lines.splitlines())}
    # OpenCascade's writer gives each PRODUCT its name as id.
    assert parts == {f"top/{path}": {"StepProduct": product, "StepProductId": product, "SourceFile": step.name}
                     for path, product in [
        ("box 1", "box"), ("sub 1/box in sub", "box"), ("sub 1/pin A", "pin"), ("far box", "box")]}
    # The far box spans (FAR, 2.5, -3.25) + (10, 20, 30): its top face and
    # its +x face, hit from outside.
    far = FAR_MM[unit]
    for origin, direction, point in [
        ([far + 5, 12.5, 1000.0], [0, 0, -1], [far + 5, 12.5, 26.75]),
        ([far + 1000.0, 12.5, 10.0], [-1, 0, 0], [far + 10, 12.5, 10.0]),
    ]:
        _, hit, _ = dmu(dmu_bin, "pick", store, "--ray", ",".join(map(repr, origin + direction)), "--json")
        hit = json.loads(hit)
        assert hit["path"] == "top/far box" and hit["properties"]["StepProduct"] == "box"
        assert max(abs(a - b) for a, b in zip(hit["point"], point)) <= 1e-6, (hit["point"], point)


def test_step_with_a_broken_brep_imports_the_rest_and_names_it(dmu_bin, tmp_path):
    from test_cad_convert import write_broken_step

    step = write_broken_step(tmp_path / "pair.step")
    _, summary, _ = dmu(dmu_bin, "import", step, "-o", tmp_path / "pair.dmu", "--no-lod", "--json")
    summary = json.loads(summary)
    (failed,) = summary["report"]["failed_products"]
    assert (failed["name"], failed["class"]) == ("bad part", "STEP product") and failed["reason"]
    assert summary["parts"] == 1 and summary["converted"]["failed"] == 1


def test_files_that_are_not_step_or_ifc_are_one_line_errors_naming_them(dmu_bin, tmp_path):
    ifcopenshell()
    (tmp_path / "x.step").write_text("this is not a STEP file\n")
    whole = (IFC / "duplex.ifc").read_bytes()
    (tmp_path / "cut.ifc").write_bytes(whole[:len(whole) // 2])
    for name in ["x.step", "cut.ifc"]:
        status, out, err = dmu(dmu_bin, "info", tmp_path / name, check=False)
        assert status == 2 and out == "", err
        assert len(err.strip().splitlines()) == 1 and name in err, err
    # A Python without OCP (blocked, as if not installed): the error names
    # the file, the package and the command that installs it.
    from test_cad_convert import write_step

    step = write_step(tmp_path / "a.step")
    blocked = tmp_path / "python-without-ocp"
    blocked.write_text(f"#!/bin/sh\nexec {sys.executable} -c \"import runpy, sys; sys.modules['OCP'] = None; "
                       "sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')\" \"$@\"\n")
    blocked.chmod(0o755)
    env = dict(os.environ, DMU_PYTHON=str(blocked))
    missing = subprocess.run([str(dmu_bin), "info", str(step)], capture_output=True, text=True, env=env, timeout=120)
    assert missing.returncode == 2 and len(missing.stderr.strip().splitlines()) == 1, missing.stderr
    assert "a.step" in missing.stderr and "needs the Python package OCP" in missing.stderr, missing.stderr
    assert "pip install cadquery-ocp-novtk" in missing.stderr, missing.stderr
