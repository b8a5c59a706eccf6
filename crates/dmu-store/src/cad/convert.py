#!/usr/bin/env python3
"""Converts a STEP or IFC file into a GLB 2.0 that dmu's glTF importer reads.

    python3 convert.py INPUT OUTPUT.glb [--deflection 0.001]
        [--angular-deflection 0.5] [--ifc-include CLASS,...] [--threads N]

STEP goes through OpenCascade's XCAF (PyPI `cadquery-ocp-novtk`, module OCP),
IFC through IfcOpenShell; each package is imported only for its format.

Design choices:
- Millimetres everywhere; node matrices LOCAL to the parent, column-major,
  written as Python float reprs (full double precision).
- One glTF mesh per distinct shape (STEP: part label and colour; IFC: the
  iterator's geometry id), referenced by every node placing it. Positions are
  float32 in the part's frame; a mesh reaching past 10 m from that frame's
  origin is stored about its centre (rounded to the mm) and the offset folded
  into its nodes' matrices, so float32 keeps micrometres.
- OUTPUT appears whole or not at all (OUTPUT.part, fsync, rename); the binary
  chunk is spooled to an unnamed temporary file beside it meanwhile.
- stdout carries JSON lines only; what the native libraries print on file
  descriptors 1 and 2 goes to /dev/null.
- Exit 2 with one stderr line for bad input, 3 for a missing package.
"""

import argparse
import importlib
import json
import math
import multiprocessing
import os
import resource
import shutil
import struct
import sys
import tempfile
import time

try:
    import numpy as np
except ImportError:  # refused with the missing package's name in convert()
    np = None

EXIT_BAD_INPUT, EXIT_MISSING_PACKAGE = 2, 3
DEFAULT_RGBA = (0.6, 0.6, 0.6, 1.0)
IFC_LEFT_OUT_BY_DEFAULT = ("IfcSpace", "IfcOpeningElement")
RECENTRE_BEYOND_MM = 1.0e4


class BadInput(Exception):
    """The input cannot be converted; printed after "FILE: "."""


class MissingPackage(Exception):
    """The Python package a format needs is not installed."""


class Reporter:
    """The JSON lines on stdout; keeps the failed products."""

    def __init__(self, stream):
        self.stream, self.failures, self.last = stream, [], (0.0, None)

    def line(self, obj):
        self.stream.write(json.dumps(obj) + "\n")
        self.stream.flush()

    def progress(self, done, total):
        """At most ten lines a second, never the same twice, always the last."""
        now = time.monotonic()
        if [done, total] != self.last[1] and (done >= total or now - self.last[0] >= 0.1):
            self.last = (now, [done, total])
            self.line({"progress": [done, total]})

    def failed(self, name, cls, reason, **more):
        entry = {"name": name, "class": cls, "reason": reason, **more}
        self.failures.append(entry)
        self.line({"failed": entry})


class Node:
    """An assembly node: `matrix` 4×4 float64 relative to the parent (None:
    identity), `extras` string properties, `mesh` a glTF mesh index or None."""

    def __init__(self, name, extras, matrix=None, mesh=None):
        self.name, self.extras, self.matrix, self.mesh = name or "unnamed", extras, matrix, mesh
        self.children = []


def compose(a, b):
    """a·b, where None stands for identity."""
    return b if a is None else a if b is None else a @ b


