"""The typed schema of scenario YAML files (pydantic). Unknown keys are errors.

Units: metres, seconds, m/s, m/s^2, degrees where a key ends in ``_deg`` or is an angle
given to users (``fov``, ``yaw``, ``max_steer``...), radians nowhere in YAML.
"""

from __future__ import annotations

import numbers
import re
from dataclasses import dataclass
from pathlib import Path
from types import UnionType
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union, get_args, get_origin

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from gridsim.frames import setpoint_times
from gridsim.sensors.occupancy import GridSpec
from gridsim.traffic.library import is_number
from gridsim.traffic.track import USUAL_SIZE
from gridsim.vehicle.kinematics import BicycleParams

#: The most road [m] kept populated behind and ahead of the ego (``traffic.window``).
MAX_WINDOW = 10_000.0
#: The longest episode (and drive) [s]: one hour of simulated time.
MAX_DURATION = 3600.0
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
#: One side of ``traffic.window`` [m]: at least 50 m of road kept populated.
WindowSide = Annotated[float, Field(ge=50, le=MAX_WINDOW, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Seed = Annotated[int, Field(ge=0, le=2**63 - 1)]


if TYPE_CHECKING:
    #: ``ScenarioConfig.road``: at run time the union of the registered families' configs,
    #: which :mod:`gridsim.scenario.family` resolves when a family registers.
    RoadConfig = Any


def _bare(annotation: Any) -> Any:
    """``annotation`` without ``Annotated[...]``'s constraints."""
    return get_args(annotation)[0] if get_origin(annotation) is Annotated else annotation


def _members(annotation: Any) -> list[Any]:
    """What a field of ``annotation`` may hold: a union's members but None (``Seed | None``),
    else the annotation itself; each without ``Annotated[...]``'s constraints."""
    if get_origin(annotation) in (Union, UnionType):
        return [_bare(a) for a in get_args(annotation) if a is not type(None)]
    return [_bare(annotation)]


#: A number written with leading zeros, which YAML 1.1 reads as octal: the scenario loader
#: keeps it as written (``00427``: a zero-padded id), and a number key says to drop them.
ZERO_PADDED = re.compile(r"^[-+]?0[0-9_]+$")


def _is_number_type(annotation: Any) -> bool:
    """Whether a field of ``annotation`` holds a number (``int``, ``float``, or one of them or
    None)."""
    members = _members(annotation)
    return bool(members) and all(m in (int, float) for m in members)


def _number_items(annotation: Any, value: Any, name: str) -> list[tuple[tuple, Any]]:
    """``((name, index), item)`` of a list ``value`` of the field ``name`` that holds a
    tuple or list of numbers (``traffic.window``, ``env.speed_range``); none otherwise."""
    for kind in _members(annotation):
        if get_origin(kind) in (tuple, list) and isinstance(value, (list, tuple)):
            args = [a for a in get_args(kind) if a is not Ellipsis]
            if args and all(_is_number_type(a) for a in args):
                return [((name, k), item) for k, item in enumerate(value)]
    return []


class Strict(BaseModel):
    """A block of a scenario file: unknown keys are errors, and a number key takes numbers
    only (pydantic would read ``yes`` as 1 and ``"12"`` as 12)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)

    @model_validator(mode="before")
    @classmethod
    def _numbers_are_numbers(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        wrong = []  # (located at the key, env.horizon, as pydantic's own errors are)
        for name, value in data.items():
            field = cls.model_fields.get(name)
            if field is None:
                continue
            items = [((name,), value)] if _is_number_type(field.annotation) else (
                _number_items(field.annotation, value, name))  # fmt: skip
            for loc, item in items:
                # (other text fails pydantic's own check, which names the key)
                if isinstance(item, bool) or (isinstance(item, str) and is_number(item)):
                    if isinstance(item, bool):
                        what = "a YAML yes/no/true/false, which is a boolean"
                    elif ZERO_PADDED.match(item.strip()):  # (the loader keeps 010 as text)
                        what = "text: write it without the leading zeros (YAML reads them as octal)"
                    else:
                        what = "text: write it without quotes"
                    said = PydanticCustomError("value_error", f"expects a number, not {what}")
                    wrong.append(InitErrorDetails(type=said, loc=loc, input=item))
        if wrong:
            raise ValidationError.from_exception_data(cls.__name__, wrong)
        return data


#: The most simulation ticks in an episode (``duration / dt``): the world and the reference
#: are built for the whole episode at reset.
MAX_TICKS = 100_000


class SimulationConfig(Strict):
    dt: Annotated[float, Field(ge=1e-3, le=1.0, description="simulation time step [s]")] = 0.1
    duration: Annotated[
        float, Field(gt=0, le=MAX_DURATION, description="episode time limit [s]")
    ] = 60.0

    @model_validator(mode="after")
    def _ticks(self) -> SimulationConfig:
        if self.duration / self.dt > MAX_TICKS:
            raise ValueError(
                f"duration / dt = {self.duration:g} / {self.dt:g} = "
                f"{self.duration / self.dt:.0f} ticks, more than {MAX_TICKS}: raise dt or "
                "shorten the episode"
            )
        return self


#: A vehicle's wheelbase is at most this share of its length (cars: 0.55-0.65).
MAX_WHEELBASE_SHARE = 0.7


class VehicleConfig(Strict):
    """The ego vehicle's geometry and limits: :class:`BicycleParams`' defaults, but a scenario
    ego's top speed (20 m/s) and its steering limits in degrees (35 deg, 45 deg/s)."""

    length: Annotated[float, Field(gt=0, le=25, description="[m]")] = BicycleParams.length
    width: Annotated[float, Field(gt=0, le=4, description="[m]")] = BicycleParams.width
    wheelbase: Annotated[float, Field(gt=0, le=10, description="[m]")] = BicycleParams.wheelbase
    v_min: Annotated[float, Field(ge=0, le=100, description="[m/s]")] = BicycleParams.v_min
    v_max: Annotated[float, Field(gt=0, le=100, description="[m/s]")] = 20.0
    a_max: Annotated[float, Field(gt=0, le=20, description="[m/s^2]")] = BicycleParams.a_max
    b_max: Annotated[float, Field(gt=0, le=20, description="braking [m/s^2]")] = BicycleParams.b_max
    max_steer_deg: Annotated[float, Field(gt=0, lt=90)] = 35.0
    max_steer_rate_deg: Annotated[float, Field(gt=0, le=360)] = 45.0

    @model_validator(mode="after")
    def _order(self) -> VehicleConfig:
        if self.v_max < self.v_min:
            raise ValueError(f"v_max ({self.v_max}) must be >= v_min ({self.v_min})")
        _not_radians("max_steer_deg", self.max_steer_deg, 5.0)  # cars: 25-45 deg
        _not_radians("max_steer_rate_deg", self.max_steer_rate_deg, 5.0)
        if self.wheelbase > self.length:
            raise ValueError(f"wheelbase ({self.wheelbase}) must not exceed length ({self.length})")
        (length, _), (width, _) = USUAL_SIZE  # the smallest car: a smaller one is a unit slip
        if self.length < length or self.width < width:
            raise ValueError(f"length {self.length:g} m x width {self.width:g} m is smaller than "
                             f"any car ({length:g} m x {width:g} m at least): sizes "
                             "are in metres")  # fmt: skip
        return self


def _not_radians(name: str, value: float, least: float) -> None:
    """A ``ValueError`` when an angle in degrees ``value`` is below ``least`` and reads as
    radians (at most 2 pi)."""
    if 0 < value < least and value <= 2 * np.pi + 1e-6:
        raise ValueError(f"{name} {value:g} looks like radians ({value:g} rad = "
                         f"{np.degrees(value):.4g} deg); it is in degrees")  # fmt: skip


class MountConfig(Strict):
    x: Annotated[float, Field(ge=-20, le=20, allow_inf_nan=False, description="[m]")] = 0.0
    y: Annotated[float, Field(ge=-10, le=10, allow_inf_nan=False, description="[m]")] = 0.0
    yaw_deg: Annotated[float, Field(ge=-180, le=180)] = 0.0
    fov_deg: Annotated[float, Field(gt=0, le=360)] = 360.0

    @model_validator(mode="after")
    def _degrees(self) -> MountConfig:
        _not_radians("fov_deg", self.fov_deg, 10.0)  # (a grid seen through a 6 deg slit)
        quarters = abs(self.yaw_deg) / (0.5 * np.pi)  # pi / 2, pi, ... written as radians
        if 0.5 < quarters < 4.5 and abs(quarters - round(quarters)) < 1e-3:
            raise ValueError(f"yaw_deg {self.yaw_deg:g} looks like radians ({self.yaw_deg:g} "
                             f"rad = {np.degrees(self.yaw_deg):.4g} deg); it is in "
                             "degrees")  # fmt: skip
        return self


class SensorConfig(Strict):
    """The occupancy-grid sensor; defaults: :class:`~gridsim.sensors.occupancy.GridSpec`'s."""

    rows: Annotated[int, Field(ge=8, le=1024)] = GridSpec.rows
    cols: Annotated[int, Field(ge=8, le=1024)] = GridSpec.cols
    cell_size: Annotated[float, Field(gt=0, le=5, description="[m]")] = GridSpec.cell_size
    orientation: Literal["north_up", "heading_up"] = GridSpec.orientation
    max_range: Annotated[float, Field(gt=0, le=500, description="[m]")] = GridSpec.max_range
    rays: Annotated[int, Field(ge=8, le=8192)] = GridSpec.rays
    hit_depth: Annotated[float, Field(ge=0, le=10)] = GridSpec.hit_depth
    ray_step: Annotated[float, Field(ge=0.1, le=2.0, description="ray sample spacing [cells]")] = (
        GridSpec.ray_step
    )
    mounts: Annotated[list[MountConfig], Field(min_length=1, max_length=8)] = [MountConfig()]

    @model_validator(mode="after")
    def _range(self) -> SensorConfig:
        if self.max_range < self.cell_size:
            raise ValueError(f"max_range ({self.max_range:g} m) is shorter than a cell "
                             f"(cell_size {self.cell_size:g} m): every cell would be "
                             "unknown")  # fmt: skip
        return self


#: m/s: the fastest generated traffic (as fast as recorded tracks may imply:
#: :data:`gridsim.scenario.checks.MAX_SPEED`).
MAX_TRAFFIC_SPEED = 70.0


class TrafficConfig(Strict):
    participants: Annotated[int, Field(ge=0, le=5000)] = 10
    v_min: Annotated[NonNegFloat, Field(description="[m/s]")] = 4.16
    v_max: Annotated[PositiveFloat, Field(description="[m/s]")] = 13.88
    a_max: Annotated[PositiveFloat, Field(description="[m/s^2]")] = 2.0
    max_vehicle_length: Annotated[float, Field(gt=2, le=25)] = 6.0
    library: Annotated[
        list[str],
        Field(
            min_length=1,
            description="trajectory files (.csv, CommonRoad .xml), 'builtin' (the shipped "
            "NGSIM tracks) or 'scene' (the dynamic obstacles of the recorded road.map)",
        ),
    ] = ["builtin"]
    window: Annotated[
        tuple[WindowSide, WindowSide],
        Field(
            description="[behind, ahead] metres of road around the ego kept populated, "
            f"each in [50, {MAX_WINDOW:g}]"
        ),
    ] = (80.0, 160.0)

    @field_validator("library", mode="before")
    @classmethod
    def _one_file(cls, value: Any) -> Any:
        """One file, folder or glob may be given alone (``library: tracks.csv``)."""
        return [value] if isinstance(value, str) else value

    @model_validator(mode="after")
    def _order(self) -> TrafficConfig:
        if self.v_max < self.v_min:
            raise ValueError(f"v_max ({self.v_max}) must be >= v_min ({self.v_min})")
        return self


def _track_id(value: Any) -> Any:
    """A track id as text (an integer, numpy's too, as written); anything else but text is
    refused in plain words (pydantic's union named its types)."""
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return str(int(value))
    if isinstance(value, str):
        return value
    number = isinstance(value, numbers.Real) and not isinstance(value, bool)
    hint = (f' (quote it as written in the file, e.g. "{int(value)}")'
            if number and float(value).is_integer() else "")  # fmt: skip
    if value is None:
        raise ValueError("no track id given (an empty ego.track: give an id, or 'random')")
    raise ValueError(f"track id {value!r} is neither text nor a whole number{hint}")


class EgoConfig(Strict):
    lane: Annotated[int, Field(ge=0, le=7)] = 1
    speed: Annotated[NonNegFloat, Field(description="initial speed [m/s]")] = 8.0
    track: Annotated[
        str | list[Annotated[str, Field(min_length=1)]],
        Field(
            description="recorded scenes: the ego's track_id, 'random' (any fit track, drawn "
            "from the seed) or a list of track_ids to draw from"
        ),
    ] = "random"
    vehicle: VehicleConfig = VehicleConfig()

    @field_validator("track", mode="before")
    @classmethod
    def _ids_as_text(cls, value: Any) -> Any:
        """Track ids are text; an integer id (``track: 42``, as a user types it) is one. A
        number with a fraction, a truth value or an empty list is refused in plain words."""
        if isinstance(value, list | tuple):
            if not value:
                raise ValueError("an empty list names no track: give track ids, or 'random'")
            return [_track_id(v) for v in value]
        return _track_id(value)


class EnvConfig(Strict):
    """What the gymnasium environment observes, decides and scores."""

    history: Annotated[int, Field(ge=1, le=32, description="tau_i: grids in an observation")] = 5
    horizon: Annotated[int, Field(ge=1, le=20, description="tau_o: set-points in a plan")] = 5
    setpoint_period: Annotated[float, Field(gt=0, le=5, description="set-point spacing [s]")] = 0.5
    decision_period: Annotated[
        float, Field(gt=0, le=5, description="time between decisions [s], a multiple of dt")
    ] = 0.1
    speed_range: Annotated[
        tuple[NonNegFloat, PositiveFloat] | None,
        Field(description="[v_min, v_max] counted by l3 [m/s]; default: the traffic bounds"),
    ] = None
    destination_tolerance: Annotated[float, Field(gt=0, le=50, description="[m]")] = 2.0
    end_at_destination: Annotated[
        bool,
        Field(description="reaching the destination ends the episode (terminated); false: it "
              "runs on to its time limit, info still saying destination_reached (recording "
              "windows: a human crawling near its end point drives on to its recording's end)"),
    ] = True  # fmt: skip
    goal_seconds: Annotated[
        float | None,
        Field(gt=0, le=30, description="how far ahead the observed destination lies [s]: "
              "where the reference will be then; default: the end of the horizon (the last "
              "set-point's time), >= it"),
    ] = None  # fmt: skip

    @property
    def goal_time(self) -> float:
        """How far ahead the observed destination lies [s] (``goal_seconds``, by default the
        end of the horizon)."""
        return self.horizon_time if self.goal_seconds is None else float(self.goal_seconds)

    @property
    def setpoint_times(self) -> np.ndarray:
        """The set-point times [s] after a decision (:func:`gridsim.frames.setpoint_times`)."""
        return setpoint_times(self.setpoint_period, self.horizon)

    @property
    def horizon_time(self) -> float:
        """How far a plan reaches [s]: the last set-point's time."""
        return self.horizon * self.setpoint_period


class ScenarioConfig(Strict):
    """A whole scenario file."""

    name: Annotated[str, Field(min_length=1, max_length=80)]
    description: str = ""

    @field_validator("name", mode="before")
    @classmethod
    def _name_as_written(cls, value: Any) -> Any:
        """A name YAML reads as a number or a truth value (``name: 101``, ``name: no``)."""
        if isinstance(value, bool | int | float):
            raise ValueError(f"YAML reads this name as {value!r}, not text: quote it "
                             "(name: \"...\")")  # fmt: skip
        return value

    simulation: SimulationConfig = SimulationConfig()
    #: the road family's block, told apart by ``type``: the union of the registered families'
    #: configs (:mod:`gridsim.scenario.family` builds it when a family registers)
    road: RoadConfig
    traffic: TrafficConfig = TrafficConfig()
    ego: EgoConfig = EgoConfig()
    sensor: SensorConfig = SensorConfig()
    env: EnvConfig = EnvConfig()

    @model_validator(mode="before")
    @classmethod
    def _ego_lane_on_a_narrow_road(cls, data: Any) -> Any:
        """The ego's default lane on a road of fewer lanes than it: the last lane (a one-lane
        road needs no ``ego.lane: 0``)."""
        if not isinstance(data, dict):
            return data
        road, ego = data.get("road"), data.get("ego", {})
        lanes = road.get("lanes") if isinstance(road, dict) else None
        default = EgoConfig.model_fields["lane"].default
        whole = (isinstance(lanes, numbers.Real) and not isinstance(lanes, bool)
                 and float(lanes).is_integer())  # (1, 1.0, numpy's 1)  # fmt: skip
        if whole and 1 <= lanes <= default and isinstance(ego, dict) and "lane" not in ego:
            return {**data, "ego": {**ego, "lane": int(lanes) - 1}}
        return data

    @model_validator(mode="after")
    def _consistency(self) -> ScenarioConfig:
        """Checks across sections, every failing one reported (one line each)."""
        problems = []
        if self.ego.speed > self.ego.vehicle.v_max:
            problems.append(f"ego.speed ({self.ego.speed}) must be <= ego.vehicle.v_max "
                            f"({self.ego.vehicle.v_max})")  # fmt: skip
        lanes = getattr(self.road, "lanes", None)
        if lanes is not None and self.ego.lane >= lanes:
            problems.append(f"ego.lane ({self.ego.lane}) must be < road.lanes ({lanes})")
        dt = self.simulation.dt
        ticks = self.env.decision_period / dt
        if abs(ticks - round(ticks)) > 1e-6 or round(ticks) < 1:
            problems.append(f"env.decision_period ({self.env.decision_period}) must be a whole "
                            f"multiple of simulation.dt ({dt})")  # fmt: skip
        if self.simulation.duration < self.env.decision_period - 1e-9:
            problems.append(f"simulation.duration ({self.simulation.duration:g} s) is shorter "
                            f"than one decision (env.decision_period, "
                            f"{self.env.decision_period:g} s)")  # fmt: skip
        goal = self.env.goal_seconds
        if goal is not None and goal < self.env.horizon_time - 1e-9:
            problems.append(f"env.goal_seconds ({goal:g}) must be >= the horizon's "
                            f"{self.env.horizon_time:g} s (env.horizon x env.setpoint_period): "
                            "the destination lies at or beyond the last set-point")  # fmt: skip
        if self.env.speed_range is not None and self.env.speed_range[0] > self.env.speed_range[1]:
            problems.append(f"env.speed_range {list(self.env.speed_range)} must be [min, max]")
        elif self.speed_range[0] > self.ego.vehicle.v_max:
            where = ("env.speed_range" if self.env.speed_range is not None else
                     "traffic.v_min and v_max (env.speed_range's default)")  # fmt: skip
            lo, hi = self.speed_range
            problems.append(
                f"{where} [{lo:g}, {hi:g}] m/s begin above ego.vehicle.v_max "
                f"({self.ego.vehicle.v_max:g} m/s): l3 would never count the ego's "
                "speed; give env.speed_range the speeds that count, in m/s"
            )
        if self.traffic.v_max > MAX_TRAFFIC_SPEED:
            problems.append(f"traffic.v_max ({self.traffic.v_max:g} m/s) is faster than road "
                            f"traffic drives (at most {MAX_TRAFFIC_SPEED:g} m/s, "
                            f"{MAX_TRAFFIC_SPEED * 3.6:g} km/h); speeds are in m/s (km/h / "
                            "3.6)")  # fmt: skip
        if problems:
            raise ValueError("\n".join(problems))
        return self

    @property
    def ticks_per_decision(self) -> int:
        return round(self.env.decision_period / self.simulation.dt)

    @property
    def episode_decisions(self) -> int:
        """Decisions (environment steps) in an episode of ``simulation.duration``."""
        return int(round(self.simulation.duration / self.env.decision_period))

    @property
    def speed_range(self) -> tuple[float, float]:
        """``[v_min, v_max]`` [m/s] inside which l3 counts the speed."""
        return self.env.speed_range or (self.traffic.v_min, self.traffic.v_max)


@dataclass(frozen=True)
class Scenario:
    """A validated scenario and the folder relative paths in it resolve against."""

    config: ScenarioConfig
    source: str
    base_dir: Path | None

    @property
    def name(self) -> str:
        return self.config.name
