"""RGB views of occupancy grids, in the paper's colours."""

from __future__ import annotations

import numpy as np

from gridsim.sensors.occupancy import FREE, OCCUPIED, UNKNOWN

_COLOURS = np.zeros((256, 3), np.uint8)
_COLOURS[FREE] = (0, 200, 0)
_COLOURS[OCCUPIED] = (220, 0, 0)
_COLOURS[UNKNOWN] = (0, 0, 0)


def colourise(grid: np.ndarray) -> np.ndarray:
    """RGB view ``(..., 3)`` uint8 of a grid: green free, red occupied, black unknown."""
    return _COLOURS[grid]
