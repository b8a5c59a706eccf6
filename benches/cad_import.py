#!/usr/bin/env python3
"""dmu's STEP and IFC import beside the converters engineers reach for.

For each input, alternately and `--repeat` times (medians reported):
- `dmu import FILE -o OUT.dmu --no-lod --json` (the converter runs with this
  interpreter: DMU_PYTHON), the whole import: conversion and store;
- IFC: IfcOpenShell's glTF serializer, the one `IfcConvert model.ifc
  model.glb` runs, driven by the same multi-core iterator (IfcConvert is not
  on PyPI; its serializer is);
- STEP: OpenCascade's own glTF writer (`RWGltf_CafWriter`) after reading the
  file with XCAF and meshing it in parallel with the same deflections.

Each is a child process under `/usr/bin/time`, whose peak resident set is
that of the largest process (dmu or its converter). Inputs: the three IFC
files in ../shared/data/ifc, and a STEP assembly this script writes with
OpenCascade (`--step-parts` distinct filleted, drilled parts, each placed
`--step-instances` times in sub-assemblies).

Usage (in a venv with the dmu wheel's `cad` extra):
    python benches/cad_import.py [--dmu target/release/dmu] [--repeat 3] [--json]
"""

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile

REPO = pathlib.Path(__file__).resolve().parents[1]
IFC = REPO.parent / "shared" / "data" / "ifc"

IFCCONVERT = """
import multiprocessing, sys
import ifcopenshell, ifcopenshell.geom
f = ifcopenshell.open(sys.argv[1])
settings = ifcopenshell.geom.settings()
serializer = ifcopenshell.geom.serializers.gltf(sys.argv[2], settings)
serializer.setFile(f)
serializer.writeHeader()
it = ifcopenshell.geom.iterator(settings, f, multiprocessing.cpu_count(), exclude=("IfcSpace", "IfcOpeningElement"))
if it.initialize():
    while True:
        serializer.write(it.get())
        if not it.next():
            break
serializer.finalize()
"""

OCCT_GLTF = """
import sys
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.collections import IndexedDataMap_TCollection_AsciiString_TCollection_AsciiString, Sequence_TDF_Label
from OCP.Message import Message_ProgressRange
from OCP.RWGltf import RWGltf_CafWriter
from OCP.STEPCAFControl import STEPCAFControl_Reader
from OCP.TCollection import TCollection_AsciiString, TCollection_ExtendedString
from OCP.TDocStd import TDocStd_Document
from OCP.XCAFApp import XCAFApp_Application
from OCP.XCAFDoc import XCAFDoc_DocumentTool
doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
XCAFApp_Application.GetApplication_s().InitDocument(doc)
reader = STEPCAFControl_Reader()
reader.SetNameMode(True)
reader.SetColorMode(True)
reader.ReadFile(sys.argv[1])
reader.Transfer(doc)
shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
labels = Sequence_TDF_Label()
shapes.GetFreeShapes(labels)
for i in range(1, labels.Length() + 1):
    BRepMesh_IncrementalMesh(shapes.GetShape_s(labels.Value(i)), 0.001, True, 0.5, True)
writer = RWGltf_CafWriter(TCollection_AsciiString(sys.argv[2]), True)
writer.SetParallel(True)
assert writer.Perform(doc, IndexedDataMap_TCollection_AsciiString_TCollection_AsciiString(), Message_ProgressRange())
"""


