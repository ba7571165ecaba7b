"""Headless top-down rendering."""

from gridsim.render.topdown import TopDownRenderer, ViewSpec

__all__ = ["TopDownRenderer", "ViewSpec"]
