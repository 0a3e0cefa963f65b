"""Geometry of the rendered fridge room: textured quads, boxes and the door hinge (SPEC 9).

World frame: x east, y north, z up, metres; the floor is z = 0. Every surface
is a :class:`TexturedQuad`, a parallelogram ``corner + a·edge_u + b·edge_v``
for a, b ∈ [0, 1] seen from one side only: its front normal is
``normalise(edge_v × edge_u)``. Built as (corner = top-left seen from the front,
edge_u = rightwards, edge_v = downwards), the texture appears upright.

The door is a thin box that turns about a vertical hinge axis. Door state
(SPEC 9): a point on the hinge axis ``hinge_point_world`` (m), its unit
direction ``hinge_axis_world`` and the opening angle φ (rad, 0 = closed); the
door panel is the closed panel turned by φ about the axis by the right-hand
rule, so φ > 0 opens it towards the room.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from stslam.geometry import rotation_about_axis
from stslam.rgbd import textures as tex
# Surface labels of the label image (0 = nothing rendered).
LABEL_ROOM = 1
LABEL_FURNITURE = 2
LABEL_FRIDGE_BODY = 3
LABEL_FRIDGE_INSIDE = 4
LABEL_DOOR_FRONT = 5
LABEL_DOOR_OTHER = 6
DOOR_LABELS = (LABEL_DOOR_FRONT, LABEL_DOOR_OTHER)

# Unit light direction (towards the light) and shading weights: shade = ambient + diffuse·max(0, n·l).
LIGHT_DIR_WORLD = np.array([0.35, -0.5, 0.79]) / np.linalg.norm([0.35, -0.5, 0.79])
AMBIENT, DIFFUSE = 0.6, 0.4


@dataclass(frozen=True)
class TexturedQuad:
    """One textured, one-sided planar parallelogram.

    Attributes
    ----------
    corner_world : numpy.ndarray, shape (3,)
        Top-left corner seen from the front (m, world frame).
    edge_u_world, edge_v_world : numpy.ndarray, shape (3,)
        Edges along texture columns (rightwards) and rows (downwards), m.
    texture : int
        Index into the scene's texture list.
    label : int
        Surface label written into the label image.
    shade : float
        Brightness factor applied to the texture (fixed Lambertian shading).
    """

    corner_world: np.ndarray
    edge_u_world: np.ndarray
    edge_v_world: np.ndarray
    texture: int
    label: int
    shade: float = 1.0

    @property
    def normal_world(self) -> np.ndarray:
        """Unit front normal ``edge_v × edge_u / |…|``, shape (3,)."""
        n = np.cross(self.edge_v_world, self.edge_u_world)
        return n / np.linalg.norm(n)


def lambert_shade(normal_world) -> float:
    """Brightness of a surface with unit normal ``normal_world``: ambient + diffuse·max(0, n·l)."""
    return float(AMBIENT + DIFFUSE * max(0.0, float(np.dot(normal_world, LIGHT_DIR_WORLD))))


def shaded(quad: TexturedQuad) -> TexturedQuad:
    """``quad`` with its shade set from its normal (:func:`lambert_shade`)."""
    return replace(quad, shade=lambert_shade(quad.normal_world))


def box_quads(min_xyz, max_xyz, textures: dict, label: int, outward: bool = True) -> list[TexturedQuad]:
    """The faces of an axis-aligned box as quads.

    Parameters
    ----------
    min_xyz, max_xyz : array_like, shape (3,)
        Opposite corners of the box (m, world frame).
    textures : dict
        Texture index per face name: any of ``"-x", "+x", "-y", "+y", "top", "bottom"``;
        faces not named are left out.
    label : int
        Label of every face.
    outward : bool
        Faces visible from outside (a piece of furniture) or inside (the room).
    """
    x0, y0, z0 = (float(v) for v in min_xyz)
    x1, y1, z1 = (float(v) for v in max_xyz)
    down = np.array([0.0, 0.0, z0 - z1])
    # Each face: corner (top-left seen from outside) and its rightwards edge.
    faces = {
        "-y": (np.array([x0, y0, z1]), np.array([x1 - x0, 0.0, 0.0]), down),
        "+y": (np.array([x1, y1, z1]), np.array([x0 - x1, 0.0, 0.0]), down),
        "-x": (np.array([x0, y1, z1]), np.array([0.0, y0 - y1, 0.0]), down),
        "+x": (np.array([x1, y0, z1]), np.array([0.0, y1 - y0, 0.0]), down),
        "top": (np.array([x0, y1, z1]), np.array([x1 - x0, 0.0, 0.0]), np.array([0.0, y0 - y1, 0.0])),
        "bottom": (np.array([x0, y0, z0]), np.array([x1 - x0, 0.0, 0.0]), np.array([0.0, y1 - y0, 0.0])),
    }
    quads = []
    for name, texture in textures.items():
        corner, edge_u, edge_v = faces[name]
        if not outward:  # mirror: seen from inside, the face's right is the other way
            corner, edge_u = corner + edge_u, -edge_u
        quads.append(shaded(TexturedQuad(corner, edge_u, edge_v, texture, label)))
    return quads


def door_quads_at(closed_quads, hinge_point_world, hinge_axis_world, angle_rad: float) -> list[TexturedQuad]:
    """Door faces turned by ``angle_rad`` about the hinge axis (SPEC 9), reshaded.

    X' = p + R(a, φ)(X − p) for each point X of the closed door, p the hinge point.
    """
    R = rotation_about_axis(hinge_axis_world, angle_rad)
    p = np.asarray(hinge_point_world, dtype=float)
    return [shaded(replace(q, corner_world=p + R @ (q.corner_world - p), edge_u_world=R @ q.edge_u_world,
                           edge_v_world=R @ q.edge_v_world)) for q in closed_quads]


@dataclass(frozen=True)
class FridgeRoom:
    """The fridge room: static quads, the closed door, its hinge, and textures.

    Attributes
    ----------
    static_quads : list[TexturedQuad]
        Room, furniture and fridge body (world frame).
    door_closed_quads : list[TexturedQuad]
        The door box with the door closed (world frame).
    hinge_point_world : numpy.ndarray, shape (3,)
        Point on the hinge axis at floor height (m).
    hinge_axis_world : numpy.ndarray, shape (3,)
        Unit hinge direction (+z: φ > 0 swings the free edge towards the room).
    door_closed_direction_world : numpy.ndarray, shape (3,)
        Unit vector from the hinge along the closed door panel to its free edge.
    fridge_front_centre_world : numpy.ndarray, shape (3,)
        Centre of the closed door's front face (m), what the camera path circles.
    textures : list[numpy.ndarray]
        RGB uint8 textures (rows, cols, 3), indexed by ``TexturedQuad.texture``.
    """

    static_quads: list
    door_closed_quads: list
    hinge_point_world: np.ndarray
    hinge_axis_world: np.ndarray
    door_closed_direction_world: np.ndarray
    fridge_front_centre_world: np.ndarray
    textures: list = field(repr=False)

    def quads_at(self, door_angle_rad: float) -> list[TexturedQuad]:
        """All quads with the door opened by ``door_angle_rad``."""
        return self.static_quads + door_quads_at(self.door_closed_quads, self.hinge_point_world,
                                                 self.hinge_axis_world, door_angle_rad)


def fridge_room(rng: np.random.Generator, room_size_m=(6.0, 5.0, 2.6)) -> FridgeRoom:
    """Build the fridge room with textures drawn from ``rng`` (SPEC 9).

    Layout (metres, world frame): room [0, X] × [0, Y] × [0, Z]; a fridge 0.8 m
    wide, 0.7 m deep, 1.8 m tall against the north wall (y = Y) centred at
    x = X/2; its door (5 cm thick) hinged on its east front edge; a kitchen
    counter west of the fridge, a shelf east of it and a table and a crate in
    the room.
    """
    X, Y, Z = (float(v) for v in room_size_m)
    textures: list[np.ndarray] = []

    def add(image: np.ndarray) -> int:
        textures.append(image)
        return len(textures) - 1

    ppm_room, ppm_furniture, ppm_fridge = 120.0, 150.0, 300.0
    quads: list[TexturedQuad] = []
    quads += box_quads((0, 0, 0), (X, Y, Z), {
        "-y": add(tex.painted_wall(rng, (X, Z), ppm_room)),
        "+y": add(tex.painted_wall(rng, (X, Z), ppm_room)),
        "-x": add(tex.painted_wall(rng, (Y, Z), ppm_room)),
        "+x": add(tex.painted_wall(rng, (Y, Z), ppm_room)),
        "top": add(tex.plain_panel(rng, (X, Y), 40.0, (235, 235, 230))),
        "bottom": add(tex.tiled_floor(rng, (X, Y), ppm_room)),
    }, LABEL_ROOM, outward=False)
    fx0, fx1 = X / 2 - 0.4, X / 2 + 0.4
    fy0, fy1, fz1 = Y - 0.7, Y, 1.8

    def furniture(lo, hi, faces):
        size = np.subtract(hi, lo)
        spec = {}
        for face in faces:
            dims = {"-y": (size[0], size[2]), "+y": (size[0], size[2]), "-x": (size[1], size[2]),
                    "+x": (size[1], size[2]), "top": (size[0], size[1])}[face]
            spec[face] = add(tex.wood(rng, dims, ppm_furniture))
        return box_quads(lo, hi, spec, LABEL_FURNITURE)

    quads += furniture((fx0 - 1.4, Y - 0.6, 0.0), (fx0 - 0.05, Y, 0.9), ("-y", "+x", "-x", "top"))
    quads += furniture((fx1 + 0.05, Y - 0.4, 0.0), (fx1 + 1.1, Y, 1.5), ("-y", "-x", "+x", "top"))
    quads += furniture((0.7, 1.9, 0.0), (1.7, 2.7, 0.75), ("-y", "+y", "-x", "+x", "top"))
    quads += furniture((4.6, 1.2, 0.0), (5.1, 1.6, 0.45), ("-y", "+y", "-x", "+x", "top"))

    body_colour = (225, 228, 230)
    quads += box_quads((fx0, fy0, 0.0), (fx1, fy1, fz1), {
        "-x": add(tex.plain_panel(rng, (0.7, fz1), 100.0, body_colour)),
        "+x": add(tex.plain_panel(rng, (0.7, fz1), 100.0, body_colour)),
        "top": add(tex.plain_panel(rng, (0.8, 0.7), 100.0, body_colour)),
    }, LABEL_FRIDGE_BODY)
    quads += box_quads((fx0, fy0, 0.0), (fx1, fy1, fz1), {
        "-y": add(tex.fridge_interior(rng, (0.8, fz1), ppm_fridge)),
    }, LABEL_FRIDGE_INSIDE)

    # Door: 0.8 × 1.76 m, 5 cm thick, 5 mm in front of the body; hinge on its east front edge.
    gap, thick = 0.005, 0.05
    dy1 = fy0 - gap
    dy0 = dy1 - thick
    lo, hi = (fx0, dy0, 0.02), (fx1, dy1, fz1 - 0.02)
    door = box_quads(lo, hi, {"-y": add(tex.fridge_door_front(rng, (0.8, 1.76), ppm_fridge))},
                     LABEL_DOOR_FRONT)
    door += box_quads(lo, hi, {
        "+y": add(tex.fridge_interior(rng, (0.8, 1.76), ppm_fridge, n_shelves=5)),
        "-x": add(tex.plain_panel(rng, (thick, 1.76), 200.0, (200, 200, 205))),
        "+x": add(tex.plain_panel(rng, (thick, 1.76), 200.0, (200, 200, 205))),
        "top": add(tex.plain_panel(rng, (0.8, thick), 200.0, (200, 200, 205))),
        "bottom": add(tex.plain_panel(rng, (0.8, thick), 200.0, (120, 120, 120))),
    }, LABEL_DOOR_OTHER)
    return FridgeRoom(
        static_quads=quads,
        door_closed_quads=door,
        hinge_point_world=np.array([fx1, dy0, 0.0]),
        hinge_axis_world=np.array([0.0, 0.0, 1.0]),
        door_closed_direction_world=np.array([-1.0, 0.0, 0.0]),
        fridge_front_centre_world=np.array([X / 2, dy0, 0.9]),
        textures=textures,
    )
