"""Golden episodes: SHA-256 digests of everything a rollout produces, for bit-identity tests.

Optimisations of the step path must not change any result. :func:`env_digests` rolls out
``GridSim-v0`` with fixed action policies and hashes, per quantity, the observations, the
rewards and flags, the ego pose and the fleet state after every step; :func:`world_digests`
does the same for bare :meth:`World.tick` calls driven by a :class:`LaneFollower`. The
recorded digests live in ``tests/data/golden_digests.json``; re-record them (only from a
commit whose results are known to be right) with::

    python tests/golden.py                      # every section
    python tests/golden.py training datasets    # only these sections

:func:`training_digests` and :func:`dataset_digests` guard the trainer the same way: a
short warm-started training run (its history without timings, front and checkpoint), short
runs down the trainer's other paths (:data:`TRAINING_PATHS`; a resumed run must match the
uninterrupted one) and recorded window datasets.

The simulator's digests hold on every x86-64 CPU (its transcendental functions go through
libm: :mod:`gridsim.libm`). The training digests involve torch's CPU kernels (MKL, oneDNN,
ATen's vectorised functions), whose float rounding depends on the CPU's vendor and instruction
set: they are recorded per :func:`numerics_platform`, and a platform with no record of its
own skips those tests (record it with ``python tests/golden.py training training_paths``).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import openblas_pin  # noqa: F401  (before NumPy: recorded with the kernels the tests use)

# isort: split
import gymnasium as gym
import numpy as np
from proc_cpuinfo import cpuinfo_field

from gridsim.envs import ENV_ID
from gridsim.scenario import build_world, load_scenario
from gridsim.world.scripted_drivers import LaneFollower

GOLDEN_PATH = Path(__file__).parent / "data" / "golden_digests.json"


def numerics_platform() -> str:
    """``"<CPU vendor>/<torch CPU capability>/torch <version>"``, e.g.
    ``"AuthenticAMD/AVX512/torch 2.13.0"``: what torch's float rounding depends on. The record
    of the first (AVX2) machine, whose vendor was not noted, is stored under ``"*/AVX2/..."``
    and stands for any vendor."""
    import torch

    vendor = cpuinfo_field("vendor_id") or "unknown"
    return f"{vendor}/{torch.backends.cpu.get_cpu_capability()}/torch {torch.__version__}"


def training_golden(golden: dict, section: str) -> dict | None:
    """The digests of ``section`` recorded for this machine's :func:`numerics_platform`, or
    None when it has none."""
    records = golden.get(section, {})
    platform = numerics_platform()
    return records.get(platform, records.get("*/" + platform.split("/", 1)[1]))


SCENARIOS = ("seamless", "inner_city", "us101_3_3", "us101_4_1", "lankershim_1_1", "peachtree_4_8")
SEEDS = (0, 7)
POLICIES = ("reference", "reference_shifted", "control", "discrete")
STEPS = 150
#: World-level cases: (name, scenario, overrides, ticks).
WORLD_CASES = (
    (
        "seamless_1000",
        "seamless",
        {"traffic": {"participants": 1000, "window": [4000.0, 4000.0]}},
        200,
    ),
    ("seamless_20", "seamless", {"traffic": {"participants": 20, "window": [80.0, 160.0]}}, 400),
    ("inner_city_60", "inner_city", {"traffic": {"participants": 60}}, 300),
)


class _Digests:
    """One running SHA-256 per named quantity."""

    def __init__(self) -> None:
        self._h: dict[str, hashlib._Hash] = {}

    def add(self, name: str, value) -> None:
        a = np.ascontiguousarray(np.asarray(value))
        h = self._h.setdefault(name, hashlib.sha256())
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())

    def hexdigests(self) -> dict[str, str]:
        return {k: h.hexdigest() for k, h in sorted(self._h.items())}


def _fleet(d: _Digests, world) -> None:
    f = world.traffic.fleet
    for name in ("active", "mode", "x", "y", "psi", "v", "s", "d", "tau", "gap", "leader"):
        d.add(f"fleet_{name}", getattr(f, name))


def _action(policy: str, info: dict, k: int):
    if policy == "reference":
        return info["reference_setpoints"]
    if policy == "reference_shifted":  # off the reference: a lateral shift and a stretch
        return info["reference_setpoints"] * np.float32(1.1) + np.float32([0.0, 0.7])
    if policy == "control":
        return np.array([1.5 * np.sin(0.1 * k), 0.3 * np.cos(0.07 * k)], np.float32)
    return k % 5  # discrete


def env_digests(scenario: str, seed: int, policy: str, steps: int = STEPS) -> dict[str, str]:
    """Digests of a ``steps``-step rollout (resetting with the next seed when an episode ends)."""
    action_type = {"control": "control", "discrete": "discrete"}.get(policy, "trajectory")
    env = gym.make(ENV_ID, scenario=scenario, action_type=action_type)
    d = _Digests()
    obs, info = env.reset(seed=seed)
    for k in range(steps):
        obs, reward, terminated, truncated, info = env.step(_action(policy, info, k))
        for key, value in obs.items():
            d.add(f"obs_{key}", value)
        d.add("reward", reward)
        d.add("flags", [terminated, truncated, info["collision"], info["off_road"],
                        info["destination_reached"]])  # fmt: skip
        d.add("pose", info["pose"])
        d.add("setpoints", info["reference_setpoints"])
        d.add("contacts", info["collided_with"] + [-1] + info["road_edges_touched"])
        _fleet(d, env.unwrapped.world)
        if terminated or truncated:
            obs, info = env.reset(seed=seed + 1000 + k)
    env.close()
    return d.hexdigests()


def world_digests(scenario: str, overrides: dict, ticks: int, seed: int = 0) -> dict[str, str]:
    """Digests of ``ticks`` world ticks driven by a lane follower at 10 m/s."""
    world = build_world(load_scenario(scenario, overrides), seed)
    driver = LaneFollower(speed=10.0)
    d = _Digests()
    for _ in range(ticks):
        r = world.tick(*driver(world))
        d.add("ego", world.ego)
        d.add("result", [r.accel, r.steer_rate, float(r.off_road)])
        d.add("contacts", list(r.contact.vehicles) + [-1] + list(r.contact.boundaries))
        _fleet(d, world)
    return d.hexdigests()


#: Datasets recorded for :func:`dataset_digests`: (scenario, episodes, seed, duration [s]).
DATASET_CASES = (("seamless", 2, 9, 6.0), ("inner_city", 2, 4, 6.0), ("us101_3_3", 2, 0, None))
#: History fields that measure time, not results.
TIMING_FIELDS = ("seconds", "individual_steps_per_s")
#: History fields added after the training digests were recorded, checked by tests of their
#: own (``test_nt_train.py``): evaluations on the validation episodes that change nothing else.
LATER_FIELDS = ("knee_validation", "warm_start_validation")


def _windows_digests(d: _Digests, prefix: str, windows) -> None:
    from dataclasses import fields

    for f in fields(windows):
        d.add(f"{prefix}{f.name}", getattr(windows, f.name))


def dataset_digests(scenario: str, episodes: int, seed: int, duration) -> dict[str, str]:
    """Digests of every array of the windows ``record_scenario`` records."""
    from neurotrajectory.data.windows import record_scenario

    d = _Digests()
    _windows_digests(d, "", record_scenario(scenario, episodes, seed=seed, duration=duration)[0])
    return d.hexdigests()


def training_digests(out: Path) -> dict[str, str]:
    """Digests of a short run in ``out``: a warm start on 2 recorded episodes with a DAgger
    round, then 2 generations of 4 tiny networks (local backend, batched)."""
    from neurotrajectory.evolve.runs import Run, TrainConfig

    config = TrainConfig(preset="tiny", population=4, generations=2, episodes=1,
                         episode_seconds=3.0, seed=3, pretrain_episodes=2, pretrain_epochs=2,
                         dagger_rounds=1, validation_episodes=2, batch=3,
                         selection="pareto")  # fmt: skip
    Run.create(out, config).train(progress=False)
    return run_digests(out)


#: Short runs down the paths the warm-started golden run does not take (``train`` settings):
#: generation 0 from random weights (plans followed as given), a warm start evaluated by
#: worker processes, and anchored selection (recorded later: a platform may lack it).
TRAINING_PATHS = {
    "random_init": dict(preset="tiny", population=4, generations=3, episodes=1,
                        episode_seconds=3.0, seed=5, validation_episodes=2, batch=3,
                        plan_smoothing=0.0),
    "warm_start_processes": dict(preset="tiny", population=4, generations=2, episodes=1,
                                 episode_seconds=3.0, seed=4, pretrain_episodes=2,
                                 pretrain_epochs=1, validation_episodes=1, batch=2,
                                 backend="processes", workers=2, selection="pareto"),
    "anchored": dict(preset="tiny", population=5, generations=3, episodes=1,
                     episode_seconds=3.0, seed=6, pretrain_episodes=2, pretrain_epochs=1,
                     validation_episodes=2, batch=2, selection="anchored"),
}  # fmt: skip


def training_path_digests(out: Path, name: str) -> dict[str, str]:
    """Digests of the run :data:`TRAINING_PATHS` ``[name]`` in ``out``."""
    from neurotrajectory.evolve.runs import Run, TrainConfig

    Run.create(out, TrainConfig(**TRAINING_PATHS[name])).train(progress=False)
    return run_digests(out)


def run_history(out: Path) -> list[dict]:
    """The generations of the run in ``out`` (its ``history.json``)."""
    return json.loads((Path(out) / "history.json").read_text())["generations"]


def untimed_history(out: Path) -> list[dict]:
    """:func:`run_history` without the fields that measure time (:data:`TIMING_FIELDS`): what
    two runs of the same settings share."""
    return [{k: v for k, v in h.items() if k not in TIMING_FIELDS} for h in run_history(out)]


def run_digests(out: Path) -> dict[str, str]:
    """Digests of a finished run in ``out``: its history without timings, front and
    checkpoint, and ``pretrain.json`` if it has one."""
    d = _Digests()
    for gen in run_history(out):
        for key, value in sorted(gen.items()):
            if key not in TIMING_FIELDS + LATER_FIELDS:
                d.add(f"history_{key}", value)
    for name in ("front.npz", "checkpoint.npz"):
        with np.load(out / name) as arrays:
            for key in sorted(arrays.files):
                # the settings' digest (config.json), not a result; the history (with its
                # timings) is digested above
                if key not in ("run", "history"):
                    d.add(f"{name}_{key}", arrays[key])
    if (out / "pretrain.json").exists():
        pretrain = json.loads((out / "pretrain.json").read_text())
        d.add("pretrain", json.dumps(pretrain, sort_keys=True))
    return d.hexdigests()


def env_cases() -> list[tuple[str, int, str]]:
    """Every policy on the first seed, the reference policy on the others."""
    return [
        (sc, seed, pol)
        for sc in SCENARIOS
        for seed in SEEDS
        for pol in POLICIES
        if seed == SEEDS[0] or pol == "reference"
    ]


def record(sections: tuple[str, ...]) -> dict:
    import tempfile

    out = json.loads(GOLDEN_PATH.read_text()) if GOLDEN_PATH.exists() else {}
    if "env" in sections:
        out["env"] = {}
        for sc, seed, pol in env_cases():
            out["env"][f"{sc}/{seed}/{pol}"] = env_digests(sc, seed, pol)
            print(sc, seed, pol, flush=True)
    if "world" in sections:
        out["world"] = {}
        for name, sc, overrides, ticks in WORLD_CASES:
            out["world"][name] = world_digests(sc, overrides, ticks)
            print(name, flush=True)
    if "datasets" in sections:
        out["datasets"] = {f"{c[0]}/{c[2]}": dataset_digests(*c) for c in DATASET_CASES}
    platform = numerics_platform()
    if "training" in sections:
        with tempfile.TemporaryDirectory() as tmp:
            out.setdefault("training", {})[platform] = training_digests(Path(tmp) / "run")
    if "training_paths" in sections:
        with tempfile.TemporaryDirectory() as tmp:
            out.setdefault("training_paths", {})[platform] = {
                name: training_path_digests(Path(tmp) / name, name) for name in TRAINING_PATHS
            }
    return out


if __name__ == "__main__":
    import sys

    sections = tuple(sys.argv[1:]) or ("env", "world", "datasets", "training", "training_paths")
    GOLDEN_PATH.write_text(json.dumps(record(sections), indent=1, sort_keys=True) + "\n")
