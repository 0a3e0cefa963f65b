"""Figures of classified point tracks (SPEC 10): the track in 3D with its fitted structure."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from stslam.render.articulation import MODEL_COLOURS, UNDECIDED_COLOUR


def structure_curve(structure, model: str, points_world) -> np.ndarray | None:
    """Points (k, 3) drawing a fitted structure: the circle, the line over the track's extent, or the point."""
    if structure is None:
        return None
    if model == "revolute":
        a = np.linspace(0.0, 2.0 * np.pi, 181)[:, None]
        x0, y0 = structure.centre_xy
        return (structure.p0 + (x0 + structure.radius * np.cos(a)) * structure.v1
                + (y0 + structure.radius * np.sin(a)) * structure.v2)
    if model == "prismatic":
        along = (np.asarray(points_world) - structure.p0) @ structure.direction
        return structure.p0 + np.outer([along.min(), along.max()], structure.direction)
    return np.asarray(structure.p0).reshape(1, 3)


def track_figure(points_world, model: str | None, structure, title: str) -> Figure:
    """3D view (m, capture frame) of a track, coloured by time, with its chosen model's structure.

    For a revolute joint the hinge axis is drawn through the circle centre.
    """
    # Fixed margins: a 3D axes leaves the constrained layout engine nothing to gain, and the
    # engine doubles the cost of drawing.
    figure = Figure(figsize=(4.6, 4.2))
    figure.subplots_adjust(left=0.0, right=0.92, bottom=0.04, top=0.94)
    draw_track(figure.add_subplot(projection="3d"), points_world, model, structure, title)
    return figure


def tracks_overview(panels: list[tuple], columns: int = 5) -> Figure:
    """One sheet of small 3D views, a panel per ``(points_world, model, structure, title, wrong)``.

    A wrong classification (``wrong`` true) has its title in red. One sheet costs
    about a third of as many single figures (one file pair to write).
    """
    if not panels:
        raise ValueError("tracks_overview: expected at least one panel")
    columns = min(columns, len(panels))
    rows = -(-len(panels) // columns)
    figure = Figure(figsize=(2.7 * columns, 2.6 * rows))
    figure.subplots_adjust(left=0.0, right=0.97, bottom=0.02, top=0.95, wspace=0.05, hspace=0.15)
    for k, (points, model, structure, title, wrong) in enumerate(panels):
        axes = figure.add_subplot(rows, columns, k + 1, projection="3d")
        draw_track(axes, points, model, structure, title, small=True)
        if wrong:
            axes.title.set_color("tab:red")
    return figure


def draw_track(axes, points_world, model: str | None, structure, title: str, small: bool = False) -> None:
    """Draw one track and its structure into a 3D ``axes`` (cubic limits about the track)."""
    p = np.asarray(points_world)
    axes.scatter(p[:, 0], p[:, 1], p[:, 2], c=np.arange(len(p)), cmap="viridis", s=2 if small else 3,
                 depthshade=False)
    colour = MODEL_COLOURS.get(model, UNDECIDED_COLOUR)
    curve = structure_curve(structure, model, p)
    if curve is not None:
        axes.plot(curve[:, 0], curve[:, 1], curve[:, 2], "-" if len(curve) > 1 else "o", color=colour,
                  linewidth=1.5, label=f"{model} fit")
    if model == "revolute" and structure is not None:
        half = max(structure.radius, 0.1)
        axis = structure.axis_point + np.outer([-half, half], structure.axis_direction)
        axes.plot(axis[:, 0], axis[:, 1], axis[:, 2], "k--", linewidth=1, label="hinge axis")
    span = np.ptp(np.vstack([p] + ([curve] if curve is not None else [])), axis=0).max() / 2 or 0.1
    centre = p.mean(axis=0)
    axes.set_xlim(centre[0] - span, centre[0] + span)
    axes.set_ylim(centre[1] - span, centre[1] + span)
    axes.set_zlim(centre[2] - span, centre[2] + span)
    if small:  # a sheet of many: the title says what it is; ticks only crowd it
        axes.set_xticklabels([])
        axes.set_yticklabels([])
        axes.set_zticklabels([])
        axes.set_title(title, fontsize="x-small")
        return
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_zlabel("z (m)")
    axes.set_title(title, fontsize="small")
    if curve is not None:
        axes.legend(fontsize="x-small", loc="upper left")
