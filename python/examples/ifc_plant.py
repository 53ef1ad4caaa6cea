"""A plant model made with ``ifcopenshell.api``: a grid of rooms on one
storey, each with a floor slab, walls, pipes and ducts. The pipes and
ducts run along x through the walls between rooms (no openings are cut),
so a clash test finds each of them against the walls it crosses.

    python examples/ifc_plant.py plant.ifc --rooms 12   # 12 x 12 rooms: 2,184 elements
"""

from __future__ import annotations

import argparse
from typing import Any, List

import ifcopenshell
import ifcopenshell.api.aggregate
import ifcopenshell.api.context
import ifcopenshell.api.geometry
import ifcopenshell.api.project
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.unit
import numpy as np

ROOM_M = 6.0
"""A room's side, metres (ifcopenshell.api takes SI units; the file is in mm)."""
HEIGHT_M = 3.0
PIPES = 8
DUCTS = 4


def _placement(model: Any, product: Any, at: "tuple[float, float, float]", along_x: bool = False) -> None:
    matrix = np.eye(4)
    if along_x:
        # The profile is extruded along its local z: turn local z to world x.
        matrix[:3, :3] = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    matrix[:3, 3] = at
    ifcopenshell.api.geometry.edit_object_placement(model, product=product, matrix=matrix)


def make_plant(rooms: int = 12) -> Any:
    """The model of ``rooms`` x ``rooms`` rooms: rooms**2 slabs, walls on
    every grid line (2 * rooms * (rooms + 1)), and per room 8 pipes
    (IfcPipeSegment, round) and 4 ducts (IfcDuctSegment, rectangular)."""
    model = ifcopenshell.api.project.create_file(version="IFC4")
    project = ifcopenshell.api.root.create_entity(model, ifc_class="IfcProject", name="Plant")
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

    def element(ifc_class: str, name: str, representation: Any) -> Any:
        e = ifcopenshell.api.root.create_entity(model, ifc_class=ifc_class, name=name)
        ifcopenshell.api.geometry.assign_representation(model, product=e, representation=representation)
        return e

    # One representation per kind, shared by every element of the kind (as
    # a modeller's types do); each element has its own placement.
    wall_rep = ifcopenshell.api.geometry.add_wall_representation(
        model, context=body, length=ROOM_M, height=HEIGHT_M, thickness=0.2
    )
    slab_rep = ifcopenshell.api.geometry.add_slab_representation(
        model, context=body, depth=0.2, polyline=[(0.0, 0.0), (ROOM_M, 0.0), (ROOM_M, ROOM_M), (0.0, ROOM_M)]
    )
    # Profiles are written in the file's unit (mm); depths are SI.
    pipe = model.create_entity("IfcCircleProfileDef", ProfileType="AREA", Radius=60.0)
    pipe_rep = ifcopenshell.api.geometry.add_profile_representation(model, context=body, profile=pipe, depth=ROOM_M)
    duct = model.create_entity("IfcRectangleProfileDef", ProfileType="AREA", XDim=300.0, YDim=200.0)
    duct_rep = ifcopenshell.api.geometry.add_profile_representation(model, context=body, profile=duct, depth=ROOM_M)

    products: List[Any] = []
    n = rooms
    for i in range(n + 1):
        for j in range(n):
            # Walls along x on the line y = i, and along y on the line x = i.
            w = element("IfcWall", f"Wall X{i}-{j}", wall_rep)
            _placement(model, w, (j * ROOM_M, i * ROOM_M - 0.1, 0.0))
            products.append(w)
            w = element("IfcWall", f"Wall Y{i}-{j}", wall_rep)
            matrix = np.eye(4)
            matrix[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
            matrix[:3, 3] = (i * ROOM_M + 0.1, j * ROOM_M, 0.0)
            ifcopenshell.api.geometry.edit_object_placement(model, product=w, matrix=matrix)
            products.append(w)
    for i in range(n):
        for j in range(n):
            x0, y0 = i * ROOM_M, j * ROOM_M
            s = element("IfcSlab", f"Slab {i}-{j}", slab_rep)
            _placement(model, s, (x0, y0, -0.2))
            products.append(s)
            for k in range(PIPES):
                p = element("IfcPipeSegment", f"Pipe {i}-{j}-{k}", pipe_rep)
                # Half a room along: each pipe crosses the wall between two rooms.
                _placement(model, p, (x0 + ROOM_M / 2, y0 + 0.6 + 0.6 * k, 2.2 + 0.05 * (k % 3)), along_x=True)
                products.append(p)
            for k in range(DUCTS):
                d = element("IfcDuctSegment", f"Duct {i}-{j}-{k}", duct_rep)
                _placement(model, d, (x0 + ROOM_M / 2, y0 + 1.0 + 1.2 * k, 2.7), along_x=True)
                products.append(d)
    ifcopenshell.api.spatial.assign_container(model, relating_structure=storey, products=products)
    return model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("out", help="the .ifc file to write")
    ap.add_argument("--rooms", type=int, default=12, help="rooms per side of the grid")
    args = ap.parse_args()
    model = make_plant(args.rooms)
    model.write(args.out)
    print(f"{args.out}: {len(model.by_type('IfcElement'))} elements")


if __name__ == "__main__":
    main()
