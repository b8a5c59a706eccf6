"""The STEP/IFC converter (`crates/dmu-store/src/cad/convert.py`) alone,
against independent oracles: IfcOpenShell's own listing, containers and
world-coordinate shapes for the three sample IFC files, and STEP assemblies
made here through OCP's XCAF with known names, placements, colours and units,
their PRODUCT ids then set in the file's text.

The converter runs as a subprocess of this interpreter ($DMU_CAD_CONVERT
names another copy). The GLB is read with `json` + `struct` only. Under
CI=true a missing OCP, ifcopenshell or sample file fails; elsewhere it
skips, saying so. The `dmu` module is not needed.

IFC oracle rule: a product is expected when it has a representation whose
RepresentationIdentifier is 'Body' and it is not an IfcSpace or an
IfcOpeningElement (unless --ifc-include names the class). On the three
samples IfcOpenShell's iterator yields geometry for exactly those; a product
of the rule that yields none must be listed as failed, so the rule equals
written ∪ failed."""

import functools
import importlib
import json
import math
import os
import pathlib
import re
import struct
import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO, require

CONVERT = pathlib.Path(os.environ.get("DMU_CAD_CONVERT")
                       or pathlib.Path(__file__).resolve().parents[2] / "dmu-store/src/cad/convert.py")
IFC_DIR = REPO.parent / "shared/data/ifc"
IFC_SAMPLES = ["duplex", "fzk_haus", "mini_project"]
LEFT_OUT = ("IfcSpace", "IfcOpeningElement")
FAR_MM = {"MM": 1e7 + 0.0005, "M": 1e7 + 0.25}  # exact in the 13 digits OCCT's writer keeps
PRODUCT_IDS = {"top": "P-100-top", "sub": "P-101-sub", "box": "P-102-box", "pin": ""}  # by product name


def ocp():
    """OCP's modules used here (occ.XCAFDoc, ...), or a failure (CI) / skip."""
    names = ("BRepPrimAPI", "Interface", "Quantity", "STEPCAFControl", "STEPControl", "TCollection", "TDataStd",
             "TDocStd", "TopAbs", "TopExp", "TopLoc", "XCAFApp", "XCAFDoc", "gp")
    try:
        return type("OCP", (), {name: importlib.import_module(f"OCP.{name}") for name in names})
    except ImportError as e:
        require(False, f"OCP is not installed (pip install cadquery-ocp-novtk): {e}")


def ifcos():
    """ifcopenshell with its geometry and util modules, or a failure (CI) / skip."""
    try:
        import ifcopenshell
        import ifcopenshell.geom
        import ifcopenshell.util.element
        import ifcopenshell.util.unit
    except ImportError as e:
        require(False, f"ifcopenshell is not installed (pip install ifcopenshell): {e}")
    return ifcopenshell


def ifc_sample(name):
    path = IFC_DIR / f"{name}.ifc"
    require(path.is_file(), f"{path} is absent (../shared/data exists beside the checkout in CI)")
    return path


def run(input_path, output, *flags, python_prelude=None):
    """Runs the converter; returns (exit status, stdout lines as JSON, stderr)."""
    command = [sys.executable, str(CONVERT), str(input_path), str(output), *map(str, flags)]
    if python_prelude:
        command[1:2] = ["-c", f"{python_prelude}; import runpy, sys; sys.argv = sys.argv[1:]; "
                        "runpy.run_path(sys.argv[0], run_name='__main__')", str(CONVERT)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=900)
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    return done.returncode, lines, done.stderr