class Glb:
    """The materials, meshes and binary chunk of the GLB being built."""

    def __init__(self, spool):
        self.spool, self.bin_length = spool, 0
        self.materials, self.material_index = [], {}
        self.meshes, self.accessors, self.views, self.mesh_triangles = [], [], [], []

    def material(self, rgba, name=None):
        """The index of the material of colour `rgba` (deduplicated by colour)."""
        rgba = tuple(round(min(max(float(c), 0.0), 1.0), 6) for c in rgba)
        if rgba not in self.material_index:
            self.material_index[rgba] = len(self.materials)
            self.materials.append({
                "name": name or "#%02x%02x%02x" % tuple(round(c * 255) for c in rgba[:3]),
                "pbrMetallicRoughness": {"baseColorFactor": list(rgba), "metallicFactor": 0.0,
                                         "roughnessFactor": 0.8},
                **({"alphaMode": "BLEND"} if rgba[3] < 1.0 else {})})
        return self.material_index[rgba]

    def mesh(self, name, groups):
        """Adds a mesh of one primitive per material; `groups` maps a material
        to [(positions (n,3) mm, triangles (m,3))]. Returns (mesh index, offset
        matrix or None), or None when it has no triangles."""
        merged = {}
        for material, parts in sorted(groups.items()):
            bases = np.cumsum([0] + [len(p) for p, _ in parts])
            triangles = np.concatenate([t + base for (_, t), base in zip(parts, bases)])
            if len(triangles):
                merged[material] = (np.concatenate([p for p, _ in parts]), triangles)
        if not merged:
            return None
        lo = np.min([p.min(axis=0) for p, _ in merged.values()], axis=0)
        hi = np.max([p.max(axis=0) for p, _ in merged.values()], axis=0)
        far = max(np.abs(lo).max(), np.abs(hi).max()) > RECENTRE_BEYOND_MM
        offset = np.round((lo + hi) / 2) if far else np.zeros(3)
        primitives = []
        for material, (positions, triangles) in merged.items():
            local = (positions - offset).astype(np.float32)
            position = self._accessor(local, 34962, {"componentType": 5126, "type": "VEC3",
                                                     "min": local.min(axis=0).tolist(),
                                                     "max": local.max(axis=0).tolist()})
            indices = self._accessor(triangles.astype(np.uint32).reshape(-1), 34963,
                                     {"componentType": 5125, "type": "SCALAR"})
            primitives.append({"mode": 4, "material": material, "attributes": {"POSITION": position},
                               "indices": indices})
        self.meshes.append({"name": name, "primitives": primitives})
        self.mesh_triangles.append(sum(len(t) for _, t in merged.values()))
        matrix = np.eye(4)
        matrix[:3, 3] = offset
        return len(self.meshes) - 1, matrix if far else None

    def _accessor(self, array, target, accessor):
        data = np.ascontiguousarray(array).tobytes()
        padding = -len(data) % 4
        self.views.append({"buffer": 0, "byteOffset": self.bin_length, "byteLength": len(data), "target": target})
        self.spool.write(data + b"\0" * padding)
        self.bin_length += len(data) + padding
        self.accessors.append(dict(accessor, bufferView=len(self.views) - 1, count=len(array)))
        return len(self.accessors) - 1

    def document(self, root):
        """The glTF JSON with `root`'s children as the scene's root nodes (dmu
        names the scene after the file, so `root` itself is left out), and the
        number of nodes placing a mesh and of the triangles they place."""
        nodes, placed = [], [0, 0]

        def emit(node):
            index, entry = len(nodes), {"name": node.name}
            nodes.append(entry)
            if node.matrix is not None and not np.array_equal(node.matrix, np.eye(4)):
                entry["matrix"] = [float(x) for x in node.matrix.T.reshape(-1)]
            if node.mesh is not None:
                entry["mesh"] = node.mesh
                placed[0] += 1
                placed[1] += self.mesh_triangles[node.mesh]
            if node.extras:
                entry["extras"] = node.extras
            if node.children:
                entry["children"] = [emit(child) for child in node.children]
            return index

        roots = [emit(child) for child in root.children]
        doc = {"asset": {"version": "2.0", "generator": "dmu cad/convert.py"},
               "scene": 0, "scenes": [{"name": root.name, "nodes": roots}], "nodes": nodes}
        if self.materials:
            doc["materials"] = self.materials
        if self.meshes:
            doc.update(meshes=self.meshes, accessors=self.accessors, bufferViews=self.views,
                       buffers=[{"byteLength": self.bin_length}])
        return doc, placed[0], placed[1]

    def write(self, path, doc):
        """Writes the GLB to `path`.part, syncs it and renames it to `path`."""
        body = json.dumps(doc, separators=(",", ":")).encode()
        body += b" " * (-len(body) % 4)
        total = 20 + len(body) + (8 + self.bin_length if self.bin_length else 0)
        if total >= 2**32:
            raise BadInput(f"the GLB would be {total} bytes, past glTF's 4 GiB")
        part = path + ".part"
        try:
            with open(part, "wb") as out:
                out.write(struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(body), b"JSON") + body)
                if self.bin_length:
                    out.write(struct.pack("<I4s", self.bin_length, b"BIN\0"))
                    self.spool.seek(0)
                    shutil.copyfileobj(self.spool, out, 1 << 24)
                out.flush()
                os.fsync(out.fileno())
            os.replace(part, path)
        finally:
            if os.path.exists(part):
                os.remove(part)


