"""Driving clips a study participant can read: highway-env's frames, cropped to the road, with the
brake lights and the weather drawn on.

highway-env draws every car as a flat-coloured rectangle on a flat grey ground (the ego green,
the scenario's front car blue, a crashed car red, other cars yellow) and draws neither brake lights
nor weather. :func:`view_config` sets its camera so that a car is :data:`SCALING` px a metre (a
5 m car is 70 px long) with the ego near the left edge and the front car in view, and
:func:`decorate` then

* crops each frame to the road's rows (found from its two continuous edge lines) and a verge of
  :data:`VERGE` metres either side, so the road stays still while the ego changes lane;
* colours the verges and the road by the sleet level ``s``: green verges and a grey road when dry,
  snow-white verges, a darker wet-blue road and falling streaks (:data:`STREAKS` · ``s`` a px²) on a
  sleety day;
* lights two red brake lights at the back of each car that brakes in that frame, with a red glow
  behind it, so braking differs from coasting even on a phone.
"""

from __future__ import annotations

import numpy as np

SCALING = 14.0
"""Pixels a metre: a 5 m car is 70 px long."""
BEHIND, AHEAD = 8.0, 55.0
"""Metres of road shown behind the ego's centre and ahead of it (the front car starts 47.5 m ahead)."""
VERGE = 2.5
"""Metres of ground shown beside the road on each side."""
GROUND = (100, 100, 100)
"""highway-env's ground colour (``WorldSurface.GREY``)."""
CAR_COLOURS = {"ego": (50, 200, 0), "front": (100, 200, 255)}
"""highway-env's colours of the ego (``VehicleGraphics.EGO_COLOR``) and of the scenario's front car."""
BRAKE_LIGHT = (255, 0, 0)
DRY_ROAD, WET_ROAD = np.array(GROUND, float), np.array((82, 94, 112), float)
DRY_VERGE, SNOW_VERGE = np.array((104, 142, 84), float), np.array((222, 228, 236), float)
STREAK = np.array((240, 244, 252), float)
STREAKS = 0.6e-3
"""Sleet streaks a frame per px² at full sleet."""


def view_config(lanes: int) -> dict:
    """highway-env config entries for the camera: the ego :data:`BEHIND` m from the left edge,
    :data:`AHEAD` m of road ahead, tall enough to hold the whole road wherever the ego drives
    (the camera follows its lateral position; :func:`decorate` crops to the road)."""
    width = int(round((BEHIND + AHEAD) * SCALING))
    height = int(round(2 * (4.0 * lanes + VERGE) * SCALING))
    return {
        "screen_width": width,
        "screen_height": height,
        "scaling": SCALING,
        "centering_position": [BEHIND * SCALING / width, 0.5],
    }


def road_rows(frame: np.ndarray) -> tuple[int, int] | None:
    """The first and last pixel rows of the road's two continuous edge lines (rows nearly all white), or None."""
    white = (np.asarray(frame) >= 250).all(-1).mean(1) > 0.9
    rows = np.flatnonzero(white)
    return (int(rows[0]), int(rows[-1])) if len(rows) >= 2 and rows[-1] - rows[0] > SCALING else None


def decorate(frames, braking, sleet: float, seed: int = 0) -> list[np.ndarray]:
    """Crop, colour and light ``frames`` (highway-env's, drawn with :func:`view_config`).

    Args:
        frames: T frames [H, W, 3] uint8.
        braking: [T, 2] bool: whether the ego and the front car brake in each frame.
        sleet: the sleet level in [0, 1] (0: a dry road, no streaks).
        seed: the streaks' random positions (the same seed gives the same snowfall, so two clips
            of a pair fall in step).

    Returns:
        T frames [h, W, 3] uint8, h the road's width and a verge of :data:`VERGE` m each side.
    """
    from PIL import Image, ImageDraw

    braking = np.asarray(braking, bool).reshape(len(frames), 2)
    s = float(np.clip(sleet, 0.0, 1.0))
    road_c = DRY_ROAD + (WET_ROAD - DRY_ROAD) * s
    verge_c = DRY_VERGE + (SNOW_VERGE - DRY_VERGE) * s
    margin = int(round(VERGE * SCALING))
    rng = np.random.default_rng(seed)
    out = []
    for f, brakes in zip(frames, braking):
        f = np.asarray(f, np.uint8)
        rows = road_rows(f)
        top, bottom = rows if rows else (margin, f.shape[0] - margin - 1)
        lo, hi = max(0, top - margin), min(f.shape[0], bottom + margin + 1)
        f = f[lo:hi].astype(float)
        h, w = f.shape[:2]
        ground = (f == GROUND).all(-1)
        on_road = np.zeros((h, w), bool)
        on_road[top - lo : bottom - lo + 1] = True
        lights = [_car_box(f, CAR_COLOURS[c]) for c, b in zip(("ego", "front"), brakes) if b]
        f[ground & on_road] = road_c
        f[ground & ~on_road] = verge_c
        n = int(round(STREAKS * s * h * w))
        if n:
            layer = Image.new("L", (w, h), 0)
            draw = ImageDraw.Draw(layer)
            for x, y in zip(rng.uniform(0, w + 6, n), rng.uniform(-12, h, n)):
                draw.line([(x, y), (x - 4, y + 11)], fill=255, width=2)
            a = 0.85 * (np.asarray(layer, float) / 255)[..., None] * ground[..., None]
            f = f * (1 - a) + STREAK * a
        for box in lights:
            if box is not None:
                _brake_lights(f, box, ground)
        out.append(np.clip(f, 0, 255).astype(np.uint8))
    return out


def _car_box(frame: np.ndarray, colour) -> tuple[int, int, int, int] | None:
    """(x0, x1, y0, y1) of the pixels of a car's body colour, or None when that car is not in view."""
    ys, xs = np.nonzero((frame == colour).all(-1))
    return (int(xs.min()), int(xs.max()), int(ys.min()), int(ys.max())) if len(xs) else None


def _brake_lights(f: np.ndarray, box, ground: np.ndarray) -> None:
    """Two lights at the car's back corners (cars drive rightwards) and a glow on the ground behind it."""
    x0, x1, y0, y1 = box
    size = max(2, int(round(0.8 * SCALING)))
    glow = max(2, int(round(1.2 * SCALING)))
    g0 = max(0, x0 - glow)
    region = (slice(y0, y1 + 1), slice(g0, x0))
    fade = np.linspace(0.15, 0.7, x0 - g0)[None, :, None] * ground[region][..., None]
    f[region] = f[region] * (1 - fade) + np.array(BRAKE_LIGHT, float) * fade
    f[y0 : y0 + size, x0 : x0 + size] = BRAKE_LIGHT
    f[y1 + 1 - size : y1 + 1, x0 : x0 + size] = BRAKE_LIGHT
