"""The world: road, traffic and the ego vehicle, advanced together at a fixed time step."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gridsim.road.base import Road
from gridsim.road.polyline import Polyline
from gridsim.traffic.fleet import EgoPose
from gridsim.traffic.sources import TrafficSource
from gridsim.traffic.track import Track
from gridsim.vehicle.kinematics import (
    PSI,
    STATE_SIZE,
    BicycleParams,
    V,
    X,
    Y,
    centre_xy,
    step_bicycle,
    step_limits,
)
from gridsim.world import world_kernels
from gridsim.world.collision import CollisionChecker, Contact

_NO_CONTACT = Contact()


@dataclass(frozen=True)
class TickResult:
    """Outcome of one tick: inputs actually applied, contacts, and whether the ego left the road."""

    accel: float
    steer_rate: float
    contact: Contact
    off_road: bool

    @property
    def collided(self) -> bool:
        return bool(self.contact.vehicles)


class World:
    """Road + traffic + ego. The ego state is ``[x, y, psi, v, delta]`` (rear axle, SI units).

    ``route`` returns the ego's nominal path (its lane or route) for controllers and rewards.
    """

    def __init__(
        self,
        road: Road,
        traffic: TrafficSource,
        ego_params: BicycleParams,
        ego_state: np.ndarray,
        dt: float,
        route: Callable[[], Polyline],
        rng: np.random.Generator,
        ego_track: Track | None = None,
    ) -> None:
        if not dt > 0:
            raise ValueError(f"time step dt must be > 0, got {dt}")
        self.road = road
        self.traffic = traffic
        self.ego_params = ego_params
        self.dt = float(dt)
        self._route = route
        #: On recorded scenes, the human track the ego replaces (its future is the reference).
        self.ego_track = ego_track
        self.ego = np.asarray(ego_state, dtype=np.float64).reshape(STATE_SIZE).copy()
        self.time = 0.0
        self.moved = 0.0  # how far [m] the rear axle moved in the last checked tick
        self.collision = CollisionChecker(ego_params.length, ego_params.width)
        road.update(self.ego[:2])
        traffic.reset(rng, self.ego_pose())
        on_road = bool(road.is_drivable(self.ego_center()[None])[0])
        self.last = TickResult(0.0, 0.0, self.check_contacts(), not on_road)
        self._checked = True  # whether ``last`` was tested (see :meth:`tick`)

    @property
    def route(self) -> Polyline:
        return self._route()

    def _center_xy(self) -> tuple[float, float]:
        return centre_xy(self.ego[X], self.ego[Y], self.ego[PSI], self.ego_params.center_offset)

    def ego_center(self) -> np.ndarray:
        """Centre of the ego footprint [m] in the world frame."""
        return np.array(self._center_xy())

    def ego_pose(self) -> EgoPose:
        cx, cy = self._center_xy()
        p = self.ego_params
        return EgoPose(cx, cy, float(self.ego[PSI]), float(self.ego[V]), p.length, p.width)

    def tick(self, accel: float, steer_rate: float, check: bool = True) -> TickResult:
        """Advance the world by ``dt``: ego kinematics, road generation, traffic, collisions.
        ``check=False`` skips the ego's contact and road-edge tests (the result then reports
        none), for a caller that tests what it needs itself (the reference's shadow world)."""
        step = step_bicycle(self.ego, accel, steer_rate, self.ego_params, self.dt)
        previous, self.ego = self.ego, step.state
        self.road.update(self.ego[:2])
        pose = self.ego_pose()
        self.traffic.tick(self.dt, pose)
        self.time += self.dt
        if not check:
            return self.unchecked(float(step.accel), float(step.steer_rate))
        return self._checked_tick(previous, float(step.accel), float(step.steer_rate))

    def _checked_tick(
        self, previous: np.ndarray, accel: float, steer_rate: float, contact: Contact | None = None
    ) -> TickResult:
        """The rest of a checked :meth:`tick` that moved the ego from ``previous`` applying
        ``accel`` and ``steer_rate``: the contact and road-edge tests (``contact``: the
        contacts if known)."""
        if contact is None:
            contact = self.check_contacts()
        self.moved = moved = float(np.hypot(self.ego[0] - previous[0], self.ego[1] - previous[1]))
        trusted, self._checked = self._checked, True
        if contact.boundaries:
            off_road = True
        elif (trusted and not self.last.off_road and moved < 0.5 * self.ego_params.width
              and self.road.enclosed):  # fmt: skip
            # Still on the road: the footprint cannot have crossed an edge without touching it
            # (a recorded map's open ends have no edge: there the test below runs).
            off_road = False
        else:
            off_road = not bool(self.road.is_drivable(self.ego_center()[None])[0])
        self.last = TickResult(accel, steer_rate, contact, off_road)
        return self.last

    def tick_following(self, follow) -> TickResult:
        """A checked :meth:`tick` with the inputs of ``follow(world)``, a
        :class:`~gridsim.envs.actions.PathControl` (pure pursuit along a path, or a stop) or
        :class:`~gridsim.envs.actions.HeldInputs`: in one compiled call with the traffic's
        tick (:func:`~gridsim.world.world_kernels.follow_tick`; the same bits) where the road
        is static or offers its :meth:`~gridsim.road.base.Road.tracking` and the traffic its
        :meth:`~gridsim.traffic.sources.TrafficSource.tick_data`; otherwise, or when the road
        must grow, in Python."""
        args = self._follow_args(follow)
        if args is None:
            return self.tick(*follow(self))
        out = world_kernels.follow_tick(*args)
        if out.status == world_kernels.NOT_FINITE:
            return self.tick(*follow(self))
        if out.status == world_kernels.BEFORE:
            return self.tick(out.accel, out.steer)
        previous, self.ego = self.ego, np.array(out.ego)
        self.road.set_tracked(out.road_s, out.road_hint)
        placed = False  # whether the refill may have placed someone (None: it did not say)
        if out.status == world_kernels.TRAFFIC:
            placed = self.traffic.refill(out.ended, self.ego_pose(), self.dt) is not False
        self.time += self.dt
        contact = None
        quiet = out.quiet and not placed
        if quiet and self.collision.keeps_boundaries(self.road.version, *out.center):
            contact = _NO_CONTACT  # what check_contacts finds: nothing near
        return self._checked_tick(previous, out.applied, out.steer_rate, contact)

    def _follow_args(self, follow) -> tuple | None:
        """The arguments of :func:`~gridsim.world.world_kernels.follow_tick`, or None when
        this world does not tick compiled."""
        p = self.ego_params
        if not p._scalar:
            return None
        static = self.road.static  # nothing to track (None to the kernel)
        road = None if static else self.road.tracking()
        traffic = self.traffic.tick_data(self.dt, self.road)
        if traffic is None or (road is None and not static):  # what they offer the kernel
            return None
        return (tuple(self.ego.tolist()), step_limits(p), self.dt, follow.kernel_data(), road,
                traffic, (p.length, p.width, p.center_offset),
                self.collision.broad_phase_data())  # fmt: skip

    def unchecked(self, accel: float, steer_rate: float) -> TickResult:
        """Record a tick that applied ``accel`` [m/s^2] and ``steer_rate`` [rad/s] without the
        contact and road-edge tests (:meth:`tick` with ``check=False``, or compiled ticks)."""
        self.last = TickResult(accel, steer_rate, Contact(), False)
        self._checked = False  # the next checked tick cannot trust last.off_road
        return self.last

    def check_contacts(self) -> Contact:
        center = self.ego_center()
        self.collision.set_boundaries(self.road.boundary_segments(), self.road.version, center)
        return self.contacts(self.collision, center)

    def contacts(self, checker: CollisionChecker, center: np.ndarray | None = None) -> Contact:
        """What ``checker``'s ego box, placed at the ego's pose, touches among the active
        traffic (and the road edges it has loaded). ``center``: the ego centre if known."""
        center = self.ego_center() if center is None else center
        return checker.check_fleet(center, float(self.ego[PSI]), self.traffic.fleet)
