"""NeuroTrajectory: the perception-planning network and its neuroevolution trainer.

Not implemented yet (issue 4); ``gridsim`` never imports this package.
"""
