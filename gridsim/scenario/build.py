"""Turn a validated :class:`Scenario` into a :class:`World` and an occupancy-grid sensor.

Dispatch is by the road config's type to its family's builder
(:attr:`~gridsim.scenario.family.Family.build`); static maps and libraries are cached so
that resets are cheap, and the first world of a (scenario, seed) is kept and copied.
"""

from __future__ import annotations

import copy
from collections import OrderedDict

import numpy as np

from gridsim.scenario.family import family_of
from gridsim.scenario.parts import input_stamps
from gridsim.scenario.schema import Scenario
from gridsim.sensors.occupancy import GridSpec, OccupancyGridSensor, SensorMount
from gridsim.world.world import World


def build_sensor(scenario: Scenario) -> OccupancyGridSensor:
    s = scenario.config.sensor
    mounts = tuple(
        SensorMount(m.x, m.y, np.deg2rad(m.yaw_deg), np.deg2rad(m.fov_deg)) for m in s.mounts
    )
    spec = GridSpec(**s.model_dump(exclude={"mounts"}), mounts=mounts)
    return OccupancyGridSensor(spec)


_PRISTINE: OrderedDict[tuple, World] = OrderedDict()
_PRISTINE_SIZE = 64


def build_world(scenario: Scenario, seed: int = 0) -> World:
    """A fresh world for ``scenario``; the same seed always gives the same world.

    The first world built for a (scenario, its files as they are, seed) is kept untouched
    and later ones are copies of it (a copy costs a fraction of a build: warm resets).
    Objects that do not depend on the seed and never change (static maps, profile tables)
    are shared, not copied."""
    key = (scenario.config.model_dump_json(), str(scenario.base_dir), input_stamps(scenario),
           int(seed))  # fmt: skip
    pristine = _PRISTINE.get(key)
    if pristine is None:
        pristine = family_of(scenario).build(scenario, int(seed))
        _PRISTINE[key] = pristine
        if len(_PRISTINE) > _PRISTINE_SIZE:
            _PRISTINE.popitem(last=False)
    else:
        _PRISTINE.move_to_end(key)
    return copy.deepcopy(pristine, {id(o): o for o in _shared_parts(pristine)})


def _shared_parts(world: World) -> list:
    """The parts of ``world`` that copies share: immutable (frozen settings, the last tick's
    result) or independent of the seed and never changed."""
    parts = [world.ego_params, world.last, world.traffic.fleet.p]
    if world.ego_track is not None:
        parts.append(world.ego_track)
    return parts + world.road.shared_parts() + world.traffic.shared_parts()