class Glb:
    """A GLB read with json + struct: the document, the binary chunk, and
    each node's parent, world matrix (float64) and positions."""

    def __init__(self, path):
        data = pathlib.Path(path).read_bytes()
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        assert (magic, version, length) == (b"glTF", 2, len(data))
        json_length, kind = struct.unpack_from("<I4s", data, 12)
        assert kind == b"JSON"
        self.doc = json.loads(data[20:20 + json_length])
        self.bin = b""
        if 20 + json_length < len(data):
            bin_length, kind = struct.unpack_from("<I4s", data, 20 + json_length)
            assert kind == b"BIN\0"
            self.bin = data[28 + json_length:28 + json_length + bin_length]
        self.nodes = self.doc["nodes"]
        self.parent = {c: i for i, n in enumerate(self.nodes) for c in n.get("children", [])}

    def matrix(self, i):
        m = self.nodes[i].get("matrix")
        return np.eye(4) if m is None else np.array(m, dtype=np.float64).reshape(4, 4).T

    def world(self, i):
        w = self.matrix(i)
        while i in self.parent:
            i = self.parent[i]
            w = self.matrix(i) @ w
        return w

    def ancestors(self, i):
        while i in self.parent:
            i = self.parent[i]
            yield i

    def accessor(self, index):
        a = self.doc["accessors"][index]
        view = self.doc["bufferViews"][a["bufferView"]]
        dtype, width = {5126: (np.float32, 3), 5125: (np.uint32, 1)}[a["componentType"]]
        start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        return np.frombuffer(self.bin, dtype, a["count"] * width, start).reshape(-1, width)

    def triangles(self, mesh):
        """[(material index, positions (n,3), triangles (m,3))] of a mesh."""
        out = []
        for p in self.doc["meshes"][mesh]["primitives"]:
            assert p.get("mode", 4) == 4
            assert self.doc["accessors"][p["indices"]]["componentType"] == 5125
            out.append((p["material"], self.accessor(p["attributes"]["POSITION"]),
                        self.accessor(p["indices"]).reshape(-1, 3)))
        return out

    def world_positions(self, i):
        w = self.world(i)
        pts = np.concatenate([p for _, p, _ in self.triangles(self.nodes[i]["mesh"])]).astype(np.float64)
        return pts @ w[:3, :3].T + w[:3, 3]

    def check_accessors(self):
        """Every POSITION accessor's min/max is its data's."""
        for mesh in self.doc.get("meshes", []):
            for p in mesh["primitives"]:
                a = self.doc["accessors"][p["attributes"]["POSITION"]]
                data = self.accessor(p["attributes"]["POSITION"])
                assert a["min"] == data.min(axis=0).tolist() and a["max"] == data.max(axis=0).tolist()

    def named(self, name):
        found = [i for i, n in enumerate(self.nodes) if n["name"] == name]
        assert len(found) == 1, f"{len(found)} nodes named {name!r}"
        return found[0]


def convert_ok(input_path, output, *flags):
    status, lines, err = run(input_path, output, *flags)
    assert status == 0, err
    assert all(set(line) <= {"progress", "failed", "summary"} and len(line) == 1 for line in lines)
    assert list(lines[-1]) == ["summary"]
    glb = Glb(output)
    failed = [line["failed"] for line in lines if "failed" in line]
    assert glb.doc["asset"]["extras"]["dmu_cad"] == dict(lines[-1]["summary"], failed_products=failed)
    assert not pathlib.Path(str(output) + ".part").exists()
    # The scene is named after the file (dmu's root); its nodes are the roots.
    (scene,) = glb.doc["scenes"]
    assert scene["name"] == pathlib.Path(input_path).stem
    assert scene["nodes"] and not any(r in glb.parent for r in scene["nodes"])
    for node in glb.nodes:
        assert node["name"] and all(isinstance(v, str) for v in node.get("extras", {}).values())
    glb.check_accessors()
    return glb, lines[-1]["summary"], failed


# ---- IFC -------------------------------------------------------------------

def expected_products(ifc, left_out):
    """(GlobalId, class) of the products the oracle rule expects."""
    def has_body(p):
        return bool(p.Representation) and any(
            r.RepresentationIdentifier == "Body" for r in p.Representation.Representations)
    return {(p.GlobalId, p.is_a()) for p in ifc.by_type("IfcProduct")
            if has_body(p) and not any(p.is_a(c) for c in left_out)}


@functools.lru_cache(maxsize=None)
def converted_ifc(name, tmp, *flags):
    """Converts a sample once per set of flags."""
    return convert_ok(ifc_sample(name), pathlib.Path(tmp) / f"{name}{''.join(flags)}.glb", *flags)


