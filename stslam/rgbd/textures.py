"""Procedural surface textures for the rendered fridge room (SPEC 9).

Every texture is an RGB image, ``uint8`` of shape (rows, cols, 3), drawn from a
seeded ``numpy.random.Generator`` with numpy and OpenCV primitives only, so the
same generator state gives the same pixels. A texture covers a rectangle of
``size_m = (width m, height m)`` at ``ppm`` texels per metre; row 0 is the top
edge as seen from the front of the surface.

The designs aim at what a corner tracker needs: floor tiles, posters, wood and
shelves give moderate texture everywhere, and the fridge door front carries
magnets, photos, a calendar and lettered stickers so that it holds many strong
corners at every opening angle.
"""

from __future__ import annotations

import cv2
import numpy as np

# Hershey fonts are vector fonts built into OpenCV: deterministic and headless.
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_LETTERS = np.array(list("ABCDEFGHKLMNPRSTUVWXYZ0123456789"))


def texture_shape(size_m, ppm: float) -> tuple[int, int]:
    """(rows, cols) of a texture covering ``size_m`` (width m, height m) at ``ppm`` texels/m."""
    width_m, height_m = size_m
    return max(2, int(round(height_m * ppm))), max(2, int(round(width_m * ppm)))


def smooth_noise(rng: np.random.Generator, shape, cell_px: float, amplitude: float) -> np.ndarray:
    """Band-limited noise of shape ``shape`` (rows, cols), float32, std ≈ ``amplitude``.

    Gaussian white noise on a grid of ``cell_px`` texels, upsampled bicubically.
    """
    rows, cols = shape
    small = (max(2, int(np.ceil(rows / cell_px)) + 1), max(2, int(np.ceil(cols / cell_px)) + 1))
    coarse = rng.standard_normal(small).astype(np.float32) * amplitude
    return cv2.resize(coarse, (cols, rows), interpolation=cv2.INTER_CUBIC)


def _finish(image_f32: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(image_f32), 0, 255).astype(np.uint8)


def _random_colour(rng: np.random.Generator, low: int = 20, high: int = 235) -> tuple[int, int, int]:
    return tuple(int(c) for c in rng.integers(low, high, size=3))


