"""One recorded vehicle trajectory (:class:`Track`), as libraries and scenes hold them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from gridsim.errors import DataError
from gridsim.frames import MAX_COORDINATE

#: No road vehicle is faster [m/s] (360 km/h): a larger recorded speed, or a larger distance
#: between consecutive positions over their time step, is a glitch of the data.
MAX_SPEED = 100.0
#: The largest time stamp accepted [s] (about 300 years: Unix times in seconds pass, times
#: in milli- or microseconds do not).
MAX_TIME = 1e10
#: The longest gap between two samples of a track [s] (recordings lose a vehicle for a few
#: seconds; a longer gap is another vehicle, or a unit error).
MAX_GAP = 60.0
#: The largest vehicle accepted, length and width [m].
MAX_SIZE = (50.0, 10.0)
#: A vehicle's usual length and width [m], ``(least, most)`` each: a size read in other
#: units lands here once converted (a hint), and no ego is smaller.
USUAL_SIZE = ((1.0, 25.0), (0.5, 5.0))
#: Kinds of road users (:attr:`Track.kind`) that stay traffic, never the ego's track.
NOT_CARS = frozenset({"pedestrian", "bicycle"})


@dataclass(frozen=True, eq=False)
class Track:
    """One recorded vehicle: arrays of equal length sampled at increasing ``t`` [s].

    Compared and hashed by identity (tracks are loaded once per library)."""

    scenario_id: str
    track_id: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    length: float
    width: float
    #: Where the track was read from (a file path), for messages.
    source: str = ""
    #: The id as its file gives it, when ``track_id`` is a piece of it (``ID#2``: the id
    #: reused after a pause); "" when the same
    recorded_id: str = ""
    #: What the file says it is (CommonRoad's obstacle ``<type>``, a CSV's
    #: ``obstacle_type``: ``car``, ``truck``, ``pedestrian``, ...); "" when it says nothing
    kind: str = ""

    @property
    def drivable_as_ego(self) -> bool:
        """Whether the ego (a car) may drive this track: not one of :data:`NOT_CARS`."""
        return self.kind.lower() not in NOT_CARS

    def __post_init__(self) -> None:
        problem = track_data_problem(self)
        if problem:
            raise DataError(f"{self.where}: {problem}")

    @property
    def where(self) -> str:
        """The track in messages: file, scene and id."""
        return f"{self.source or '<tracks>'}: track {self.track_id} of scene {self.scenario_id}"

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def lateral_offset(self) -> np.ndarray:
        """Human lateral wander [m]: signed offset of each position from a smooth fit.

        A polynomial in time (degree 1 to 3 by track length) stands for the lane the driver
        follows; the residual perpendicular to the fit's direction, positive to the left, is
        the offset replayed on synthetic roads.
        """
        n = len(self.t)
        if n < 5:
            return np.zeros(n)
        deg = 1 if n < 15 else (2 if n < 40 else 3)
        tt = self.t - self.t[0]
        fx = np.polynomial.Polynomial.fit(tt, self.x, deg)
        fy = np.polynomial.Polynomial.fit(tt, self.y, deg)
        dx, dy = fx.deriv()(tt), fy.deriv()(tt)
        norm = np.hypot(dx, dy)
        norm[norm < 1e-6] = 1.0
        rx, ry = self.x - fx(tt), self.y - fy(tt)
        return (dx * ry - dy * rx) / norm

    def smoothed_speed(self) -> np.ndarray:
        """Speed [m/s] smoothed with a Savitzky-Golay filter (recorded speeds are noisy)."""
        n = len(self.speed)
        win = min(11, n if n % 2 else n - 1)
        if win < 5:
            return self.speed.copy()
        return np.maximum(savgol_filter(self.speed, win, 2), 0.0)


def track_data_problem(track: Track) -> str | None:
    """What makes a track's data impossible, naming the first bad state (``None`` if none):
    unequal or too few samples, non-finite values, time stamps beyond :data:`MAX_TIME`, not
    increasing or :data:`MAX_GAP` apart, coordinates
    beyond :data:`MAX_COORDINATE`, speeds below 0 or above :data:`MAX_SPEED`, a jump between
    consecutive positions faster than :data:`MAX_SPEED`, a size outside (0, :data:`MAX_SIZE`]."""
    arrays = {k: np.asarray(getattr(track, k)) for k in ("t", "x", "y", "heading", "speed")}
    sizes = {k: a.shape for k, a in arrays.items()}
    if len(set(sizes.values())) != 1 or arrays["t"].ndim != 1:
        return f"its arrays must be 1-D of one length, got shapes {sizes}"
    if len(arrays["t"]) < 2:
        return f"has {len(arrays['t'])} state(s); at least 2 are needed"
    t = arrays["t"]

    def state(k: int) -> str:
        return f"state {k} (t = {t[k]:.6g} s)" if np.isfinite(t[k]) else f"state {k}"

    for name, a in arrays.items():
        bad = np.flatnonzero(~np.isfinite(a))
        if len(bad):
            return f"{state(int(bad[0]))}: {name} is {a[bad[0]]}; expected a finite number"
    for name in ("x", "y"):
        bad = np.flatnonzero(np.abs(arrays[name]) > MAX_COORDINATE)
        if len(bad):
            return (f"{state(int(bad[0]))}: {name} = {arrays[name][bad[0]]:.6g} m is beyond "
                    f"+-{MAX_COORDINATE:g} m")  # fmt: skip
    bad = np.flatnonzero(np.abs(t) > MAX_TIME)
    if len(bad):
        return (f"state {int(bad[0])}: time {t[bad[0]]:.6g} s is beyond +-{MAX_TIME:g} s "
                "(time stamps in seconds?)")  # fmt: skip
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        return f"{state(int(bad[0]) + 1)}: time stamps must increase (after {t[bad[0]]:.6g} s)"
    bad = np.flatnonzero(np.diff(t) > MAX_GAP)
    if len(bad):
        return (f"{state(int(bad[0]) + 1)}: {t[bad[0] + 1] - t[bad[0]]:.6g} s after the "
                f"previous sample; at most {MAX_GAP:g} s (time stamps in seconds?)")  # fmt: skip
    speed = arrays["speed"]
    bad = np.flatnonzero((speed < 0) | (speed > MAX_SPEED))
    if len(bad):
        return (f"{state(int(bad[0]))}: speed {speed[bad[0]]:.6g} m/s is outside "
                f"[0, {MAX_SPEED:g}] (reversing is not supported)")  # fmt: skip
    step = np.hypot(np.diff(arrays["x"]), np.diff(arrays["y"]))
    implied = step / np.diff(t)
    bad = np.flatnonzero(implied > MAX_SPEED)
    if len(bad):
        k = int(bad[0])
        return (f"{state(k + 1)}: jumps {step[k]:.6g} m in {t[k + 1] - t[k]:.6g} s "
                f"({implied[k]:.6g} m/s; no vehicle is faster than {MAX_SPEED:g} m/s)")  # fmt: skip
    sizes = zip(("length", "width"), (track.length, track.width), MAX_SIZE, USUAL_SIZE,
                strict=True)  # fmt: skip
    for name, value, most, (lo, hi) in sizes:
        if not 0 < value <= most:
            # a vehicle's size [m] read in centimetres or millimetres: said so
            unit = next((f" (in {u}? {value / k:g} m)" for u, k in (("cm", 100.0), ("mm", 1e3))
                         if lo <= value / k <= hi), "")  # fmt: skip
            return f"{name} {value:.10g} m is outside (0, {most:g}]{unit}"
    return None


#: A file whose tracks are impossible data (:func:`track_data_problem`, or a CommonRoad
#: obstacle that cannot be read) in more than this share is refused, naming them; fewer are
#: left out with a warning naming each (one glitch among thousands of vehicles refused the
#: file, naming only the first).
MAX_IMPOSSIBLE_SHARE = 0.5

#: Problems named in full in one message (the rest counted).
NAMED_PROBLEMS = 10


def refuse_mostly_impossible(path, kept: int, impossible: list[str]) -> None:
    """A :class:`DataError` naming every problem of ``impossible`` (one per track, without
    the file's name) when they are more than :data:`MAX_IMPOSSIBLE_SHARE` of the file
    ``path``'s tracks (``kept`` others)."""
    if len(impossible) <= MAX_IMPOSSIBLE_SHARE * (kept + len(impossible)):
        return
    if len(impossible) == 1:
        raise DataError(f"{path}: {impossible[0]}")
    raise DataError(f"{path}: {len(impossible)} of its {kept + len(impossible)} tracks are "
                    "impossible:" + listed(impossible))  # fmt: skip


def impossible_note(impossible: list[str]) -> str:
    """What a warning says of the tracks ``impossible`` left out (their problems)."""
    return f"{len(impossible)} track(s) left out, their data impossible:" + listed(impossible)


def listed(problems: list[str]) -> str:
    """``problems`` one per indented line (the first :data:`NAMED_PROBLEMS`, the rest
    counted)."""
    more = problems[NAMED_PROBLEMS:]
    lines = [*problems[:NAMED_PROBLEMS], *([f"... and {len(more)} more"] if more else [])]
    return "".join(f"\n    {line}" for line in lines)


def track_name(scene: str, track_id: str) -> str:
    """A track's name across scenes, ``SCENE/ID`` (as datasets label their windows and as
    ``ego.track`` may name a track of a collection's scene)."""
    return f"{scene}/{track_id}"


def scene_ids(names: list[str], scene: str) -> list[str]:
    """The track ids of the ``SCENE/ID`` names of ``scene`` among ``names``, in their order."""
    prefix = track_name(scene, "")
    return [name[len(prefix) :] for name in names if name.startswith(prefix)]


def ids_in_scene(names: list[str], scene: str) -> tuple[list[str], list[str]]:
    """``(own, foreign)``: the track ids of ``scene`` among ``names`` (plain ids as they are,
    ``SCENE/ID`` names of ``scene`` stripped), and the names of tracks of other scenes."""
    prefix = track_name(scene, "")
    own, foreign = [], []
    for name in names:
        if name.startswith(prefix):
            own.append(name[len(prefix) :])
        elif "/" in name:
            foreign.append(name)
        else:
            own.append(name)
    return own, foreign