def check_ifc(ifcopenshell, ifc, glb, failed, left_out):
    """Products written ∪ failed = the oracle rule; each under its container; spatial nodes tagged."""
    written = {(n["extras"]["GlobalId"], n["extras"]["IfcClass"]) for n in glb.nodes if "mesh" in n}
    failed_ids = {(f["GlobalId"], f["class"]) for f in failed}
    assert not written & failed_ids
    assert written | failed_ids == expected_products(ifc, left_out)
    node_of = {n["extras"]["GlobalId"]: i for i, n in enumerate(glb.nodes) if "GlobalId" in n.get("extras", {})}
    for kind in ("IfcProject", "IfcSite", "IfcBuilding", "IfcBuildingStorey"):
        for e in ifc.by_type(kind):
            extras = glb.nodes[node_of[e.GlobalId]]["extras"]
            assert extras["IfcClass"] == e.is_a() and extras.get("Name") == (e.Name or None)
    util = ifcopenshell.util.element
    for guid, _ in written:
        product = ifc.by_guid(guid)
        container = util.get_container(product)
        while container is not None and container.is_a() in left_out:
            container = util.get_aggregate(container) or util.get_container(container)
        if container is not None:
            assert container.GlobalId in {glb.nodes[a]["extras"].get("GlobalId") for a in glb.ancestors(node_of[guid])}


