"""The methods an evaluation compares, by the names its tables print: the baseline planners
that need only a :class:`~neurotrajectory.compare.predictors.Setting` (each class names
itself with ``name``), End2End (trained per group), and NeuroTrajectory's front members."""

from __future__ import annotations

from neurotrajectory.compare.baselines.constant_velocity import ConstantVelocity
from neurotrajectory.compare.baselines.destination_curve import DestinationCurve
from neurotrajectory.compare.baselines.dwa import DWA

#: The trajectory planners made from a scenario's setting alone, in the order the tables
#: list them: ``cls(setting)`` predicts windows (``predict(windows)``: set-points ``(N,
#: tau_o, 2)`` [m, grid frame]) and plans in closed loop; its ``name`` labels its rows.
#: Append a class to compare one more.
PLANNERS: list[type] = [ConstantVelocity, DestinationCurve, DWA]
#: NeuroTrajectory as compared: the front member picked without test data.
NT_PICKED = "NeuroTrajectory"
#: NeuroTrajectory's front member with the lowest test RMSE (an optimistic pick).
NT_BEST = "NeuroTrajectory (best member on test)"
