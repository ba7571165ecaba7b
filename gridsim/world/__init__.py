"""The world: road + traffic + ego, and ego collision detection."""

from gridsim.world.collision import CollisionChecker, Contact
from gridsim.world.world import TickResult, World

__all__ = ["CollisionChecker", "Contact", "TickResult", "World"]
