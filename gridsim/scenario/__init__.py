"""Scenarios: the YAML schema, loading by name or path, and building worlds from them."""

from gridsim.scenario import families  # noqa: F401  (registers the built-in families)
from gridsim.scenario.build import build_sensor, build_world
from gridsim.scenario.loader import builtin_scenarios, load_scenario, parse_scenario
from gridsim.scenario.schema import Scenario

__all__ = [
    "Scenario",
    "build_sensor",
    "build_world",
    "builtin_scenarios",
    "load_scenario",
    "parse_scenario",
]
