"""Scenario families, one module each with its world builder and defaults: ``seamless``,
``inner_city`` and ``recorded``. :data:`WORLD_BUILDERS` maps a road configuration's type to
its family's builder ``(scenario, seed) -> World``; :func:`scenario_report` checks a scenario's
recorded data, if its family has any."""

from __future__ import annotations

from collections.abc import Callable

from gridsim.scenario.checks import SceneReport
from gridsim.scenario.families import inner_city, recorded, seamless
from gridsim.scenario.loader import Scenario
from gridsim.scenario.schema import CityRoadConfig, RecordedRoadConfig, SeamlessRoadConfig
from gridsim.world.world import World

WORLD_BUILDERS: dict[type, Callable[[Scenario, int], World]] = {
    SeamlessRoadConfig: seamless.build,
    CityRoadConfig: inner_city.build,
    RecordedRoadConfig: recorded.build,
}

#: The families whose scenarios have recorded data to check: road configuration type ->
#: ``scenario -> SceneReport`` (:mod:`gridsim.scenario.checks`).
DATA_REPORTS: dict[type, Callable[[Scenario], SceneReport]] = {
    RecordedRoadConfig: recorded.data_report,
}


def scenario_report(scenario: Scenario) -> SceneReport:
    """The plausibility report of ``scenario``'s recorded data (an empty report for a family
    without recorded data)."""
    report = DATA_REPORTS.get(type(scenario.config.road))
    return SceneReport((), (), frozenset()) if report is None else report(scenario)


def scenario_problems(scenario: Scenario) -> list[str]:
    """The problems of :func:`scenario_report` (none for generated roads)."""
    return list(scenario_report(scenario).problems)
