"""The built-in scenario families, one module each with its typed ``road:`` block, its world
builder and its defaults, registered in :data:`gridsim.scenario.family.FAMILIES` when this
package is imported (``gridsim.scenario`` imports it): ``seamless``, ``inner_city`` and
``recorded``. :func:`scenario_report` checks a scenario's recorded data, if its family has
any."""

from __future__ import annotations

from gridsim.scenario.checks import SceneReport
from gridsim.scenario.families import inner_city, recorded, seamless  # noqa: F401 (registers)
from gridsim.scenario.family import family_of
from gridsim.scenario.schema import Scenario


def scenario_report(scenario: Scenario) -> SceneReport:
    """The plausibility report of ``scenario``'s recorded data (an empty report for a family
    without recorded data)."""
    report = family_of(scenario).data_report
    return SceneReport((), (), frozenset()) if report is None else report(scenario)


def scenario_problems(scenario: Scenario) -> list[str]:
    """The problems of :func:`scenario_report` (none for generated roads)."""
    return list(scenario_report(scenario).problems)