# ---- STEP through OpenCascade XCAF -----------------------------------------

def step_modules():
    """The OCP modules the STEP reader uses (occ.XCAFDoc, ...), or MissingPackage."""
    names = ("BRep", "BRepMesh", "IFSelect", "Interface", "OSD", "Quantity", "STEPCAFControl", "TCollection",
             "TDataStd", "TDF", "TDocStd", "TopAbs", "TopExp", "TopLoc", "TopoDS", "XCAFApp", "XCAFDoc", "collections")
    try:
        return argparse.Namespace(**{name: importlib.import_module(f"OCP.{name}") for name in names})
    except ImportError as e:
        raise MissingPackage("reading STEP needs the Python package OCP: pip install cadquery-ocp-novtk") from e


class StepReader:
    """Walks an XCAF document: assemblies become nodes, each part label is
    meshed once, each (part, colour) pair becomes one glTF mesh."""

    def __init__(self, occ, doc, options, glb, reporter, source):
        self.occ, self.options, self.glb, self.reporter, self.source = occ, options, glb, reporter, source
        self.shapes = occ.XCAFDoc.XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
        self.faces = {}   # part entry -> [(face rgba or None, positions, triangles)], None when failed
        self.meshes = {}  # (part entry, rgba) -> (mesh index, offset matrix) or None

    def entry(self, label):
        text = self.occ.TCollection.TCollection_AsciiString()
        self.occ.TDF.TDF_Tool.Entry_s(label, text)
        return text.ToCString()

    def name(self, label):
        attribute = self.occ.TDataStd.TDataStd_Name()
        found = label.FindAttribute(self.occ.TDataStd.TDataStd_Name.GetID_s(), attribute)
        return attribute.Get().ToExtString() if found else ""

    def product_id(self, label):
        """The id of the STEP PRODUCT behind a product label, None where it has
        none: the product metadata read during the transfer (once per product)
        keeps it as the string "ProductID", and leaves out an empty one."""
        data, key = self.occ.TDataStd.TDataStd_NamedData(), self.occ.TCollection.TCollection_ExtendedString("ProductID")
        found = label.FindAttribute(self.occ.TDataStd.TDataStd_NamedData.GetID_s(), data) and data.HasString(key)
        return data.GetString(key).ToExtString() if found else None

    def colour(self, label):
        """The surface (else generic) colour set on `label`, RGBA, or None."""
        kinds, colour = self.occ.XCAFDoc.XCAFDoc_ColorType, self.occ.Quantity.Quantity_ColorRGBA()
        for kind in (kinds.XCAFDoc_ColorSurf, kinds.XCAFDoc_ColorGen):
            if self.occ.XCAFDoc.XCAFDoc_ColorTool.GetColor_s(label, kind, colour):
                rgb = colour.GetRGB()
                return (rgb.Red(), rgb.Green(), rgb.Blue(), colour.Alpha())
        return None

    def labels(self, fill):
        sequence = self.occ.collections.Sequence_TDF_Label()
        fill(sequence)
        return [sequence.Value(i) for i in range(1, sequence.Length() + 1)]

    def components(self, label):
        """[(component label, referred label)] of an assembly."""
        out = []
        for component in self.labels(lambda s: self.shapes.GetComponents_s(label, s, False)):
            referred = self.occ.TDF.TDF_Label()
            self.shapes.GetReferredShape_s(component, referred)
            out.append((component, referred))
        return out

    def matrix(self, location):
        """A TopLoc_Location as a 4×4 matrix, None for identity."""
        if location.IsIdentity():
            return None
        trsf = location.Transformation()
        return np.array([[trsf.Value(r, c) for c in range(1, 5)] for r in range(1, 4)] + [[0, 0, 0, 1]])

    def parts(self, label, found):
        """Collects the part labels under `label` (entry -> label), each once."""
        if self.shapes.IsAssembly_s(label):
            for _, referred in self.components(label):
                self.parts(referred, found)
        else:
            found.setdefault(self.entry(label), label)
        return found

    def mesh_parts(self, parts):
        """Meshes every part once, reporting progress and failures."""
        for done, (entry, label) in enumerate(parts.items(), 1):
            try:
                self.faces[entry] = self.part_faces(label)
            except BadInput as e:
                self.faces[entry] = None
                self.reporter.failed(self.name(label) or entry, "STEP product", str(e))
            self.reporter.progress(done, len(parts))

    def explore_faces(self, shape):
        explorer = self.occ.TopExp.TopExp_Explorer(shape, self.occ.TopAbs.TopAbs_ShapeEnum.TopAbs_FACE)
        while explorer.More():
            yield self.occ.TopoDS.TopoDS.Face(explorer.Current())
            explorer.Next()

    def face_colours(self, label):
        """Face hash -> [(face, rgba)] from the colours set on sub-shapes of `label`."""
        found = {}
        for sub in self.labels(lambda s: self.shapes.GetSubShapes_s(label, s)):
            rgba = self.colour(sub)
            for face in self.explore_faces(self.shapes.GetShape_s(sub)) if rgba else ():
                found.setdefault(hash(face), []).append((face, rgba))
        return found

    def part_faces(self, label):
        """Meshes a part: [(face rgba or None, positions mm, triangles)], counter-
        clockwise seen from outside; BadInput when it yields no triangle."""
        shape = self.shapes.GetShape_s(label)
        if shape.IsNull():
            raise BadInput("no shape")
        try:
            mesher = self.occ.BRepMesh.BRepMesh_IncrementalMesh(
                shape, self.options.deflection, True, self.options.angular_deflection, True)
        except Exception as e:  # OCCT's Standard_Failure
            raise BadInput(f"meshing failed: {e}") from e
        colours, faces, count = self.face_colours(label), [], 0
        for face in self.explore_faces(shape):
            count += 1
            location = self.occ.TopLoc.TopLoc_Location()
            mesh = self.occ.BRep.BRep_Tool.Triangulation_s(face, location)
            if mesh is None or mesh.NbTriangles() == 0:
                continue
            positions = np.array([mesh.Node(i).Coord() for i in range(1, mesh.NbNodes() + 1)])
            triangles = np.array([mesh.Triangle(i).Get() for i in range(1, mesh.NbTriangles() + 1)]) - 1
            m = self.matrix(location)
            if m is not None:
                positions = positions @ m[:3, :3].T + m[:3, 3]
            if face.Orientation() == self.occ.TopAbs.TopAbs_Orientation.TopAbs_REVERSED:
                triangles = triangles[:, ::-1]
            rgba = next((c for f, c in colours.get(hash(face), []) if f.IsSame(face)), None)
            faces.append((rgba, positions, triangles))
        if not faces:
            what = f"{count} faces (mesher status {mesher.GetStatusFlags()})" if count else "the reader kept no face"
            raise BadInput(f"no triangles: {what}")
        return faces

    def mesh_of(self, label, rgba):
        """The (mesh index, offset matrix) of a part in default colour `rgba`, None if it failed."""
        entry = self.entry(label)
        if (entry, rgba) not in self.meshes:
            groups = {}
            for face_rgba, positions, triangles in self.faces[entry] or []:
                groups.setdefault(self.glb.material(face_rgba or rgba), []).append((positions, triangles))
            self.meshes[entry, rgba] = self.glb.mesh(self.name(label) or entry, groups) if groups else None
        return self.meshes[entry, rgba]

    def node(self, label, name, matrix, override, fallback):
        """The node of a shape label placed by `matrix`, None for a failed part.
        Colours: a face's own, else the nearest instance's (`override`), else
        the part's, else the nearest assembly's (`fallback`)."""
        extras, product_id = {"StepProduct": self.name(label)}, self.product_id(label)
        if product_id is not None:
            extras["StepProductId"] = product_id
        extras["SourceFile"] = self.source
        if not self.shapes.IsAssembly_s(label):
            made = self.mesh_of(label, override or self.colour(label) or fallback or DEFAULT_RGBA)
            return made and Node(name, extras, compose(matrix, made[1]), made[0])
        node, fallback = Node(name, extras, matrix), self.colour(label) or fallback
        for component, referred in self.components(label):
            child = self.node(referred, self.name(component) or self.name(referred),
                              self.matrix(self.shapes.GetLocation_s(component)),
                              self.colour(component) or override, fallback)
            if child is not None:
                node.children.append(child)
        return node


