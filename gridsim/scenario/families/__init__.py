"""Scenario families, one module each with its world builder and defaults: ``seamless``,
``inner_city`` and ``recorded``. :data:`WORLD_BUILDERS` maps a road configuration's type to
its family's builder ``(scenario, seed) -> World``."""

from __future__ import annotations

from collections.abc import Callable

from gridsim.scenario.families import inner_city, recorded, seamless
from gridsim.scenario.loader import Scenario
from gridsim.scenario.schema import CityRoadConfig, RecordedRoadConfig, SeamlessRoadConfig
from gridsim.world.world import World

WORLD_BUILDERS: dict[type, Callable[[Scenario, int], World]] = {
    SeamlessRoadConfig: seamless.build,
    CityRoadConfig: inner_city.build,
    RecordedRoadConfig: recorded.build,
}
