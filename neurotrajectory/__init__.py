"""NeuroTrajectory: the perception-planning network and its neuroevolution trainer.

:mod:`neurotrajectory.model` (the network, its kinematic prior from
:mod:`neurotrajectory.curves`) and three wings:

- :mod:`neurotrajectory.evolve`: training. Genomes and the shared noise table, Pareto
  selection and the genetic algorithm, fitness from closed-loop rollouts in GridSim-v0,
  the local / processes / Ray backends, runs (checkpoints, resume), the warm start and the
  run's plots;
- :mod:`neurotrajectory.data`: labelled windows of human driving (datasets) and the
  discrete commands they imply;
- :mod:`neurotrajectory.compare`: evaluation. Accuracy metrics, the baselines (constant
  velocity, destination curve, DWA, End2End), trained fronts as predictors and policies,
  the closed-loop comparison and the report.

``compare`` uses ``evolve`` and ``data``; ``evolve`` uses ``data``; ``gridsim`` never
imports any of it.
"""

import os

# torch's OpenMP threads busy-wait between parallel regions by default; on a shared machine
# (another process on the cores) that makes training and prediction 5-20x slower. Passive
# threads sleep instead: the same results, at most a little latency. Read when torch is
# first imported (setdefault: a user's own setting wins).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from gridsim import __version__  # noqa: E402  (one distribution, one version)
from gridsim.errors import count_as_internal  # noqa: E402

count_as_internal(os.path.dirname(__file__))  # DataWarnings point at the user's line

__all__ = ["__version__"]
