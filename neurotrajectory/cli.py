"""The ``neurotrajectory`` command line: ``train`` and ``rollout``."""

from __future__ import annotations

import argparse
import json
import sys

from gridsim.errors import GridSimError
from neurotrajectory.backends import BackendError
from neurotrajectory.front import PICKS
from neurotrajectory.model import PRESETS
from neurotrajectory.train import Run, RunError, TrainConfig

_TRAIN_KEYS = (
    "scenario", "preset", "population", "generations", "episodes", "episode_seconds", "sigma",
    "seed", "backend", "workers", "ray_address",
)  # fmt: skip


def _cmd_train(args: argparse.Namespace) -> int:
    if args.resume:
        run = Run.open(args.resume, scenario=args.scenario, preset=args.preset,
                       population=args.population, episodes=args.episodes, seed=args.seed,
                       generations=args.generations, backend=args.backend,
                       workers=args.workers, ray_address=args.ray_address)  # fmt: skip
    else:
        defaults = TrainConfig()
        given = {k: getattr(args, k) for k in _TRAIN_KEYS}
        config = TrainConfig(
            **{k: (v if v is not None else getattr(defaults, k)) for k, v in given.items()}
        )
        run = Run.create(args.out, config)
    summary = run.train(progress=not args.quiet)
    print(json.dumps({"run": str(run.out), **summary}, indent=1))
    if args.video:
        _rollout(str(run.out), "knee", args.video, seed=run.config.seed, steps=None)
    return 0


def _rollout(run_dir: str, pick: str, video: str, seed: int, steps: int | None) -> dict:
    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.video import record_rollout
    from neurotrajectory.front import load_front_member

    run, policy, member = load_front_member(run_dir, pick)
    env = GridSimEnv(run.config.scenario, render_mode="rgb_array", **run.config.overrides)
    max_steps = steps or int(round(env.cfg.simulation.duration / env.cfg.env.decision_period))
    path, infos = record_rollout(env, policy, video, max_steps, seed=seed)
    last = infos[-1] if infos else {}
    result = {
        "video": str(path),
        "member": member,
        "steps": len(infos),
        "collision": bool(last.get("collision")),
        "off_road": bool(last.get("off_road")),
    }
    print(json.dumps(result, indent=1))
    return result


def _cmd_rollout(args: argparse.Namespace) -> int:
    _rollout(args.run, args.pick, args.video, args.seed, args.steps)
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="neurotrajectory", description="NeuroTrajectory: neuroevolution of local trajectories."
    )
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="evolve a population in GridSim-v0")
    t.add_argument("--scenario", default=None, help="built-in name or YAML path (default seamless)")
    t.add_argument("--preset", default=None, choices=sorted(PRESETS))
    t.add_argument("--population", type=int, default=None)
    t.add_argument("--generations", type=int, default=None)
    t.add_argument("--episodes", type=int, default=None, help="evaluation episodes per individual")
    t.add_argument("--episode-seconds", dest="episode_seconds", type=float, default=None)
    t.add_argument("--sigma", type=float, default=None, help="mutation noise scale")
    t.add_argument("--seed", type=int, default=None)
    t.add_argument("--backend", default=None, choices=["local", "processes", "ray"])
    t.add_argument("--workers", type=int, default=None)
    t.add_argument("--ray-address", dest="ray_address", default=None)
    t.add_argument("--out", default="runs/default", help="run directory (created)")
    t.add_argument("--resume", default=None, help="continue the run in this directory")
    t.add_argument(
        "--video", default=None, help="after training, drive the knee member into this video"
    )
    t.add_argument("--quiet", action="store_true")
    t.set_defaults(func=_cmd_train)
    r = sub.add_parser("rollout", help="drive a Pareto-front member and export a video")
    r.add_argument("--run", required=True)
    r.add_argument("--pick", default="knee", choices=PICKS)
    r.add_argument("--video", default="rollout.mp4")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--steps", type=int, default=None)
    r.set_defaults(func=_cmd_rollout)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (RunError, BackendError, GridSimError) as exc:
        print(f"neurotrajectory: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
