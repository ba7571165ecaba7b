"""Scenarios: the YAML schema, loading by name or path, and building worlds from them."""

from gridsim.scenario.build import build_sensor, build_world
from gridsim.scenario.loader import Scenario, builtin_scenarios, load_scenario, parse_scenario

__all__ = [
    "Scenario",
    "build_sensor",
    "build_world",
    "builtin_scenarios",
    "load_scenario",
    "parse_scenario",
]