def read_step(path, options, glb, reporter, root):
    """Reads a STEP file into `root`; returns the format's name."""
    occ = step_modules()
    occ.OSD.OSD_ThreadPool.DefaultPool_s(options.threads)
    reader = occ.STEPCAFControl.STEPCAFControl_Reader()
    occ.Interface.Interface_Static.SetCVal_s("xstep.cascade.unit", "MM")
    reader.SetNameMode(True)
    reader.SetColorMode(True)
    reader.SetProductMetaMode(True)  # PRODUCT.id, read by StepReader.product_id
    status = reader.ReadFile(path)
    if status != occ.IFSelect.IFSelect_ReturnStatus.IFSelect_RetDone:
        raise BadInput(f"truncated or not a STEP file (OCCT reader status {status.name})")
    doc = occ.TDocStd.TDocStd_Document(occ.TCollection.TCollection_ExtendedString("XmlXCAF"))
    occ.XCAFApp.XCAFApp_Application.GetApplication_s().InitDocument(doc)
    occ.XCAFDoc.XCAFDoc_DocumentTool.SetLengthUnit_s(doc, 0.001)  # metres per document unit
    step = StepReader(occ, doc, options, glb, reporter, os.path.basename(path))
    free = step.labels(step.shapes.GetFreeShapes) if reader.Transfer(doc) else []
    if not free:
        raise BadInput("no shapes")
    step.mesh_parts({k: v for label in free for k, v in step.parts(label, {}).items()})
    for label in free:
        child = step.node(label, step.name(label), None, None, None)
        if child is not None:
            root.children.append(child)
    return "STEP"


