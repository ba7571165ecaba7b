"""Scripted ego drivers: the lane follower (route by pure pursuit, distance by IDM) and the
human driver of the reference's shadow world."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import lru_cache

import numpy as np

from gridsim.traffic.profiles import ProfileChain
from gridsim.vehicle.control import PursuitGains
from gridsim.vehicle.idm import IDMParams
from gridsim.vehicle.kinematics import BicycleParams, V, centre_of
from gridsim.world.scripted_driver_kernels import follower_inputs


class LaneFollower:
    """Follows ``world.route`` at up to ``speed`` [m/s], braking for traffic on the route.

    It tracks its position along the route from call to call (a few segments of walking
    instead of a projection onto the whole route).
    """

    def __init__(
        self,
        speed: float,
        idm: IDMParams | None = None,
        gains: PursuitGains | None = None,
        lookahead: float = 60.0,
    ) -> None:
        self.speed, self.lookahead = speed, lookahead
        self.idm = idm or IDMParams()
        self.gains = gains or PursuitGains()
        # the world and route tracked (held, so that new ones are never mistaken for them:
        # copies of a world share their immutable routes)
        self._world = self._route = None
        self._hint = 0
        self._settings = None

    def __call__(self, world) -> tuple[float, float]:
        """Inputs ``(acceleration [m/s^2], steering rate [rad/s])`` for the current state."""
        return self.inputs(world, self.speed, 0.0)

    def tracked(self, world) -> int:
        """The route segment :meth:`inputs` tracks the ego from on ``world``'s current route
        (see :meth:`set_tracked`)."""
        return self._hint_on(world, world.route)

    def set_tracked(self, hint: int) -> None:
        """The segment as :meth:`inputs` would have tracked it (for compiled ticks)."""
        self._hint = hint

    def _hint_on(self, world, route) -> int:
        """The segment of ``route`` to track the ego from: the last one, or on a new route
        (or world) the nearest one."""
        if route is not self._route or world is not self._world:  # search all of a new route
            _, _, seg = route.project(world.ego[None, :2])
            self._world, self._route, self._hint = world, route, int(seg[0])
        return self._hint

    def inputs(
        self, world, speed: float, offset: float, yield_to: Sequence[int] = ()
    ) -> tuple[float, float]:
        """Inputs keeping lateral ``offset`` [m] from the route at up to ``speed`` [m/s];
        with ``yield_to`` (fleet indices), also giving way to those vehicles
        (:func:`conflict_free_accel`)."""
        route = world.route
        f = world.traffic.fleet
        accel, steer_rate, s_rear, d_rear, self._hint = follower_inputs(
            route.tracking_data(), (f.x, f.y, f.active, f.length, f.width, f.v),
            tuple(world.ego.tolist()), driver_limits(world.ego_params),
            self._hint_on(world, route), float(speed), float(offset), self.settings)  # fmt: skip
        if len(yield_to):
            accel = conflict_free_accel(world, route, s_rear, d_rear, accel, yield_to)
        return accel, steer_rate

    def tick_data(self, world) -> tuple | None:
        """What a compiled tick needs to drive as this follower does (the ``driver`` of
        :func:`~gridsim.envs.shadow_world_kernels.ticks`): the route's tracking data, the
        segment tracked and :attr:`settings`; None where the kernel would not drive as it
        does (a subclass with inputs of its own), so that its world ticks in Python."""
        if type(self).inputs is not LaneFollower.inputs:
            return None
        return (world.route.tracking_data(), self.tracked(world), self.settings)

    @property
    def settings(self) -> tuple:
        """Pursuit gains, IDM parameters, projection window and leader look-ahead, as
        :func:`~gridsim.world.scripted_driver_kernels.follower_inputs` takes them."""
        if self._settings is None:
            g = self.gains
            gains = (g.min_lookahead, g.lookahead_time, g.steer_time, g.speed_gain)
            self._settings = (gains, self.idm.values, 96, float(self.lookahead))
        return self._settings


@lru_cache(maxsize=16)
def driver_limits(p: BicycleParams) -> tuple[float, ...]:
    """The ego's size and limits as :func:`~gridsim.world.scripted_driver_kernels.follower_inputs`
    takes them."""
    return tuple(float(a) for a in (p.length, p.width, p.center_offset, p.wheelbase,
                                    p.delta_max, p.b_max, p.a_max, p.v_delta_max))  # fmt: skip


#: Prediction horizon [s] and step [s] of :func:`conflict_free_accel`.
YIELD_HORIZON, YIELD_STEP = 4.0, 0.2
#: Extra clearance [m] between the footprints' covering disks when giving way.
YIELD_MARGIN = 1.0


def _disks(x, y, psi, length):
    """Centres ``(..., 3, 2)`` [m] of three disks along a vehicle of ``length`` [m] centred at
    ``(x, y)`` with heading ``psi`` (arrays broadcast); with radius :func:`_disk_radius` they
    cover its footprint."""
    along = np.asarray(length)[..., None] * (np.array([-1.0, 0.0, 1.0]) / 3.0)
    cx = np.asarray(x)[..., None] + along * np.cos(psi)[..., None]
    cy = np.asarray(y)[..., None] + along * np.sin(psi)[..., None]
    return np.stack([cx, cy], axis=-1)


def _disk_radius(length, width):
    return np.hypot(np.asarray(length) / 6.0, np.asarray(width) / 2.0)


def conflict_free_accel(world, route, s_rear, d_rear, accel, vehicles) -> float:
    """The acceleration [m/s^2] closest to ``accel`` (trying ``accel``, then braking harder,
    then accelerating) under which the ego, held at that acceleration along ``route`` at its
    lateral offset ``d_rear`` [m], keeps clear of ``vehicles`` (fleet indices) for
    :data:`YIELD_HORIZON` seconds, each predicted along its own path at its current speed.
    If every candidate meets one, the one that meets it latest."""
    f = world.traffic.fleet
    idx = np.asarray([j for j in vehicles if f.active[j]], dtype=np.int64)
    if len(idx) == 0:
        return accel
    p = world.ego_params
    t = YIELD_STEP * np.arange(1, round(YIELD_HORIZON / YIELD_STEP) + 1)
    m = len(t)
    s = (f.s[idx, None] + f.v[idx, None] * t).ravel()
    xy, h = f.paths.frenet_to_world(np.repeat(f.path[idx], m), s, np.repeat(f.d[idx], m))
    shape = (len(idx), m)
    other = _disks(xy[:, 0].reshape(shape), xy[:, 1].reshape(shape), h.reshape(shape),
                   f.length[idx, None])  # fmt: skip
    # clearance needed between disk centres, per vehicle (broadcast over time and disks)
    reach = _disk_radius(f.length[idx], f.width[idx]) + _disk_radius(p.length, p.width)
    reach = (reach + YIELD_MARGIN)[:, None, None, None]
    candidates = [accel] + [a for a in (0.0, -1.5, -3.0, -p.b_max) if a < accel] + [p.a_max]
    v0 = float(world.ego[V])
    first_conflict = []
    for a in candidates:
        stop = np.inf if a >= 0 else v0 / -a
        tt = np.minimum(t, stop)
        ds = v0 * tt + 0.5 * a * tt**2
        rear, h_ego = route.frenet_to_world(s_rear + ds, np.full(m, d_rear))
        centre = centre_of(rear, h_ego, p.center_offset)
        ego = _disks(centre[:, 0], centre[:, 1], h_ego, p.length)
        # distances (vehicle, time, ego disk, other disk)
        gap = np.linalg.norm(ego[None, :, :, None, :] - other[:, :, None, :, :], axis=-1)
        hit = np.any(gap < reach, axis=(0, 2, 3))
        if not hit.any():
            return float(a)
        first_conflict.append(t[np.argmax(hit)])
    return float(candidates[int(np.argmax(first_conflict))])


class HumanDriver:
    """Drives the route with a human speed and lateral-offset profile (a
    :class:`~gridsim.traffic.profiles.ProfileChain` over time from the start of the episode,
    produced as far as needed), keeping its distance to traffic like :class:`LaneFollower`.

    ``yield_to(tick)`` names the fleet indices to give way to at that tick (see
    :func:`conflict_free_accel`): how a reference avoids a collision it has foreseen."""

    def __init__(
        self,
        chain: ProfileChain,
        follower: LaneFollower | None = None,
        yield_to: Callable[[int], Sequence[int]] | None = None,
    ) -> None:
        self.chain = chain
        self.follower = follower or LaneFollower(speed=chain.profiles.bounds.v_max)
        self.yield_to = yield_to

    def __call__(self, world) -> tuple[float, float]:
        t = world.time
        speed, offset = self.chain.at(t)
        avoid = self.yield_to(round(t / world.dt)) if self.yield_to else ()
        return self.follower.inputs(world, speed, offset, avoid)
