"""The ``neurotrajectory`` command line: ``train``, ``rollout``, ``record`` and ``evaluate``."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from gridsim.errors import GridSimError
from neurotrajectory.backends import BackendError
from neurotrajectory.front import PICKS
from neurotrajectory.model import PRESETS, PRIORS
from neurotrajectory.train import Run, RunError, TrainConfig
from neurotrajectory.windows import GROUPS

_TRAIN_KEYS = (
    "scenario", "preset", "population", "generations", "episodes", "episode_seconds", "sigma",
    "seed", "backend", "workers", "ray_address", "pretrain", "pretrain_episodes", "pretrain_epochs",
    "batch", "prior",
    "resample_episodes", "constrained", "validation_episodes", "frame", "skip",
    "pretrain_validation",
)  # fmt: skip


def _cmd_train(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    if args.resume:
        # flags that would change the run's results are refused unless they match it
        run = Run.open(args.resume, **{k: getattr(args, k) for k in _TRAIN_KEYS})
    else:
        defaults = TrainConfig()
        given = {k: getattr(args, k) for k in _TRAIN_KEYS}
        config = TrainConfig(
            **{k: (v if v is not None else getattr(defaults, k)) for k, v in given.items()}
        )
        run = Run.create(args.out, config)
    summary = run.train(progress=not args.quiet)
    print(json.dumps({"run": str(run.out), **summary}, indent=1))
    if args.heldout:
        _heldout(run, args.heldout)
    if args.video:  # an episode no generation trained on
        _rollout(str(run.out), "knee", args.video, seed=run.config.heldout_seeds(1)[0], steps=None)
    minutes, seconds = divmod(round(time.perf_counter() - started), 60)
    print(f"done in {minutes} min {seconds} s")
    return 0


def _heldout(run: Run, episodes: int) -> None:
    """Drive the knee member on held-out episodes; write ``heldout.json``, print a summary."""
    from neurotrajectory.front import heldout

    report = heldout(run.out, episodes)
    (run.out / "heldout.json").write_text(json.dumps(report, indent=1))
    net, curve = report["network"], report["destination curve"]
    print(f"knee member on {episodes} held-out episodes of {report['episode_seconds']:g} s: "
          f"completed {net['completed']:.0%} (destination curve {curve['completed']:.0%}), "
          f"progress {net['progress']:.0%} of the human's, "
          f"mean l1 {net['l1']:.0f} m^2 (destination curve {curve['l1']:.0f})")  # fmt: skip


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


def _cmd_record(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from neurotrajectory.windows import Dataset, record_group, save_dataset, split_by_track

    name, source = (args.group, args.scenario) if args.group else (args.scenario, None)
    with tqdm(desc=f"record {name}", unit="episode", disable=args.quiet) as bar:
        ds = record_group(name, args.episodes, args.seed, args.stride, args.episode_seconds,
                          progress=bar.update, source=source)  # fmt: skip
    if args.split:  # the side evaluate --seed S --test-fraction F uses
        sides = dict(zip(("train", "test"), split_by_track(ds.windows, args.test_fraction,
                                                           args.seed), strict=True))  # fmt: skip
        split = {"side": args.split, "test_fraction": args.test_fraction, "seed": args.seed}
        ds = Dataset(sides[args.split], {**ds.manifest, "split": split})
    path = save_dataset(ds, args.out)
    w = ds.windows
    print(
        json.dumps(
            {
                "out": str(path),
                "windows": len(w),
                "tracks": len(set(w.track.tolist())),
                "group": ds.manifest["group"],
                "source": ds.manifest["source"],
            },
            indent=1,
        )
    )
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from neurotrajectory.baselines.end2end import TrainSettings
    from neurotrajectory.evaluation import EvalConfig, evaluate

    sources = {}
    for item in args.group:
        group, sep, path = item.partition("=")
        if not sep or not group or not path:
            raise RunError(f"--group takes NAME=FOLDER (or a glob), got {item!r}")
        sources[group] = path
    groups = args.groups if args.groups is not None else ([] if sources else list(GROUPS))
    groups = [*groups, *(g for g in sources if g not in groups)]
    cfg = EvalConfig(
        groups=tuple(groups), episodes=args.episodes, episode_seconds=args.episode_seconds,
        sources=sources,
        test_fraction=args.test_fraction, seed=args.seed, pick=args.pick,
        end2end=TrainSettings(epochs=args.e2e_epochs, seed=args.seed),
        closed_loop_episodes=args.closed_loop_episodes,
        closed_loop_seconds=args.closed_loop_seconds, videos=args.videos,
    )  # fmt: skip
    log = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    group_runs = {}
    for item in args.group_run:
        group, sep, path = item.partition("=")
        if not sep or not path:
            raise RunError(f"--group-run takes GROUP=RUN_DIR, got {item!r}")
        group_runs[group] = path
    evaluate(args.run, args.out, cfg, data_dir=args.data, log=log, group_runs=group_runs)
    print((Path(args.out) / "table2.md").read_text())
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
    t.add_argument("--batch", type=int, default=None,
                   help="individuals each worker evaluates together (default 16)")  # fmt: skip
    t.add_argument(
        "--pretrain",
        default=None,
        metavar="DATA",
        help="first fit the network to the windows of this recorded dataset",
    )
    t.add_argument(
        "--pretrain-episodes",
        dest="pretrain_episodes",
        type=int,
        default=None,
        metavar="N",
        help="first fit the network to N episodes of the scenario recorded now (30 s each, "
        "training seeds; generated scenarios only)",
    )
    t.add_argument(
        "--pretrain-epochs",
        dest="pretrain_epochs",
        type=int,
        default=None,
        help="epochs of the warm start's fit (default 20)",
    )
    t.add_argument(
        "--pretrain-validation",
        dest="pretrain_validation",
        type=float,
        default=None,
        metavar="SHARE",
        help="share of the warm start's tracks held out to pick its epoch (default 0.2; 0: "
        "keep the last epoch)",
    )
    t.add_argument("--out", default="runs/default", help="run directory (created)")
    t.add_argument("--resume", default=None, help="continue the run in this directory")
    t.add_argument(
        "--video", default=None, help="after training, drive the knee member into this video"
    )
    t.add_argument(
        "--prior",
        default=None,
        choices=list(PRIORS),
        help="the kinematic prior the network refines (default destination_curve)",
    )
    t.add_argument(
        "--frame",
        default=None,
        choices=["ego", "grid"],
        help="frame of the network's residual on its prior (default ego: along and across "
        "the heading)",
    )
    t.add_argument(
        "--no-skip",
        dest="skip",
        action="store_const",
        const=False,
        default=None,
        help="without the linear read-out of the ego's kinematic features",
    )
    t.add_argument(
        "--fixed-episodes",
        dest="resample_episodes",
        action="store_const",
        const=False,
        default=None,
        help="evaluate every generation on the same episodes (default: new ones)",
    )
    t.add_argument(
        "--unconstrained",
        dest="constrained",
        action="store_const",
        const=False,
        default=None,
        help="rank collisions and off-road by fitness alone",
    )
    t.add_argument(
        "--validation-episodes",
        dest="validation_episodes",
        type=int,
        default=None,
        metavar="N",
        help="choose the final front on N more training episodes (default 8; 0: the last "
        "generation's)",
    )
    t.add_argument(
        "--heldout",
        type=int,
        default=20,
        metavar="N",
        help="after training, drive the knee member on N held-out episodes "
        "(default 20; 0: skip) and write heldout.json",
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
    d = sub.add_parser("record", help="record labelled windows of human driving")
    d.add_argument("--scenario", required=True,
                   help=f"a scenario group ({', '.join(GROUPS)}), a built-in scenario, a YAML "
                        "or CommonRoad XML path, or a folder or glob of them; recorded scenes "
                        "drive every track once")  # fmt: skip
    d.add_argument("--group", default=None, metavar="NAME",
                   help="the group name the dataset records (default: --scenario)")  # fmt: skip
    d.add_argument("--episodes", type=int, default=8, help="episodes per generated scenario")
    d.add_argument("--episode-seconds", dest="episode_seconds", type=float, default=None)
    d.add_argument(
        "--stride",
        type=int,
        default=None,
        help="decisions between windows (default 1 on recorded scenes, else 5)",
    )
    d.add_argument("--seed", type=int, default=0)
    d.add_argument(
        "--split",
        choices=["train", "test"],
        default=None,
        help="keep only this side of the split by track that `evaluate` with the same --seed "
        "and --test-fraction makes (e.g. train data for a group's run)",
    )
    d.add_argument("--test-fraction", dest="test_fraction", type=float, default=0.3)
    d.add_argument("--out", required=True, help="dataset folder (created)")
    d.add_argument("--quiet", action="store_true")
    d.set_defaults(func=_cmd_record)
    e = sub.add_parser("evaluate", help="compare with DWA, End2End and constant velocity")
    e.add_argument("--run", required=True, help="a finished training run")
    e.add_argument(
        "--group-run",
        dest="group_run",
        action="append",
        default=[],
        metavar="GROUP=RUN",
        help="another run for one group (repeatable)",
    )
    e.add_argument("--out", required=True, help="evaluation folder (created)")
    e.add_argument(
        "--data",
        default=None,
        help="folder with one recorded dataset per group (default: record them)",
    )
    e.add_argument(
        "--groups",
        nargs="+",
        default=None,
        choices=list(GROUPS),
        help="built-in groups (default: all, or none when --group is given)",
    )
    e.add_argument("--group", action="append", default=[], metavar="NAME=FOLDER",
                   help="a group of your scenarios: a folder or glob of scenario files "
                        "(repeatable)")  # fmt: skip
    e.add_argument("--episodes", type=int, default=8)
    e.add_argument("--episode-seconds", dest="episode_seconds", type=float, default=30.0)
    e.add_argument("--test-fraction", dest="test_fraction", type=float, default=0.3)
    e.add_argument("--pick", default="knee", choices=PICKS)
    e.add_argument("--e2e-epochs", dest="e2e_epochs", type=int, default=8)
    e.add_argument("--closed-loop-episodes", dest="closed_loop_episodes", type=int, default=3)
    e.add_argument("--closed-loop-seconds", dest="closed_loop_seconds", type=float, default=20.0)
    e.add_argument(
        "--videos",
        action="store_true",
        help="export each method's first closed-loop episode to <out>/videos/",
    )
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--quiet", action="store_true")
    e.set_defaults(func=_cmd_evaluate)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (RunError, BackendError, GridSimError, ValueError) as exc:
        print(f"neurotrajectory: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
