"""Evaluation: metrics, baselines, trained fronts, closed loop and the report."""
