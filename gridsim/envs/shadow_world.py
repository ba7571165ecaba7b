"""The reference's shadow world, ticked: in compiled batches while nothing needs Python
(:func:`~gridsim.envs.shadow_world_kernels.ticks`), by the world's own tick otherwise.

Where the road offers its tracking, the traffic its tick data (the seamless family) and the
driver's follower its own (:meth:`~gridsim.world.scripted_drivers.LaneFollower.tick_data`) a
batch runs the human driver, the ego's step, the road's tracking, the
fleet's tick and the samples, and rules near misses out where the boxes are clearly apart.
Python takes over for a tick that gives way to a vehicle (a revision), grows or trims the
road, or respawns a participant (it draws random numbers: the new profiles of participants
whose profile ran out are drawn ahead, from a copy of the stream), and pymunk decides the
near misses the compiled test cannot rule out. The ticks are the same either way (same bits:
``tests/test_gridsim/envs/test_shadow_world.py``); other roads tick in Python.
"""

from __future__ import annotations

import numpy as np

from gridsim.envs import shadow_world_kernels as kernels
from gridsim.vehicle.kinematics import step_limits
from gridsim.world.collision import CollisionChecker
from gridsim.world.scripted_drivers import HumanDriver, driver_limits
from gridsim.world.world import World

_NO_SAMPLES = (np.zeros((0, 2)), np.zeros(0), np.zeros(0))
#: Chain samples a batch needs beyond its last tick's (see ``ProfileChain.at``).
_CHAIN_AHEAD = 3
#: Profile draws a batch is given for the participants whose profile runs out.
_DRAWS = 16


class ShadowWorld:
    """``world`` driven by ``driver``; its ego's samples (rear axle [m, world], heading [rad],
    speed [m/s]) go to ``samples = (xy, psi, v)`` at their tick's index; ``checker`` is the
    near-miss box the caller tests with (:meth:`World.contacts`)."""

    def __init__(
        self,
        world: World,
        driver: HumanDriver,
        checker: CollisionChecker,
        samples: tuple[np.ndarray, np.ndarray, np.ndarray],
        compiled: bool = True,
    ) -> None:
        self.world, self.driver, self.checker, self.samples = world, driver, checker, samples
        self._compiled = compiled and world.ego_params._scalar
        if self._compiled:  # what does not change from tick to tick
            p = world.ego_params
            self._params = (step_limits(p), driver_limits(p))
            self._box = checker.ego_box

    def advance(
        self, k: int, end: int, yielding: np.ndarray, record: bool = True
    ) -> tuple[int, bool]:
        """Tick samples ``k`` to ``end - 1`` (recording them if ``record``); the driver gives
        way at the ticks where ``yielding`` is set (it decides to whom). Stops after a recorded
        sample whose near miss pymunk must test. Returns the next sample and whether the
        last one needs that test."""
        w = self.world
        while k < end:
            args = self._batch(k, end, record) if self._compiled else None
            if args is not None:
                out = self.samples if record else _NO_SAMPLES
                done = kernels.ticks(k, end, *args, yielding, out)
                if done.next > k or done.status == kernels.TRAFFIC:  # some tick was started
                    w.ego, w.time = np.array(done.ego), done.time
                    self.driver.follower.set_tracked(done.hint)
                    w.road.set_tracked(done.road_s, done.road_hint)
                    w.unchecked(done.accel, done.rate)
                    w.traffic.drew(done.used)
                k = done.next
                if done.status == kernels.DONE or done.status == kernels.CHECK:
                    return k, done.status == kernels.CHECK
                if done.status == kernels.TRAFFIC:  # the rest of tick k
                    w.traffic.refill(done.ended, w.ego_pose(), w.dt)
                    w.time += w.dt
                    k = self._recorded(k, record)
                    if record:
                        return k, True
                    continue
            w.tick(*self.driver(w), check=False)
            k = self._recorded(k, record)
            if record:
                return k, True
        return k, False

    def _recorded(self, k: int, record: bool) -> int:
        """Record sample ``k`` (the ego now) if ``record``; the next sample."""
        if record:
            xy, psi, v = self.samples
            ego = self.world.ego
            xy[k], psi[k], v[k] = ego[:2], ego[2], ego[3]
        return k + 1

    def _batch(self, k: int, end: int, record: bool) -> tuple | None:
        """The arguments of a compiled batch of samples ``k`` to ``end - 1`` but the tick
        flags and the samples, or None if the next tick must run in Python."""
        w, d = self.world, self.driver
        road, traffic = w.road.tracking(), w.traffic.tick_data(w.dt, w.road)
        offer = getattr(d.follower, "tick_data", None)  # a follower of another kind: Python
        driver = offer(w) if offer is not None else None
        if road is None or traffic is None or driver is None:  # what they offer the kernel
            return None
        if traffic.refill or len(traffic.corridors):  # work the batch kernel does not do
            return None
        c = d.chain
        c.extend(end + _CHAIN_AHEAD)  # what ProfileChain.at would compute on the way
        # profiles run out on about one tick in seven: no draws ahead for a tick or two
        draws = _DRAWS if end - k > 2 else 0
        return (
            (w.time, w.dt),
            tuple(w.ego.tolist()),
            self._params,
            driver,
            (c.times, c.speeds, c.offsets, c.ready),
            road,
            traffic,
            w.traffic.continuation(draws),
            (*self._box, record),
        )