# ---- IFC through IfcOpenShell ----------------------------------------------

def ifc_modules():
    """ifcopenshell with its geometry module, or MissingPackage."""
    try:
        import ifcopenshell
        import ifcopenshell.geom
    except ImportError as e:
        raise MissingPackage("reading IFC needs the Python package ifcopenshell: pip install ifcopenshell") from e
    return ifcopenshell


def ifc_extras(entity, source):
    extras = {"GlobalId": entity.GlobalId, "IfcClass": entity.is_a()}
    if getattr(entity, "Name", None):
        extras["Name"] = entity.Name
    extras["SourceFile"] = source
    return extras


def has_body(product):
    """Whether the product has a representation identified as 'Body'."""
    shape = product.Representation
    return bool(shape) and any(r.RepresentationIdentifier == "Body" for r in shape.Representations)


def ifc_mesh(glb, geometry):
    """The (mesh index, offset matrix) of an IfcOpenShell geometry (metres), None when empty."""
    verts = np.frombuffer(geometry.verts_buffer, dtype=np.float64).reshape(-1, 3) * 1000.0
    faces = np.frombuffer(geometry.faces_buffer, dtype=np.int32).reshape(-1, 3)
    ids = np.frombuffer(geometry.material_ids_buffer, dtype=np.int32)
    materials = [glb.material((*s.surface.components, 1.0 - s.transparency if math.isfinite(s.transparency) else 1.0),
                              s.name) for s in geometry.materials]
    groups = {}
    for k in np.unique(ids):
        used, local = np.unique(faces[ids == k], return_inverse=True)
        material = materials[k] if 0 <= k < len(materials) else glb.material(DEFAULT_RGBA, "default")
        groups.setdefault(material, []).append((verts[used], local.reshape(-1, 3)))
    return glb.mesh(geometry.id, groups)


def ifc_failure_reason(ifcopenshell, settings, product):
    """Why `product` yields no geometry: the first error of a second try with its own log."""
    log = ifcopenshell.ifcopenshell_wrapper.logger()
    log.output_format(log.FMT_JSON)
    log.verbosity(log.LOG_ERROR)
    try:
        shape = ifcopenshell.geom.create_shape(settings, product, logger=log)
        reason = "empty geometry" if shape and not shape.geometry.faces else "no geometry from the iterator"
    except Exception as e:
        reason = str(e)
    for line in log.get_log().splitlines():
        try:
            error = json.loads(line)
        except ValueError:
            continue
        reason = f"{error.get('code', '')} {error.get('message', '')} {error.get('instance', '')}".strip()
        break
    return reason[:300]


def ifc_shapes(ifcopenshell, ifc, settings, excluded, options, glb, reporter):
    """Runs the iterator: product id -> (world matrix mm, mesh index)."""
    log = ifcopenshell.ifcopenshell_wrapper.logger()
    log.verbosity(log.LOG_ERROR)
    iterator = ifcopenshell.geom.iterator(settings, ifc, options.threads, exclude=excluded or None, logger=log)
    placed, meshes = {}, {}
    if iterator.initialize():
        while True:
            shape = iterator.get()
            key = shape.geometry.id
            if key not in meshes:
                meshes[key] = ifc_mesh(glb, shape.geometry)
            if meshes[key]:
                world = np.array(shape.transformation.matrix, dtype=np.float64).reshape(4, 4).T
                world[:3, 3] *= 1000.0
                placed[shape.id] = (compose(world, meshes[key][1]), meshes[key][0])
            reporter.progress(iterator.progress(), 100)
            if not iterator.next():
                break
    reporter.progress(100, 100)
    return placed


