"""A frame of a ``scene.mcap`` drawn from above (and its camera image), for when Foxglove is not at hand."""

from __future__ import annotations

from matplotlib.figure import Figure

# Paths in colours apart from the model colours (red, green, blue, grey); the true path black.
PATH_COLOURS = ("tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "gold", "navy")


def scene_figure(snapshot, title: str = "") -> Figure:
    """Top view of paths, landmarks coloured by model and joints; beside it the image with corners, if any.

    ``snapshot`` is a :class:`stslam.io.scene_read.SceneSnapshot`.
    """
    colours = snapshot.model_colours
    has_image = snapshot.image_rgb is not None
    figure = Figure(figsize=(11.0 if has_image else 6.5, 5.2), layout="constrained")
    axes = figure.subplots(1, 2 if has_image else 1, squeeze=False)[0]
    top = axes[0]
    estimated = [name for name in snapshot.paths if name != "groundtruth"]
    for name, xy in snapshot.paths.items():
        colour = "k" if name == "groundtruth" else PATH_COLOURS[estimated.index(name) % len(PATH_COLOURS)]
        top.plot(xy[:, 0], xy[:, 1], label=name, color=colour, lw=2.0 if name == "groundtruth" else 1.2)
        if snapshot.frame < len(xy):
            top.plot(*xy[snapshot.frame], "o", ms=4, color=colour)
    for model in colours:
        chosen = [j for j, m in enumerate(snapshot.models) if m == model]
        if chosen:
            p = snapshot.positions[chosen]
            top.scatter(p[:, 0], p[:, 1], s=16, color=colours[model][:3], label=f"landmark: {model}",
                        zorder=3)
    for model, point, direction in snapshot.joints:
        colour = colours[model][:3]
        if model == "revolute":  # a vertical axis is a point seen from above
            top.plot(point[0], point[1], "x", ms=10, mew=2, color=colour, zorder=4)
        else:
            top.arrow(point[0], point[1], 0.4 * direction[0], 0.4 * direction[1], color=colour, width=0.01)
    top.set_aspect("equal", adjustable="datalim")
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.grid(alpha=0.3)
    top.legend(fontsize=7, loc="best")
    top.set_title(title or f"frame {snapshot.frame} of {snapshot.n_frames}, top view")
    if has_image:
        image = axes[1]
        image.imshow(snapshot.image_rgb)
        for model, uv in snapshot.corners.items():
            image.scatter(uv[:, 0], uv[:, 1], s=14, facecolors="none", edgecolors=[colours[model][:3]],
                          label=model)
        image.set_axis_off()
        image.set_title("colour image, tracked corners by model")
    return figure