def _draw_text(image: np.ndarray, rng: np.random.Generator, x0: int, y0: int, x1: int, y1: int,
               colour) -> None:
    """Random capital letters filling the box (x0, y0)–(x1, y1) in texels."""
    height = y1 - y0
    if height < 8 or x1 - x0 < 8:
        return
    scale = max(0.3, height / 40.0)
    thickness = max(1, int(round(scale * 2)))
    (char_w, char_h), _ = cv2.getTextSize("W", _FONT, scale, thickness)
    n_chars = max(1, (x1 - x0) // max(1, char_w))
    text = "".join(rng.choice(_LETTERS, size=n_chars))
    baseline_y = y0 + (height + char_h) // 2
    cv2.putText(image, text, (x0, baseline_y), _FONT, scale, colour, thickness, cv2.LINE_AA)


def _draw_pattern(image: np.ndarray, rng: np.random.Generator, x0: int, y0: int, x1: int,
                  y1: int) -> None:
    """One of: checkerboard, stripes, random blocks, text, inside a rectangle."""
    kind = int(rng.integers(0, 4))
    w, h = x1 - x0, y1 - y0
    if w < 4 or h < 4:
        return
    a, b = _random_colour(rng), _random_colour(rng)
    if kind == 0:
        cell = int(rng.integers(6, 16))
        ys, xs = np.mgrid[0:h, 0:w]
        mask = ((ys // cell + xs // cell) % 2).astype(bool)
        patch = np.empty((h, w, 3), np.uint8)
        patch[:] = a
        patch[mask] = b
        image[y0:y1, x0:x1] = patch
    elif kind == 1:
        image[y0:y1, x0:x1] = a
        period = int(rng.integers(8, 20))
        for x in range(x0, x1, period):
            cv2.rectangle(image, (x, y0), (min(x + period // 2, x1 - 1), y1 - 1), b, -1)
    elif kind == 2:
        image[y0:y1, x0:x1] = a
        for _ in range(int(rng.integers(3, 9))):
            bx0, by0 = int(rng.integers(x0, x1 - 2)), int(rng.integers(y0, y1 - 2))
            bx1 = int(min(x1 - 1, bx0 + rng.integers(4, max(5, w // 2))))
            by1 = int(min(y1 - 1, by0 + rng.integers(4, max(5, h // 2))))
            cv2.rectangle(image, (bx0, by0), (bx1, by1), _random_colour(rng), -1)
    else:
        image[y0:y1, x0:x1] = a
        line_h = max(10, h // int(rng.integers(2, 5)))
        for y in range(y0 + 2, y1 - line_h + 1, line_h):
            _draw_text(image, rng, x0 + 2, y, x1 - 2, y + line_h - 2, b)


def tiled_floor(rng: np.random.Generator, size_m, ppm: float, tile_m: float = 0.3) -> np.ndarray:
    """Floor tiles of ``tile_m`` with a random tint each, grout lines and mottling."""
    rows, cols = texture_shape(size_m, ppm)
    tile_px = max(4, int(round(tile_m * ppm)))
    base = np.array(_random_colour(rng, 90, 200), np.float32)
    n_ty, n_tx = rows // tile_px + 1, cols // tile_px + 1
    tints = base + rng.normal(0.0, 18.0, size=(n_ty, n_tx, 3)).astype(np.float32)
    image = np.repeat(np.repeat(tints, tile_px, axis=0), tile_px, axis=1)[:rows, :cols].copy()
    image += smooth_noise(rng, (rows, cols), 6.0, 6.0)[..., None]
    grout = max(1, tile_px // 20)
    for y in range(0, rows, tile_px):
        image[y:y + grout] = 60.0
    for x in range(0, cols, tile_px):
        image[:, x:x + grout] = 60.0
    return _finish(image)


def painted_wall(rng: np.random.Generator, size_m, ppm: float, n_posters: int = 5) -> np.ndarray:
    """Painted wall with mottled paint and ``n_posters`` framed posters."""
    rows, cols = texture_shape(size_m, ppm)
    paint = np.array(_random_colour(rng, 150, 230), np.float32)
    image = np.empty((rows, cols, 3), np.float32)
    image[:] = paint
    image += smooth_noise(rng, (rows, cols), 20.0, 5.0)[..., None]
    image = _finish(image)
    for _ in range(n_posters):
        w = int(rng.uniform(0.3, 0.8) * ppm)
        h = int(rng.uniform(0.3, 0.7) * ppm)
        if w >= cols - 2 or h >= rows - 2:
            continue
        x0 = int(rng.integers(0, cols - w))
        y0 = int(rng.integers(int(0.15 * rows), max(int(0.15 * rows) + 1, int(0.7 * rows) - h)))
        frame = max(2, int(0.02 * ppm))
        cv2.rectangle(image, (x0, y0), (x0 + w, y0 + h), (30, 30, 30), -1)
        _draw_pattern(image, rng, x0 + frame, y0 + frame, x0 + w - frame, y0 + h - frame)
    return image


def wood(rng: np.random.Generator, size_m, ppm: float, plank_m: float = 0.15) -> np.ndarray:
    """Wood planks: grain stripes along the width with plank joints."""
    rows, cols = texture_shape(size_m, ppm)
    base = np.array([140.0, 95.0, 55.0], np.float32) + rng.normal(0, 12, size=3).astype(np.float32)
    grain = smooth_noise(rng, (rows, max(2, cols // 16)), 2.0, 14.0)
    grain = cv2.resize(grain, (cols, rows), interpolation=cv2.INTER_LINEAR)
    image = base + grain[..., None]
    plank_px = max(4, int(round(plank_m * ppm)))
    for y in range(0, rows, plank_px):
        image[y:y + 2] *= 0.45
        offset = int(rng.integers(0, cols))
        image[y:y + plank_px, offset:offset + 2] *= 0.45
    for _ in range(max(1, int(size_m[0] * size_m[1] * 4))):
        cx, cy = int(rng.integers(0, cols)), int(rng.integers(0, rows))
        axes = (int(rng.integers(4, 12)), int(rng.integers(2, 5)))
        cv2.ellipse(image, (cx, cy), axes, 0, 0, 360, (70.0, 45.0, 25.0), -1)
    return _finish(image)


def plain_panel(rng: np.random.Generator, size_m, ppm: float, colour, grain: float = 3.0) -> np.ndarray:
    """Nearly uniform panel of ``colour`` (R, G, B) with faint mottling (few corners)."""
    rows, cols = texture_shape(size_m, ppm)
    image = np.empty((rows, cols, 3), np.float32)
    image[:] = np.asarray(colour, np.float32)
    image += smooth_noise(rng, (rows, cols), 25.0, grain)[..., None]
    return _finish(image)


def fridge_door_front(rng: np.random.Generator, size_m, ppm: float) -> np.ndarray:
    """Fridge door front: white enamel covered with magnets, photos, notes, a calendar.

    Dense, high-contrast detail across the whole panel so that a corner detector
    finds many features on the door at any opening angle.
    """
    rows, cols = texture_shape(size_m, ppm)
    image = plain_panel(rng, size_m, ppm, (236, 236, 232), grain=2.0)
    # handle: a dark vertical bar near the free edge (the left edge seen from the front).
    hx = int(0.06 * cols)
    cv2.rectangle(image, (hx, int(0.3 * rows)), (hx + max(3, int(0.03 * ppm)), int(0.6 * rows)),
                  (40, 40, 45), -1)
    # calendar: a grid of numbered cells.
    cx0, cy0 = int(0.45 * cols), int(0.08 * rows)
    cell = max(8, int(0.05 * ppm))
    cv2.rectangle(image, (cx0, cy0 - cell), (cx0 + 7 * cell, cy0), _random_colour(rng, 120, 220), -1)
    for i in range(5):
        for j in range(7):
            x, y = cx0 + j * cell, cy0 + i * cell
            cv2.rectangle(image, (x, y), (x + cell, y + cell), (40, 40, 40), 1)
            if rng.random() < 0.35:
                cv2.rectangle(image, (x + 2, y + 2), (x + cell - 2, y + cell - 2),
                              _random_colour(rng), -1)
    # photos and notes: rectangles with patterned content, tilted a little.
    for _ in range(int(rng.integers(9, 13))):
        w = int(rng.uniform(0.08, 0.2) * ppm)
        h = int(rng.uniform(0.06, 0.16) * ppm)
        x0 = int(rng.integers(int(0.12 * cols), max(int(0.12 * cols) + 1, cols - w - 2)))
        y0 = int(rng.integers(int(0.3 * rows), max(int(0.3 * rows) + 1, rows - h - 2)))
        patch = np.full((h, w, 3), 250, np.uint8)
        _draw_pattern(patch, rng, 3, 3, w - 3, h - 3)
        angle = float(rng.uniform(-12, 12))
        rot = cv2.getRotationMatrix2D((w / 2, h / 2), angle, 1.0)
        warped = cv2.warpAffine(patch, rot, (w, h), flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))
        alpha = cv2.warpAffine(np.full((h, w), 255, np.uint8), rot, (w, h))
        region = image[y0:y0 + h, x0:x0 + w]
        keep = alpha > 127
        region[keep] = warped[keep]
    # magnets: small saturated discs and squares with a dark rim.
    for _ in range(int(rng.integers(25, 35))):
        cx, cy = int(rng.integers(int(0.12 * cols), cols - 4)), int(rng.integers(4, rows - 4))
        radius = int(rng.uniform(0.012, 0.03) * ppm)
        colour = _random_colour(rng)
        if rng.random() < 0.5:
            cv2.circle(image, (cx, cy), radius + 1, (20, 20, 20), -1, cv2.LINE_AA)
            cv2.circle(image, (cx, cy), radius, colour, -1, cv2.LINE_AA)
        else:
            cv2.rectangle(image, (cx - radius, cy - radius), (cx + radius, cy + radius), (20, 20, 20), -1)
            cv2.rectangle(image, (cx - radius + 2, cy - radius + 2), (cx + radius - 2, cy + radius - 2),
                          colour, -1)
    # lettered stickers.
    for _ in range(int(rng.integers(4, 7))):
        w, h = int(rng.uniform(0.1, 0.25) * ppm), int(rng.uniform(0.03, 0.06) * ppm)
        x0 = int(rng.integers(int(0.12 * cols), max(int(0.12 * cols) + 1, cols - w - 2)))
        y0 = int(rng.integers(2, rows - h - 2))
        cv2.rectangle(image, (x0, y0), (x0 + w, y0 + h), _random_colour(rng, 150, 255), -1)
        _draw_text(image, rng, x0 + 2, y0 + 1, x0 + w - 2, y0 + h - 1, (15, 15, 15))
    return image


def fridge_interior(rng: np.random.Generator, size_m, ppm: float, n_shelves: int = 4) -> np.ndarray:
    """Inside of the fridge (or of its door): shelves stocked with coloured boxes and bottles."""
    rows, cols = texture_shape(size_m, ppm)
    image = plain_panel(rng, size_m, ppm, (215, 225, 230), grain=3.0)
    shelf_px = rows // (n_shelves + 1)
    for k in range(1, n_shelves + 1):
        y = k * shelf_px
        cv2.rectangle(image, (0, y), (cols - 1, y + max(2, shelf_px // 15)), (150, 160, 170), -1)
        x = int(rng.integers(2, 10))
        while x < cols - 8:
            w = int(rng.integers(max(6, cols // 14), max(7, cols // 5)))
            h = int(rng.integers(shelf_px // 3, int(shelf_px * 0.85)))
            colour = _random_colour(rng)
            cv2.rectangle(image, (x, y - h), (min(cols - 2, x + w), y - 1), colour, -1)
            cv2.rectangle(image, (x, y - h), (min(cols - 2, x + w), y - 1), (25, 25, 25), 1)
            if rng.random() < 0.5:
                _draw_text(image, rng, x + 2, y - h // 2 - 6, min(cols - 4, x + w - 2), y - h // 2 + 6,
                           (250, 250, 250))
            x += w + int(rng.integers(3, 12))
    return image