def ifc_parents(ifc):
    """Entity id -> the entity it goes under: its aggregate, else its spatial
    container, else (an opening) the element it voids."""
    parent = {}
    for relation, whole, part in (("IfcRelVoidsElement", "RelatingBuildingElement", "RelatedOpeningElement"),
                                  ("IfcRelContainedInSpatialStructure", "RelatingStructure", "RelatedElements"),
                                  ("IfcRelAggregates", "RelatingObject", "RelatedObjects")):
        for rel in ifc.by_type(relation):
            members = getattr(rel, part)
            for member in members if isinstance(members, tuple) else (members,):
                parent[member.id()] = getattr(rel, whole)
    return parent


def ifc_tree(ifc, placed, skipped, source):
    """The project node: every spatial element and placed product under its
    parent (skipping left-out classes), each matrix relative to its parent's world."""
    projects = ifc.by_type("IfcProject")
    if not projects:
        raise BadInput("no IfcProject")
    project, parent_of = projects[0], ifc_parents(ifc)
    nodes = {project.id(): (Node(project.Name or "IfcProject", ifc_extras(project, source)), None)}

    def cycle(entity):
        return BadInput(f"#{entity.id()} ({entity.is_a()} {getattr(entity, 'GlobalId', '')}) contains itself "
                        "through its aggregates or containers")

    def parent(entity):
        """The entity `entity` goes under, past left-out ones."""
        above, passed = parent_of.get(entity.id(), project), set()
        while above.id() in skipped:
            if above.id() in passed:
                raise cycle(above)
            passed.add(above.id())
            above = parent_of.get(above.id(), project)
        return above

    def place(entity):
        """Adds `entity`'s node and those above it not yet added (a loop,
        not recursion: aggregates nest to any depth)."""
        chain, on_chain = [], set()
        while entity.id() not in nodes:
            if entity.id() in on_chain:
                raise cycle(entity)
            on_chain.add(entity.id())
            chain.append(entity)
            entity = parent(entity)
        for entity in reversed(chain):
            parent_node, parent_world = nodes[parent(entity).id()]
            world, mesh = placed.get(entity.id(), (None, None))
            matrix = world if parent_world is None or world is None else np.linalg.solve(parent_world, world)
            node = Node(entity.Name or entity.is_a(), ifc_extras(entity, source), matrix, mesh)
            parent_node.children.append(node)
            nodes[entity.id()] = (node, compose(parent_world, matrix))

    spatial = "IfcSpatialStructureElement" if ifc.schema == "IFC2X3" else "IfcSpatialElement"
    for entity in [e for e in ifc.by_type(spatial) if e.id() not in skipped] + [ifc.by_id(i) for i in sorted(placed)]:
        place(entity)
    return nodes[project.id()][0]


def read_ifc(path, options, glb, reporter, root):
    """Reads an IFC file into `root`; returns its schema's name."""
    ifcopenshell = ifc_modules()
    try:
        ifc = ifcopenshell.open(path)
    except Exception as e:
        raise BadInput(f"not an IFC file ({e})") from e
    settings = ifcopenshell.geom.settings()
    for key, value in (("use-world-coords", False), ("weld-vertices", True), ("no-normals", True),
                       ("use-material-names", True), ("apply-default-materials", False)):
        settings.set(key, value)
    excluded = [e for c in IFC_LEFT_OUT_BY_DEFAULT if c not in options.ifc_include for e in ifc.by_type(c)]
    skipped = {e.id() for e in excluded}
    placed = ifc_shapes(ifcopenshell, ifc, settings, excluded, options, glb, reporter)
    for product in ifc.by_type("IfcProduct"):
        if product.id() not in placed and product.id() not in skipped and has_body(product):
            reporter.failed(product.Name or product.GlobalId, product.is_a(),
                            ifc_failure_reason(ifcopenshell, settings, product), GlobalId=product.GlobalId)
    root.children.append(ifc_tree(ifc, placed, skipped, os.path.basename(path)))
    return ifc.schema_identifier