@pytest.mark.parametrize("name", IFC_SAMPLES)
def test_ifc_products_containers_and_placements(name, tmp_path_factory):
    ifcopenshell = ifcos()
    glb, summary, failed = converted_ifc(name, tmp_path_factory.getbasetemp())
    ifc = ifcopenshell.open(str(ifc_sample(name)))
    (project,) = ifc.by_type("IfcProject")
    assert glb.doc["scenes"][0]["nodes"] == [0] and glb.nodes[0]["extras"]["GlobalId"] == project.GlobalId
    assert summary["format"] == ifc.schema_identifier
    check_ifc(ifcopenshell, ifc, glb, failed, LEFT_OUT)
    assert summary["products"] == sum("mesh" in n for n in glb.nodes)
    # World geometry: IfcOpenShell's own world-coordinate shapes, in metres, against ours in mm.
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    products = sorted(i for i, n in enumerate(glb.nodes) if "mesh" in n)
    for i in products[::max(1, len(products) // 25)]:
        shape = ifcopenshell.geom.create_shape(settings, ifc.by_guid(glb.nodes[i]["extras"]["GlobalId"]))
        theirs = np.array(shape.geometry.verts).reshape(-1, 3) * 1000.0
        ours = glb.world_positions(i)
        np.testing.assert_allclose(ours.min(axis=0), theirs.min(axis=0), atol=0.01)
        np.testing.assert_allclose(ours.max(axis=0), theirs.max(axis=0), atol=0.01)


def test_ifc_include_spaces(tmp_path_factory):
    ifcopenshell = ifcos()
    glb, _, failed = converted_ifc("duplex", tmp_path_factory.getbasetemp(), "--ifc-include", "IfcSpace")
    ifc = ifcopenshell.open(str(ifc_sample("duplex")))
    spaces = {n["extras"]["GlobalId"] for n in glb.nodes if n.get("extras", {}).get("IfcClass") == "IfcSpace"}
    assert spaces == {s.GlobalId for s in ifc.by_type("IfcSpace")} and len(spaces) == 21
    check_ifc(ifcopenshell, ifc, glb, failed, ("IfcOpeningElement",))


def test_ifc_failed_product_is_listed(tmp_path):
    ifcopenshell = ifcos()
    ifc = ifcopenshell.open(str(ifc_sample("duplex")))
    wall = ifc.by_type("IfcWallStandardCase")[0]
    for item in [r for r in wall.Representation.Representations if r.RepresentationIdentifier == "Body"][0].Items:
        item.Depth = -1.0  # a non-positive extrusion: IfcOpenShell refuses the wall
    ifc.write(str(tmp_path / "broken.ifc"))
    glb, summary, failed = convert_ok(tmp_path / "broken.ifc", tmp_path / "broken.glb")
    assert [(f["GlobalId"], f["class"], f["name"]) for f in failed] == [
        (wall.GlobalId, wall.is_a(), wall.Name)] and failed[0]["reason"]
    assert summary["failed"] == 1
    check_ifc(ifcopenshell, ifc, glb, failed, LEFT_OUT)


# ---- STEP ------------------------------------------------------------------

def write_step(path, unit="MM", broken_pair=False):
    """Writes an XCAF assembly. The default: top {box 1, sub 1 {box in sub,
    pin A}, far box}, one box part (red) placed 3 times, a pin (green, one
    face blue), `sub 1` turned 90° about z. `broken_pair`: pair {good 1, bad 1}."""
    occ = ocp()
    doc = occ.TDocStd.TDocStd_Document(occ.TCollection.TCollection_ExtendedString("XmlXCAF"))
    occ.XCAFApp.XCAFApp_Application.GetApplication_s().InitDocument(doc)
    shapes = occ.XCAFDoc.XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colours = occ.XCAFDoc.XCAFDoc_DocumentTool.ColorTool_s(doc.Main())

    def named(label, name):
        occ.TDataStd.TDataStd_Name.Set_s(label, occ.TCollection.TCollection_ExtendedString(name))
        return label

    def colour(label, rgb):
        colours.SetColor(label, occ.Quantity.Quantity_Color(*rgb, occ.Quantity.Quantity_TypeOfColor.Quantity_TOC_RGB),
                         occ.XCAFDoc.XCAFDoc_ColorType.XCAFDoc_ColorSurf)

    def at(x, y, z, turn=0.0):
        move, rotate = occ.gp.gp_Trsf(), occ.gp.gp_Trsf()
        move.SetTranslation(occ.gp.gp_Vec(x, y, z))
        rotate.SetRotation(occ.gp.gp_Ax1(occ.gp.gp_Pnt(0, 0, 0), occ.gp.gp_Dir(0, 0, 1)), turn)
        return occ.TopLoc.TopLoc_Location(move.Multiplied(rotate))

    box = named(shapes.AddShape(occ.BRepPrimAPI.BRepPrimAPI_MakeBox(10.0, 20.0, 30.0).Shape(), False), "box")
    pin_shape = occ.BRepPrimAPI.BRepPrimAPI_MakeCylinder(2.0, 15.0).Shape()
    pin = named(shapes.AddShape(pin_shape, False), "pin" if not broken_pair else "bad part")
    if broken_pair:
        named(box, "good part")
        top = named(shapes.NewShape(), "pair")
        named(shapes.AddComponent(top, box, at(0, 0, 0)), "good 1")
        named(shapes.AddComponent(top, pin, at(50, 0, 0)), "bad 1")
    else:
        colour(box, (0.8, 0.1, 0.2))
        colour(pin, (0.1, 0.7, 0.3))
        face = occ.TopExp.TopExp_Explorer(pin_shape, occ.TopAbs.TopAbs_ShapeEnum.TopAbs_FACE).Current()
        colour(shapes.AddSubShape(pin, face), (0.2, 0.3, 0.9))
        sub = named(shapes.NewShape(), "sub")
        named(shapes.AddComponent(sub, box, at(0, 0, 50)), "box in sub")
        named(shapes.AddComponent(sub, pin, at(20, 0, 0)), "pin A")
        top = named(shapes.NewShape(), "top")
        named(shapes.AddComponent(top, box, at(100, 0, 0)), "box 1")
        named(shapes.AddComponent(top, sub, at(0, 200, 0, math.pi / 2)), "sub 1")
        named(shapes.AddComponent(top, box, at(FAR_MM[unit], 2.5, -3.25)), "far box")
    shapes.UpdateAssemblies()
    writer = occ.STEPCAFControl.STEPCAFControl_Writer()
    assert occ.Interface.Interface_Static.SetCVal_s("write.step.unit", unit)  # after the writer exists
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    assert writer.Transfer(doc, occ.STEPControl.STEPControl_StepModelType.STEPControl_AsIs)
    assert writer.Write(str(path)).name == "IFSelect_RetDone"
    text = pathlib.Path(path).read_text()
    assert ("SI_UNIT(.MILLI.,.METRE.)" if unit == "MM" else "SI_UNIT($,.METRE.)") in text
    return path


def set_product_ids(path, ids):
    """Rewrites the id of each PRODUCT in the STEP file at `path` (OCCT's writer
    makes it the product's name) to ids[name]."""
    text, count = re.subn(r"\bPRODUCT\('([^']*)'", lambda m: f"PRODUCT('{ids[m.group(1)]}'", path.read_text())
    assert count == len(ids)
    path.write_text(text)
    return path


def all_outward(groups):
    """Whether every triangle of a convex mesh faces away from its centre."""
    positions = np.concatenate([p for p, _ in groups]).astype(np.float64)
    centre = (positions.min(axis=0) + positions.max(axis=0)) / 2
    for p, t in groups:
        a, b, c = (p[t[:, k]].astype(np.float64) for k in range(3))
        if not (np.einsum("ij,ij->i", np.cross(b - a, c - a), (a + b + c) / 3 - centre) > 0).all():
            return False
    return True


@pytest.mark.parametrize("unit", ["MM", "M"])
def test_step_assembly(unit, tmp_path):
    step = set_product_ids(write_step(tmp_path / f"asm_{unit}.step", unit), PRODUCT_IDS)
    glb, summary, failed = convert_ok(step, tmp_path / "asm.glb")
    assert summary["format"] == "STEP" and failed == [] and summary["failed"] == 0
    nodes = glb.nodes
    # Tree, names and ids: products and instances; an instance carries its product's id, none where it is empty.
    assert glb.doc["scenes"][0]["name"] == f"asm_{unit}"
    top = glb.named("top")
    assert [nodes[c]["name"] for c in nodes[top]["children"]] == ["box 1", "sub 1", "far box"]
    assert [nodes[c]["name"] for c in nodes[glb.named("sub 1")]["children"]] == ["box in sub", "pin A"]
    for node, product in [("top", "top"), ("sub 1", "sub"), ("box 1", "box"), ("far box", "box"),
                          ("box in sub", "box"), ("pin A", "pin")]:
        product_id = {"StepProductId": PRODUCT_IDS[product]} if PRODUCT_IDS[product] else {}
        assert nodes[glb.named(node)]["extras"] == {"StepProduct": product, **product_id, "SourceFile": step.name}
    # Instancing: one mesh for the three boxes, each its own node.
    boxes = [glb.named(n) for n in ("box 1", "box in sub", "far box")]
    assert len({nodes[b]["mesh"] for b in boxes}) == 1
    assert len(glb.doc["meshes"]) == summary["meshes"] == 2 < summary["products"] == 4
    # Units: the box is 10 × 20 × 30 mm whatever the file's unit; placements in mm.
    (_, box_positions, box_triangles), = glb.triangles(nodes[boxes[0]]["mesh"])
    np.testing.assert_allclose(box_positions.max(axis=0) - box_positions.min(axis=0), [10, 20, 30], atol=1e-4)
    for node, corner in [("box 1", [100, 0, 0]), ("box in sub", [0, 200, 50]), ("far box", [FAR_MM[unit], 2.5, -3.25])]:
        w = glb.world(glb.named(node))
        lowest = box_positions.min(axis=0).astype(np.float64)
        np.testing.assert_allclose(w[:3, :3] @ lowest + w[:3, 3], corner, rtol=0, atol=1e-6)
    np.testing.assert_allclose(glb.world(glb.named("box in sub"))[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    # Winding: counter-clockwise seen from outside (box and pin are convex).
    pin = glb.triangles(nodes[glb.named("pin A")]["mesh"])
    assert all_outward([(box_positions, box_triangles)]) and all_outward([(p, t) for _, p, t in pin])
    # Colours: part colours, and a face colour as its own primitive.
    rgb = [glb.doc["materials"][m]["pbrMetallicRoughness"]["baseColorFactor"] for m, _, _ in
           glb.triangles(nodes[boxes[0]]["mesh"]) + pin]
    np.testing.assert_allclose(rgb[0], [0.8, 0.1, 0.2, 1.0], atol=1e-3)
    assert sorted(np.round(c[:3], 3).tolist() for c in rgb[1:]) == [[0.1, 0.7, 0.3], [0.2, 0.3, 0.9]]
    assert summary["triangles"] == 3 * len(box_triangles) + sum(len(t) for _, _, t in pin)


# ---- bad input -------------------------------------------------------------

def assert_refused(status, lines, err, name):
    assert status == 2 and lines == []
    assert len(err.splitlines()) == 1 and err.startswith(f"{name}: "), err


def test_bad_inputs(tmp_path):
    ocp()
    ifcos()
    real = write_step(tmp_path / "real.step").read_bytes()
    (tmp_path / "x.step").write_text("this is not a STEP file\n")
    (tmp_path / "cut.step").write_bytes(real[:len(real) // 2])
    (tmp_path / "x.ifc").write_text("this is not an IFC file\n")
    whole = ifc_sample("duplex").read_bytes()
    (tmp_path / "cut.ifc").write_bytes(whole[:len(whole) // 2])  # IfcOpenShell alone reads what is there
    for name in ("x.step", "cut.step", "x.ifc", "cut.ifc"):
        assert_refused(*run(tmp_path / name, tmp_path / "out.glb"), name)
        assert not (tmp_path / "out.glb").exists() and not (tmp_path / "out.glb.part").exists()


@pytest.mark.parametrize("cycle", ["spaces", "storey"])
def test_ifc_containment_cycles_are_refused_naming_the_entity(tmp_path, cycle):
    """Crafted files whose aggregates and containers loop (two spaces
    aggregating each other with the walls contained in one; a storey
    aggregating its building) are one line naming an entity of the loop,
    never a hang or a recursion error."""
    ifcopenshell = ifcos()
    import ifcopenshell.guid

    ifc = ifcopenshell.open(str(ifc_sample("duplex")))
    if cycle == "spaces":
        s1, s2 = ifc.by_type("IfcSpace")[:2]
        ifc.createIfcRelAggregates(ifcopenshell.guid.new(), None, None, None, s1, [s2])
        ifc.createIfcRelAggregates(ifcopenshell.guid.new(), None, None, None, s2, [s1])
        for rel in ifc.by_type("IfcRelContainedInSpatialStructure"):
            rel.RelatingStructure = s1
        loop = {s1.id(), s2.id()}
    else:
        building, storey = ifc.by_type("IfcBuilding")[0], ifc.by_type("IfcBuildingStorey")[0]
        ifc.createIfcRelAggregates(ifcopenshell.guid.new(), None, None, None, storey, [building])
        loop = {building.id(), storey.id()}
    ifc.write(str(tmp_path / "loop.ifc"))
    status, lines, err = run(tmp_path / "loop.ifc", tmp_path / "loop.glb")
    assert_refused(status, [line for line in lines if "progress" not in line], err, "loop.ifc")
    assert "contains itself" in err and any(f"#{i} " in err for i in loop), err


def test_missing_package_exits_3(tmp_path):
    write_step(tmp_path / "a.step")
    status, lines, err = run(tmp_path / "a.step", tmp_path / "a.glb", python_prelude="import sys; sys.modules['OCP'] = None")
    assert (status, lines, err) == (3, [], "reading STEP needs the Python package OCP: pip install cadquery-ocp-novtk\n")


def write_broken_step(path):
    """The `broken_pair` assembly with every face of "bad part" (a cylinder)
    naming a point as its surface: OpenCascade keeps none of them, so that
    part alone cannot be tessellated."""
    text = write_step(path, broken_pair=True).read_text()
    text = re.sub(r"\s*\n\s*", " ", text).replace("; #", ";\n#")  # one entity a line
    entities = dict(re.findall(r"^#(\d+)\s*=\s*(.*?);\s*$", text, re.M))
    cylinder = next(i for i, e in entities.items() if e.startswith("CYLINDRICAL_SURFACE"))
    shell = next(e for e in entities.values() if e.startswith("CLOSED_SHELL") and any(
        re.search(rf",#{cylinder},", entities[f]) for f in re.findall(r"#(\d+)", e)))
    point = next(i for i, e in entities.items() if e.startswith("CARTESIAN_POINT"))
    for face in re.findall(r"#(\d+)", shell):  # every face of the pin now names a point as its surface
        text, count = re.subn(rf"(#{face}\s*=\s*ADVANCED_FACE\('[^']*',\s*\([^)]*\),\s*)#\d+", rf"\g<1>#{point}", text)
        assert count == 1
    path.write_text(text)
    return path


def test_step_broken_brep_fails_one_product(tmp_path):
    glb, summary, failed = convert_ok(write_broken_step(tmp_path / "pair.step"), tmp_path / "pair.glb")
    assert [(f["name"], f["class"]) for f in failed] == [("bad part", "STEP product")] and summary["failed"] == 1
    assert [n["name"] for n in glb.nodes if "mesh" in n] == ["good 1"] and summary["products"] == 1
