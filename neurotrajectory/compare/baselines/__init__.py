"""Baselines of the paper's comparison: a Dynamic Window Approach planner
(:mod:`~neurotrajectory.compare.baselines.dwa`), the End2End command classifier
(:mod:`~neurotrajectory.compare.baselines.end2end`) and constant velocity
(:mod:`~neurotrajectory.compare.baselines.constant_velocity`)."""
