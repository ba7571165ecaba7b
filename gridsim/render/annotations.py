"""What a video frame says besides the picture, so that a person understands it without the
code: who drives, the time, the speed, the fitness so far (top left); what each colour is
(bottom left, the grid inset's beside it); a scale bar (bottom right).

Frames come from :class:`~gridsim.render.topdown.TopDownRenderer`; :func:`annotate` writes on
them in place. Used by every video export (:func:`gridsim.video.record_episode`) and by
:class:`~gridsim.envs.wrappers.CaptionedRender` for ``render()`` frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from gridsim.render.grids import colourise
from gridsim.render.topdown import (
    DESTINATION_COLOUR,
    EGO_COLOUR,
    IDM_COLOUR,
    INSET_EGO_COLOUR,
    INSET_MARGIN,
    PLAN_COLOUR,
    REFERENCE_COLOUR,
    TRAFFIC_COLOUR,
)
from gridsim.sensors.occupancy import FREE, OCCUPIED, UNKNOWN

_FONT, _SCALE, _STEP = cv2.FONT_HERSHEY_SIMPLEX, 0.42, 17
_WHITE = (255, 255, 255)
#: The colour of the caption's last line when the episode ended (RGB; bold).
ENDED_COLOUR = (255, 120, 110)

#: The picture's colours: name, RGB, drawn as a box (vehicles, the darker end their front),
#: a ring or a dot (set-points) or a diamond (the destination).
LEGEND: tuple[tuple[str, tuple[int, int, int], str], ...] = (
    ("ego", EGO_COLOUR, "box"),
    ("replayed traffic", TRAFFIC_COLOUR, "box"),
    ("traffic driven by IDM", IDM_COLOUR, "box"),
    ("human's set-points", REFERENCE_COLOUR, "ring"),
    ("planned set-points", PLAN_COLOUR, "dot"),
    ("destination", DESTINATION_COLOUR, "diamond"),
)
#: The legend's shapes of what a frame without set-points does not draw.
_SETPOINT_SHAPES = ("ring", "dot", "diamond")
#: The grid inset's colours.
GRID_LEGEND = (
    ("free", tuple(int(c) for c in colourise(np.uint8(FREE)))),
    ("occupied", tuple(int(c) for c in colourise(np.uint8(OCCUPIED)))),
    ("unknown", tuple(int(c) for c in colourise(np.uint8(UNKNOWN)))),
    ("the ego (outline)", INSET_EGO_COLOUR),
)


@dataclass(frozen=True)
class Caption:
    """What the top-left band says: ``label`` (the driver: a method or a front member), the
    simulated time [s], the ego's speed [m/s], the fitness terms summed so far ``[l1, l2,
    l3]`` (m^2, rad/s, m/s each step, summed), or None before the first step, and what ended
    the episode at this step (``ended``: ``"collision"``, ``"off the road"``, ``"the human's
    end point reached"`` (the destination the episode ends at: where the human's whole path
    ends, not the diamond, the planner's goal ahead), ``"time limit"``, ``"steps limit"``), if
    anything did."""

    label: str | None
    time: float
    speed: float
    fitness: np.ndarray | None = None
    ended: str | None = None

    @classmethod
    def from_info(cls, info: dict, label: str | None, fitness: np.ndarray | None,
                  timed_out: bool = False, stopped: bool = False) -> Caption:  # fmt: skip
        """The caption of a GridSim-v0 step's ``info`` (its time, pose and how it ended;
        ``timed_out``: it reached its time limit; ``stopped``: the caller's last step)."""
        ended = next((text for key, text in _ENDINGS if info.get(key)), None)
        ended = ended or ("time limit" if timed_out else "steps limit" if stopped else None)
        return cls(label, float(info["time"]), float(info["pose"][3]), fitness, ended)

    def lines(self) -> list[str]:
        out = [self.label] if self.label else []
        out.append(f"t {self.time:5.1f} s    speed {self.speed:4.1f} m/s")
        if self.fitness is not None:
            l1, l2, l3 = (float(v) for v in self.fitness)
            out.append("fitness so far, each summed over the ticks:")
            out.append(f"  l1 {l1:.1f} m^2   l2 {l2:.2f} rad/s   l3 {l3:.0f} m/s")
        return out


#: What ends an episode, by its ``info`` key, as a frame says it.
_ENDINGS = (("collision", "collision"), ("off_road", "off the road"),
            ("destination_reached", "the human's end point reached"))  # fmt: skip


def annotate(img: np.ndarray, caption: Caption, pixels_per_metre: float,
             inset_size: int | None = None, setpoints: bool = True,
             orientation: str = "north_up") -> np.ndarray:  # fmt: skip
    """Write ``caption`` (with how the episode ended, if it did, as its last line, in light
    red and bold: the scene itself is left clear at the moment that matters), the colour
    legend (without the set-points' colours unless ``setpoints``: a frame that draws none),
    the grid inset's legend (of an inset of ``inset_size`` pixels at the top right, if any;
    at the bottom beside the colour legend; it says the grid's ``orientation``, "north up"
    as the frame or "heading up") and a scale bar on ``img`` (in place); returns ``img``."""
    text = [(t, None, "") for t in caption.lines()]
    if caption.ended:
        text.append((f"episode over: {caption.ended} at {caption.time:.1f} s", ENDED_COLOUR,
                     "alert"))  # fmt: skip
    # (beside the inset: a long scenario name ran on under it)
    room = img.shape[1] - (inset_size + INSET_MARGIN if inset_size else 0) - 8
    _band(img, 0, 0, _wrapped(text, room))
    for lines, x, y, _ in _legend_bands(img.shape[0], bool(inset_size), orientation, setpoints):
        _band(img, x, y, lines)
    _scale_bar(img, pixels_per_metre)
    return img


def _legend_bands(height: int, inset: bool, orientation: str,
                  setpoints: bool = True) -> list[tuple]:  # fmt: skip
    """Where :func:`annotate` writes its legends in a frame of ``height`` pixels: ``(lines,
    left, top, width)`` [pixels] of the colour legend (without the set-points' colours unless
    ``setpoints``) at the bottom left and, with an ``inset``, the grid's beside it (beside
    the inset, top middle, it hid the road ahead of an ego driving up the picture; under it,
    of one driving right)."""
    legend = LEGEND if setpoints else tuple(e for e in LEGEND if e[2] not in _SETPOINT_SHAPES)
    bands, x = [], 0
    for lines in (legend, *([inset_legend(orientation)] if inset else [])):
        width = _width(lines)
        bands.append((lines, x, height - _STEP * len(lines) - 8, width))
        x += width + 8
    return bands


def legend_boxes(height: int, inset: bool, orientation: str = "north_up") -> list[tuple]:
    """The rectangles ``(left, top, right, bottom)`` [pixels] the legends :func:`annotate`
    writes (with the set-points' colours) take at the bottom left of a frame of ``height``
    pixels, ``inset``: with the grid inset's legend beside them; a renderer keeps the
    set-points and the destination clear of them (they would be dimmed under the bands)."""
    return [(x, y, x + width, height)
            for _, x, y, width in _legend_bands(height, inset, orientation)]  # fmt: skip


def inset_legend(orientation: str) -> list[tuple]:
    """The grid inset's legend lines: its orientation ("north up", as the frame, or "heading
    up": the inset then turns with the ego) and its colours."""
    up = orientation.replace("_", " ")
    return [(f"sensor grid ({up}):", None, ""), *((n, c, "box") for n, c in GRID_LEGEND)]


def _wrapped(lines, width: int) -> list[tuple]:
    """``lines`` (as :func:`_band` takes them) broken at spaces where a band of their text
    would be wider than ``width`` pixels (a word longer than that: where it reaches it)."""
    out = []
    for text, colour, shape in lines:
        words, line = [], ""
        for word in text.split(" "):  # (a word wider than a line: cut into pieces)
            while len(word) > 8 and _width([("  " + word, colour, shape)]) > width:
                cut = max((k for k in range(8, len(word))
                           if _width([("  " + word[:k], colour, shape)]) <= width),
                          default=8)  # (no room: pieces of 8 characters)  # fmt: skip
                words.append(word[:cut])
                word = word[cut:]
            words.append(word)
        for word in words:
            longer = f"{line} {word}" if line else word
            if line and _width([(longer, colour, shape)]) > width:
                out.append((line, colour, shape))
                line = "  " + word  # (a continued line, indented)
            else:
                line = longer
        out.append((line, colour, shape))
    return out


def _width(lines) -> int:
    return max(cv2.getTextSize(t, _FONT, _SCALE, _thickness(shape))[0][0]
               for t, _, shape in lines) + 30  # fmt: skip


def _thickness(shape: str) -> int:
    """The strokes of a line's text: bold for an ``"alert"``."""
    return 2 if shape == "alert" else 1


def _band(img: np.ndarray, x: int, y: int, lines, width: int | None = None) -> None:
    """``lines`` of ``(text, colour or None, "box" | "dot" | "alert" | "")`` on a darkened
    band whose top left is ``(x, y)``; a colour is drawn before its text as a box or a dot,
    or is the text's own, in bold (an alert)."""
    width = width or _width(lines)
    _darken(img[y : y + _STEP * len(lines) + 8, x : x + width])
    for k, (text, colour, shape) in enumerate(lines):
        base = y + 17 + _STEP * k
        if shape == "box":
            cv2.rectangle(img, (x + 6, base - 9), (x + 17, base - 1), colour, -1)
        elif shape == "dot":
            cv2.circle(img, (x + 12, base - 5), 4, colour, -1, cv2.LINE_AA)
        elif shape == "ring":
            cv2.circle(img, (x + 12, base - 5), 5, colour, 2, cv2.LINE_AA)
        elif shape == "diamond":
            cv2.drawMarker(img, (x + 12, base - 5), colour, cv2.MARKER_DIAMOND, 11, 2, cv2.LINE_AA)
        marked = shape in ("box", "dot", "ring", "diamond")
        cv2.putText(img, text, (x + 24 if marked else x + 8, base), _FONT, _SCALE,
                    colour if shape == "alert" else _WHITE, _thickness(shape),
                    cv2.LINE_AA)  # fmt: skip


def _darken(region: np.ndarray) -> None:
    """Darken ``region`` of a frame in place (the ground the text is written on)."""
    region[:] = (region * 0.35).astype(np.uint8)


def _scale_bar(img: np.ndarray, pixels_per_metre: float) -> None:
    """A bar of a round length (5, 10, 20, 50 or 100 m: at least an eighth of the frame's
    width) at the bottom right, labelled."""
    h, w = img.shape[:2]
    metres = next((m for m in (5, 10, 20, 50, 100) if m * pixels_per_metre >= w / 8), 100)
    length = int(round(metres * pixels_per_metre))
    x1, y = w - 12, h - 14
    x0 = x1 - length
    _darken(img[y - 22 : h - 4, x0 - 8 : x1 + 8])
    cv2.line(img, (x0, y), (x1, y), _WHITE, 2)
    for xe in (x0, x1):
        cv2.line(img, (xe, y - 5), (xe, y + 4), _WHITE, 2)
    cv2.putText(img, f"{metres} m", (x0, y - 8), _FONT, _SCALE, _WHITE, 1, cv2.LINE_AA)


def annotate_env_frame(env, frame: np.ndarray, info: dict, label: str | None,
                       fitness: np.ndarray, stopped: bool = False) -> np.ndarray:  # fmt: skip
    """:func:`annotate` a GridSim-v0 ``frame`` (of ``env``, wrapped or not) with the caption of
    its step's ``info`` (with ``"truncated"``, a wrapper's time limit is said too) and the
    ``fitness`` summed so far, at the env renderer's scale (``stopped``: the last step the
    caller takes, its steps limit)."""
    u = env.unwrapped
    renderer = u.renderer
    # the env's own time limit (as step says), or a wrapper's (run_episode says it)
    timed_out = info.get("truncated", False) or (
        u.world is not None and u.world.time >= u.time_limit - 1e-9)  # fmt: skip
    caption = Caption.from_info(info, label, fitness, timed_out, stopped)
    return annotate(
        frame,
        caption,
        renderer.scale,
        renderer.view.inset_size,
        orientation=u.cfg.sensor.orientation,
    )
