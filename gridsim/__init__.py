"""GridSim: a headless driving simulator with occupancy-grid sensors.

Pipeline: :mod:`gridsim.road` -> :mod:`gridsim.traffic` -> :mod:`gridsim.world` ->
:mod:`gridsim.sensors`; scenarios (:mod:`gridsim.scenario`) wire them together.
"""

from gridsim.errors import DataError, GridSimError, ScenarioError

__version__ = "0.1.0"
__all__ = ["DataError", "GridSimError", "ScenarioError", "__version__"]
