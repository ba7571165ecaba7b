"""NeuroTrajectory: the perception-planning network and its neuroevolution trainer.

Pipeline: :mod:`neurotrajectory.model` (the network) -> :mod:`neurotrajectory.genome`
(flat genomes, noise table, recipes) -> :mod:`neurotrajectory.pareto` and
:mod:`neurotrajectory.evolution` (selection) -> :mod:`neurotrajectory.rollout` (fitness in
GridSim-v0) -> :mod:`neurotrajectory.backends` (local, processes, Ray) ->
:mod:`neurotrajectory.train` (runs, checkpoints, resume). ``gridsim`` never imports it.
"""
