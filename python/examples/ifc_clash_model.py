"""An IFC4 model for clash tests, made with ``ifcopenshell.api``, with
planned hard clashes, touches and clearances (docs/clash.md, "Against
IfcClash"). A grid of rooms on one storey; per room (mm):

- a floor slab, 200 thick, top at z = 0; walls 200 thick, 3,000 high on
  every grid line (walls meet at the grid corners: they overlap there);
- 4 pipes (DN 120) along x at z = 2,200, each in two segments meeting end
  to end at x = 3,500 (a touch), crossing the wall at the room's
  far side (hard);
- 2 ducts 300 x 200 along x at z = 2,600, crossing the wall (hard);
- a column 300 x 300 beside the first pipe, 30 mm from it (a clearance
  below 50 mm), standing on the slab (a touch);
- a beam 200 x 300 along y on top of the walls, z = 3,000 .. 3,300
  (touches), and a duct lying on the slab (a touch).

    python examples/ifc_clash_model.py model.ifc --rooms 14   # 3,332 elements
    python examples/ifc_clash_model.py model.ifc --rooms 56   # 50,624 elements
"""

from __future__ import annotations

import argparse
import time
from typing import Any, List, Tuple

import ifcopenshell
import ifcopenshell.api.aggregate
import ifcopenshell.api.context
import ifcopenshell.api.geometry
import ifcopenshell.api.project
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.unit
import numpy as np

ROOM = 6000.0
HEIGHT = 3000.0
PIPES = 4
DUCTS = 2

# Turns a profile's local z (its extrusion) to world x, or to world y.
ALONG_X = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
ALONG_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def make_model(rooms: int) -> Any:
    """The model of ``rooms`` x ``rooms`` rooms (see the module's notes)."""
    model = ifcopenshell.api.project.create_file(version="IFC4")
    project = ifcopenshell.api.root.create_entity(model, ifc_class="IfcProject", name="Clash model")
    ifcopenshell.api.unit.assign_unit(model)  # millimetres
    context = ifcopenshell.api.context.add_context(model, context_type="Model")
    body = ifcopenshell.api.context.add_context(
        model, context_type="Model", context_identifier="Body", target_view="MODEL_VIEW", parent=context
    )
    site = ifcopenshell.api.root.create_entity(model, ifc_class="IfcSite", name="Site")
    building = ifcopenshell.api.root.create_entity(model, ifc_class="IfcBuilding", name="Building")
    storey = ifcopenshell.api.root.create_entity(model, ifc_class="IfcBuildingStorey", name="Level 0")
    ifcopenshell.api.aggregate.assign_object(model, relating_object=project, products=[site])
    ifcopenshell.api.aggregate.assign_object(model, relating_object=site, products=[building])
    ifcopenshell.api.aggregate.assign_object(model, relating_object=building, products=[storey])

    def rect(x: float, y: float, depth_mm: float) -> Any:
        profile = model.create_entity("IfcRectangleProfileDef", ProfileType="AREA", XDim=x, YDim=y)
        return ifcopenshell.api.geometry.add_profile_representation(
            model, context=body, profile=profile, depth=depth_mm / 1000.0
        )

    circle = model.create_entity("IfcCircleProfileDef", ProfileType="AREA", Radius=60.0)
    half_pipe = ifcopenshell.api.geometry.add_profile_representation(
        model, context=body, profile=circle, depth=ROOM / 2 / 1000.0
    )
    # A wall along x, from its placement: 200 thick (y), 3,000 high (z).
    wall_x = rect(ROOM, 200.0, HEIGHT)
    slab = rect(ROOM, ROOM, 200.0)
    duct = rect(300.0, 200.0, ROOM)
    floor_duct = rect(300.0, 200.0, 2000.0)
    column = rect(300.0, 300.0, HEIGHT)
    beam = rect(200.0, 300.0, ROOM)

    products: List[Any] = []

    def element(ifc_class: str, name: str, rep: Any, at: Tuple[float, float, float], turn: Any = None) -> None:
        e = ifcopenshell.api.root.create_entity(model, ifc_class=ifc_class, name=name)
        ifcopenshell.api.geometry.assign_representation(model, product=e, representation=rep)
        m = np.eye(4)
        if turn is not None:
            m[:3, :3] = turn
        m[:3, 3] = np.array(at) / 1000.0
        ifcopenshell.api.geometry.edit_object_placement(model, product=e, matrix=m)
        products.append(e)

    quarter = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    n = rooms
    for i in range(n + 1):
        for j in range(n):
            # Rectangle profiles are centred: a wall along x on the line y = i * ROOM.
            element("IfcWall", f"Wall X{i}-{j}", wall_x, (j * ROOM + ROOM / 2, i * ROOM, 0.0))
            element("IfcWall", f"Wall Y{i}-{j}", wall_x, (i * ROOM, j * ROOM + ROOM / 2, 0.0), quarter)
    for i in range(n):
        for j in range(n):
            x0, y0 = i * ROOM, j * ROOM
            element("IfcSlab", f"Slab {i}-{j}", slab, (x0 + ROOM / 2, y0 + ROOM / 2, -200.0))
            for k in range(PIPES):
                y = y0 + 700.0 + 500.0 * k
                # Two halves end to end at the room's middle; the second crosses the wall at x0 + ROOM.
                element("IfcPipeSegment", f"Pipe {i}-{j}-{k}a", half_pipe, (x0 + 500.0, y, 2200.0), ALONG_X)
                element("IfcPipeSegment", f"Pipe {i}-{j}-{k}b", half_pipe, (x0 + 3500.0, y, 2200.0), ALONG_X)
            for k in range(DUCTS):
                element("IfcDuctSegment", f"Duct {i}-{j}-{k}", duct, (x0 + ROOM / 2 + 700, y0 + 3000.0 + 800.0 * k, 2600.0), ALONG_X)
            # 30 mm from the first pipe's side (pipe radius 60, column half-width 150).
            element("IfcColumn", f"Column {i}-{j}", column, (x0 + 1500.0, y0 + 700.0 + 60.0 + 30.0 + 150.0, 0.0))
            element("IfcBeam", f"Beam {i}-{j}", beam, (x0 + 3000.0, y0 + ROOM / 2, HEIGHT + 150.0), ALONG_Y)
            element("IfcDuctSegment", f"Floor duct {i}-{j}", floor_duct, (x0 + 2500.0, y0 + 4000.0, 150.0), ALONG_X)
    ifcopenshell.api.spatial.assign_container(model, relating_structure=storey, products=products)
    return model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("out", help="the .ifc file to write")
    ap.add_argument("--rooms", type=int, default=14, help="rooms per side of the grid")
    args = ap.parse_args()
    started = time.perf_counter()
    model = make_model(args.rooms)
    model.write(args.out)
    print(f"{args.out}: {len(model.by_type('IfcElement'))} elements in {time.perf_counter() - started:.1f} s")


if __name__ == "__main__":
    main()