# ---- command line ----------------------------------------------------------

def check_spf(path, kind):
    """Refuses a file that does not start and end as ISO 10303-21 (STEP and IFC both are)."""
    with open(path, "rb") as f:
        head = f.read(64).lstrip(b"\xef\xbb\xbf \t\r\n")
        f.seek(max(0, os.path.getsize(path) - 4096))
        tail = f.read().rstrip()
    article = "an" if kind == "IFC" else "a"
    if not head.startswith(b"ISO-10303-21;"):
        raise BadInput(f"truncated or not {article} {kind} file (no ISO-10303-21 header)")
    if not tail.endswith(b"END-ISO-10303-21;"):
        raise BadInput(f"truncated or not {article} {kind} file (no END-ISO-10303-21; at its end)")


def parse_args(argv):
    p = argparse.ArgumentParser(description="Converts STEP or IFC to a GLB for dmu, in millimetres.")
    p.add_argument("input")
    p.add_argument("output")
    p.add_argument("--deflection", type=float, default=0.001,
                   help="STEP chordal deflection, relative to the size of each edge and face (OCCT's isRelative)")
    p.add_argument("--angular-deflection", type=float, default=0.5, help="STEP angular deflection, radians")
    p.add_argument("--ifc-include", default="",
                   help="classes kept although left out by default: " + ",".join(IFC_LEFT_OUT_BY_DEFAULT))
    p.add_argument("--threads", type=int, default=multiprocessing.cpu_count(),
                   help="IfcOpenShell iterator threads; OCCT's thread pool for STEP")
    p.error = lambda message: p.exit(EXIT_BAD_INPUT, f"{p.prog}: {message}\n")  # one line, no usage
    args = p.parse_args(argv)
    args.threads = max(1, args.threads)
    args.ifc_include = {c.strip() for c in args.ifc_include.split(",") if c.strip()}
    return args


def convert(args, reporter):
    """Converts args.input into args.output; returns the summary."""
    start = time.monotonic()
    readers = {".step": ("STEP", read_step), ".stp": ("STEP", read_step), ".ifc": ("IFC", read_ifc)}
    extension = os.path.splitext(args.input)[1].lower()
    if extension not in readers:
        raise BadInput(f"unknown extension {extension!r} (expected .step, .stp or .ifc)")
    if not os.path.isfile(args.input):
        raise BadInput("no such file")
    kind, read = readers[extension]
    if np is None:
        raise MissingPackage(f"reading {kind} needs the Python package numpy: pip install numpy")
    check_spf(args.input, kind)
    name = os.path.basename(args.input)
    with tempfile.TemporaryFile(dir=os.path.dirname(os.path.abspath(args.output))) as spool:
        glb = Glb(spool)
        root = Node(os.path.splitext(name)[0], {"SourceFile": name})
        fmt = read(args.input, args, glb, reporter, root)
        doc, products, triangles = glb.document(root)
        summary = {"format": fmt, "products": products, "failed": len(reporter.failures), "triangles": triangles,
                   "unique_triangles": sum(glb.mesh_triangles), "meshes": len(glb.meshes),
                   "seconds": round(time.monotonic() - start, 3),
                   "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}
        doc["asset"]["extras"] = {"dmu_cad": dict(summary, failed_products=reporter.failures)}
        glb.write(args.output, doc)
    return summary


def detach_native_output():
    """Keeps Python's stdout and stderr on copies of fds 1 and 2, and sends what
    the native libraries print on fds 1 and 2 to /dev/null."""
    out, err = os.fdopen(os.dup(1), "w"), os.fdopen(os.dup(2), "w")
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    os.close(null)
    sys.stdout, sys.stderr = out, err


def main(argv=None):
    args = parse_args(argv)
    detach_native_output()
    reporter = Reporter(sys.stdout)
    try:
        reporter.line({"summary": convert(args, reporter)})
        return 0
    except MissingPackage as e:
        message, status = str(e), EXIT_MISSING_PACKAGE
    except (BadInput, OSError) as e:
        message, status = f"{os.path.basename(args.input)}: {e}", EXIT_BAD_INPUT
    except Exception as e:  # a library's error on input it could not read: still one line
        message, status = f"{os.path.basename(args.input)}: {type(e).__name__}: {e}", EXIT_BAD_INPUT
    print(" ".join(message.split()), file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
