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


_PRISTINE: OrderedDict[tuple, tuple[World, int]] = OrderedDict()  # world, its size [bytes]
_PRISTINE_SIZE = 64
#: The most memory the kept worlds take together [bytes] (one world of a recorded scene of
#: 5,000 vehicles takes about 80 MB: 64 of them would not fit).
PRISTINE_BYTES = 512 * 2**20


def build_world(scenario: Scenario, seed: int = 0) -> World:
    """A fresh world for ``scenario``; the same seed always gives the same world.

    The first world built for a (scenario, its files as they are, seed) is kept untouched
    and later ones are copies of it (a copy costs a fraction of a build: warm resets).
    Objects that do not depend on the seed and never change (static maps, profile tables)
    are shared, not copied."""
    key = (scenario.config.model_dump_json(), str(scenario.base_dir), input_stamps(scenario),
           int(seed))  # fmt: skip
    kept = _PRISTINE.get(key)
    if kept is None:
        pristine = family_of(scenario).build(scenario, int(seed))
        _PRISTINE[key] = (pristine, world_bytes(pristine))
        while len(_PRISTINE) > 1 and (
            len(_PRISTINE) > _PRISTINE_SIZE
            or sum(size for _, size in _PRISTINE.values()) > PRISTINE_BYTES
        ):
            _PRISTINE.popitem(last=False)
    else:
        pristine = kept[0]
        _PRISTINE.move_to_end(key)
    return copy.deepcopy(pristine, {id(o): o for o in _shared_parts(pristine)})


def world_bytes(world: World) -> int:
    """About the memory [bytes] a world's traffic takes (its fleet's arrays, paths and
    profile tables: the bulk of a recorded scene's world)."""
    fleet = world.traffic.fleet
    return sum(a.nbytes for a in fleet.state) + fleet.paths.nbytes + fleet.profiles.nbytes


def _shared_parts(world: World) -> list:
    """The parts of ``world`` that copies share: immutable (frozen settings, the last tick's
    result) or independent of the seed and never changed."""
    parts = [world.ego_params, world.last, world.traffic.fleet.p]
    if world.ego_track is not None:
        parts.append(world.ego_track)
    return parts + world.road.shared_parts() + world.traffic.shared_parts()
