"""GridSim: a headless driving simulator with occupancy-grid sensors.

Pipeline: :mod:`gridsim.road` -> :mod:`gridsim.traffic` -> :mod:`gridsim.world` ->
:mod:`gridsim.sensors` -> :mod:`gridsim.envs`; scenarios (:mod:`gridsim.scenario`) wire
them together. Importing gridsim registers the gymnasium environment ``GridSim-v0``.
"""

from gridsim.envs import ENV_ID, SCALAR_ENV_ID, register_envs
from gridsim.errors import DataError, GridSimError, ScenarioError

register_envs()

#: The version of the distribution (``gridsim`` and ``neurotrajectory``; pyproject.toml reads
#: it from here).
__version__ = "0.2.0"
__all__ = ["ENV_ID", "SCALAR_ENV_ID", "DataError", "GridSimError", "ScenarioError", "__version__"]
