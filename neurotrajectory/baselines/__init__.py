"""Baselines of the paper's comparison: a Dynamic Window Approach planner
(:mod:`~neurotrajectory.baselines.dwa`), the End2End command classifier
(:mod:`~neurotrajectory.baselines.end2end`) and constant velocity
(:mod:`~neurotrajectory.baselines.constant_velocity`)."""
