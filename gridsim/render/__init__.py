"""Headless rendering: top-down frames and coloured occupancy grids."""

from gridsim.render.grids import colourise
from gridsim.render.topdown import TopDownRenderer, ViewSpec

__all__ = ["TopDownRenderer", "ViewSpec", "colourise"]