def write_step_assembly(path, parts, instances):
    """A STEP assembly of `parts` distinct parts (boxes with a fillet and a
    hole, of different sizes), each placed `instances` times in a row of
    sub-assemblies; returns (parts placed, distinct parts)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt, gp_Trsf, gp_Vec
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_StepModelType
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopAbs import TopAbs_ShapeEnum
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    XCAFApp_Application.GetApplication_s().InitDocument(doc)
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())

    def named(label, name):
        TDataStd_Name.Set_s(label, TCollection_ExtendedString(name))
        return label

    def at(x, y, z):
        t = gp_Trsf()
        t.SetTranslation(gp_Vec(x, y, z))
        return TopLoc_Location(t)

    top = named(shapes.NewShape(), "plant")
    for p in range(parts):
        w, d, h = 40.0 + 3 * p, 30.0 + 2 * p, 20.0 + p
        solid = BRepPrimAPI_MakeBox(w, d, h).Shape()
        fillet = BRepFilletAPI_MakeFillet(solid)
        edges = TopExp_Explorer(solid, TopAbs_ShapeEnum.TopAbs_EDGE)
        while edges.More():
            fillet.Add(2.0, TopoDS.Edge(edges.Current()))
            edges.Next()
        solid = fillet.Shape()
        hole = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(w / 2, d / 2, -1), gp_Dir(0, 0, 1)), min(w, d) / 5, h + 2).Shape()
        solid = BRepAlgoAPI_Cut(solid, hole).Shape()
        part = named(shapes.AddShape(solid, False), f"part {p}")
        row = named(shapes.NewShape(), f"row {p}")
        for i in range(instances):
            named(shapes.AddComponent(row, part, at(i * 80.0, 0, 0)), f"part {p}.{i}")
        named(shapes.AddComponent(top, row, at(0, p * 80.0, 0)), f"row {p}")
    shapes.UpdateAssemblies()
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    assert writer.Transfer(doc, STEPControl_StepModelType.STEPControl_AsIs)
    assert writer.Write(str(path)).name == "IFSelect_RetDone"
    return parts * instances, parts


def timed(command, env=None):
    """(seconds, peak RSS bytes, stdout) of a command under /usr/bin/time."""
    with tempfile.NamedTemporaryFile("r") as times:
        out = subprocess.run(["/usr/bin/time", "-o", times.name, "-f", "%e %M", *map(str, command)],
                             capture_output=True, text=True, env=env, timeout=3600)
        assert out.returncode == 0, out.stderr
        seconds, kb = times.read().split()
    return float(seconds), int(kb) * 1024, out.stdout


def measure(args, name, source, other_name, other_command, folder):
    env = dict(os.environ, DMU_PYTHON=sys.executable)
    runs = {"dmu": [], other_name: []}
    summary = None
    for _ in range(args.repeat):
        seconds, rss, out = timed([args.dmu, "import", source, "-o", folder / "out.dmu", "--no-lod", "--json"], env)
        summary = json.loads(out)
        runs["dmu"].append((seconds, rss, summary["converted"]["seconds"]))
        seconds, rss, _ = timed(other_command)
        runs[other_name].append((seconds, rss, seconds))
    products, triangles = summary["converted"]["products"], summary["triangles"]
    row = {"input": name, "products": products, "triangles": triangles,
           "unique_triangles": summary["unique_triangles"], "failed": summary["converted"]["failed"]}
    for who, rs in runs.items():
        seconds = statistics.median(r[0] for r in rs)
        row[who] = {"seconds": seconds, "conversion_seconds": statistics.median(r[2] for r in rs),
                    "peak_rss_bytes": max(r[1] for r in rs), "products_per_s": products / seconds,
                    "triangles_per_s": triangles / seconds}
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dmu", default=REPO / "target" / "release" / "dmu", type=pathlib.Path)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--step-parts", type=int, default=20)
    parser.add_argument("--step-instances", type=int, default=25)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        for ifc in sorted(IFC.glob("*.ifc")):
            rows.append(measure(args, ifc.name, ifc, "ifcconvert_gltf",
                                [sys.executable, "-c", IFCCONVERT, ifc, folder / "ifc.glb"], folder))
        step = folder / "plant.step"
        # OpenCascade's writer prints its banners on file descriptor 1.
        saved = os.dup(1)
        os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
        try:
            write_step_assembly(step, args.step_parts, args.step_instances)
        finally:
            os.dup2(saved, 1)
            os.close(saved)
        rows.append(measure(args, f"plant.step ({args.step_parts} parts x {args.step_instances})", step,
                            "occt_gltf", [sys.executable, "-c", OCCT_GLTF, step, folder / "step.glb"], folder))
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print("| input | products | triangles | tool | seconds | products/s | triangles/s | peak RSS MB |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        for who in [k for k in r if isinstance(r[k], dict)]:
            m = r[who]
            print(f"| {r['input']} | {r['products']} | {r['triangles']} | {who} | {m['seconds']:.2f} | "
                  f"{m['products_per_s']:.0f} | {m['triangles_per_s']:.0f} | {m['peak_rss_bytes'] / 1e6:.0f} |")


if __name__ == "__main__":
    main()
