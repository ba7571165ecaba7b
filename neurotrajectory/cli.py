"""The ``neurotrajectory`` command line: ``train``, ``rollout``, ``record`` and ``evaluate``."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from contextlib import nullcontext
from dataclasses import fields
from pathlib import Path

import numpy as np

from gridsim.cli import MAX_SEED, at_least, overlay_flag, run_command
from gridsim.errors import GridSimError
from gridsim.outputs import new_folder, output_problem, write_json
from neurotrajectory.compare.front import heldout_problem
from neurotrajectory.data.windows import DAGGER_LABELS, GROUPS
from neurotrajectory.evolve.backends import BACKENDS, BackendError
from neurotrajectory.evolve.evolution import SELECTIONS
from neurotrajectory.evolve.pareto import PICKS
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig, run_folder
from neurotrajectory.model import ACTIVATIONS, EVOLVE_SCOPES, PRESETS, PRIORS

DEFAULT_OUT = "runs/default"


def _train_flags(args: argparse.Namespace) -> dict:
    """The ``train`` flags that set :class:`TrainConfig` fields (None where not given)."""
    return {f.name: getattr(args, f.name) for f in fields(TrainConfig) if hasattr(args, f.name)}


def _cmd_train(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    moved = args.resume and args.out and Path(args.out).resolve() != Path(args.resume).resolve()
    if moved:
        raise RunError(f"--out {args.out} with --resume {args.resume}: a resumed run stays in "
                       "its folder; leave out --out (or drop --resume for a new run)")  # fmt: skip
    if args.video:
        _check_video(args.video)
    out = args.resume or args.out or DEFAULT_OUT
    with run_folder(out, resume=bool(args.resume)):  # one writer; a failure early undoes
        if args.resume:
            # flags that would change the run's results are refused unless they match it
            run = Run.open(out, **_train_flags(args), **_after_flags(args))
        else:
            # the fields' own defaults: None where TrainConfig resolves one from the other
            # fields (the activation from the preset, the selection from the warm start)
            defaults = {f.name: f.default for f in fields(TrainConfig)}
            given = _train_flags(args)
            config = TrainConfig(**{k: (v if v is not None else defaults[k])
                                    for k, v in given.items()})  # fmt: skip
            if args.dagger_labels is not None and not config.dagger_rounds:
                raise RunError(f"--dagger-labels {args.dagger_labels} labels the DAgger rounds' "
                               "windows: give --dagger-rounds >= 1")  # fmt: skip
            run = Run.create(out, config, command=args.command, **_after_flags(args))
        heldout, video = run.after["heldout"], run.after["video"]
        if heldout and (problem := heldout_problem(run.config)):
            print(f"neurotrajectory: note: no held-out report: {problem}", file=sys.stderr)
            heldout = 0
        summary = run.train(progress=not args.quiet)
        print(front_table(run.out, summary))
        if heldout:
            _heldout(run, heldout)
        if video:  # an episode no generation trained on
            _rollout(str(run.out), "knee", video, seed=run.config.heldout_seeds(1)[0], steps=None)
    minutes, seconds = divmod(round(time.perf_counter() - started), 60)
    print(f"done in {minutes} min {seconds} s")
    return 0


def _after_flags(args: argparse.Namespace) -> dict:
    """What ``train`` does after the generations (kept in the run, restored by --resume):
    the held-out episodes and the video (None where not given)."""
    return {"heldout": args.heldout, "video": args.video}


def _cmd_heldout(args: argparse.Namespace) -> int:
    if args.seconds is not None and not (math.isfinite(args.seconds) and args.seconds > 0):
        raise RunError(f"--seconds must be a finite number > 0, got {args.seconds}")
    problem = output_problem(Path(args.out), directory=False)
    if problem:
        raise RunError(f"--out {args.out}: {problem}")
    with run_folder(args.run, resume=True) if args.out is None else nullcontext():
        _heldout(Run.open(args.run), args.episodes, args.seconds, args.pick, args.out,
                 args.plan_smoothing)  # fmt: skip
    return 0


def _goal_flag(parser: argparse.ArgumentParser, who: str) -> None:
    """The ``--goal-seconds`` flag (the scenario's ``env.goal_seconds``)."""
    parser.add_argument(
        "--goal-seconds",
        dest="goal_seconds",
        type=_positive_seconds,
        default=None,
        metavar="S",
        help=f"{who} S seconds ahead, beyond the last set-point (>= the horizon's 2.5 s; "
        "default: at the last set-point, where the human will be)",
    )


def _positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {text}")
    return value


def _check_video(path: str) -> None:
    from gridsim.video import video_problem

    problem = video_problem(path)
    if problem:
        raise RunError(f"--video {path}: {problem}")


def front_table(out: Path, summary: dict) -> str:
    """What ``train`` prints when the generations are done: where the run is, its final
    front's members (the knee marked, the best validated one of any generation named) and the
    warm start, if any, beside them, scored on the episodes the front was chosen on
    (``summary``: ``front.json``'s)."""
    from neurotrajectory.evolve.pareto import pick_member

    front = summary["front"]
    fitness = np.array([[m["l1"], m["l2"], m["l3"]] for m in front])
    knee = pick_member(fitness, "knee")
    best = summary.get("best_knee", {}).get("index")
    rows = []
    for k, m in enumerate(front):  # numbered as rollout --pick and front.npz number them
        name = f"member {k}" + (f" (the best validated, of generation "
                                f"{summary['best_knee']['generation']})"
                                if m["index"] == best else "")  # fmt: skip
        rows.append((("* " if k == knee else "  ") + name, m))
    if "warm_start" in summary:
        rows.append(("  warm start", summary["warm_start"]))
    head = (f"{out}: {summary['generation'] + 1} generations; the front of {len(front)} "
            f"chosen on {summary['chosen_on']} (* the knee):")  # fmt: skip
    width = max(len(name) for name, _ in rows)
    lines = [head, f"  {'':<{width}}  {'l1':>10}  {'l2':>8}  {'l3':>9}  {'time lost':>9}"]
    lines += [f"  {name:<{width}}  {m['l1']:10.1f}  {m['l2']:8.3f}  {m['l3']:9.1f}  "
              f"{m['violation']:9.1%}" for name, m in rows]  # fmt: skip
    lines.append("  (mean episode sums of the fitness vector: l1 and l2 lower, l3 higher is "
                 "better; front.json holds them)")  # fmt: skip
    return "\n".join(lines)


def _heldout(
    run: Run,
    episodes: int,
    seconds: float | None = None,
    pick: str = "knee",
    out=None,
    smoothing: float | None = None,
) -> None:
    """Drive a front member on held-out episodes (``smoothing``: instead of the run's plan
    smoothing); write ``out`` (default the run's ``heldout.json``), print a summary."""
    from neurotrajectory.compare.front import heldout

    report = heldout(run.out, episodes, pick, seconds, smoothing)
    path = Path(out) if out else run.out / "heldout.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, report)
    count = len(report["episodes"])
    which = "held-out tracks" if "ego_tracks" in report else "held-out episodes"
    print(f"{pick} member on {count} {which} ({report['episode_seconds']:g} s each):")
    rows = [(f"{pick} member", report["network"]), ("its warm start", report.get("warm_start")),
            ("destination curve", report["destination curve"])]  # fmt: skip
    for name, r in rows:
        if r is not None:
            print(f"  {name:<18} completed {r['completed']:4.0%}  progress {r['progress']:4.0%} "
                  f"of the human's  mean l1 {r['l1']:8.0f} m^2  steering "
                  f"{r['mean_steer_rate']:.2f} rad/s")  # fmt: skip


def _rollout(
    run_dir: str, pick: str, video: str, seed: int, steps: int | None, overlay: bool = True
) -> dict:
    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.video import record_episode
    from neurotrajectory.compare.front import load_front_member

    run, policy, member = load_front_member(run_dir, pick)
    env = GridSimEnv(run.config.scenario, render_mode="rgb_array", **run.config.overrides)
    episode = env.cfg.episode_decisions
    if steps and steps > episode:
        print(f"neurotrajectory: note: --steps {steps} is more than the run's episodes of "
              f"{episode} decisions ({env.cfg.simulation.duration:g} s): the episode ends at "
              f"{episode}", file=sys.stderr)  # fmt: skip
    label = f"NeuroTrajectory, {pick} member {member['index']} of {Path(run_dir).name}"
    driven, path = record_episode(env, policy, video, min(steps or episode, episode), seed=seed,
                                  overlay=overlay, label=label)  # fmt: skip
    s = driven.summary()
    result = {"video": str(path), "member": member, **s}
    f = s["fitness_sums"]
    ended = ("a collision" if s["collision"] else "leaving the road" if s["off_road"]
             else "reaching the destination" if s["destination_reached"]
             else "the time or --steps limit")  # fmt: skip
    print(f"{pick} member {member['index']}, seed {seed}: {s['steps']} decisions, "
          f"{s['simulated_s']:.1f} s, {s['distance_m']:.0f} m at {s['mean_speed']:.1f} m/s, "
          f"ended by {ended}\n"
          f"  fitness sums: l1 {f['l1']:.4g} m^2, l2 {f['l2']:.3g} rad/s, l3 {f['l3']:.4g} m/s\n"
          f"  video: {path}")  # fmt: skip
    return result


def _cmd_rollout(args: argparse.Namespace) -> int:
    _check_video(args.video)
    _rollout(args.run, args.pick, args.video, args.seed, args.steps, args.overlay)
    return 0


def _cmd_record(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from neurotrajectory.data.windows import Dataset, record_group, save_dataset, split_by_track

    if args.test_fraction is not None and not args.split:
        raise RunError(f"--test-fraction {args.test_fraction:g} sets the test side of --split: "
                       "give --split train or --split test (or leave it out)")  # fmt: skip
    args.test_fraction = 0.3 if args.test_fraction is None else args.test_fraction
    name, source = (args.group, args.scenario) if args.group else (args.scenario, None)
    with new_folder(args.out) as partial:  # held before recording; --out appears when done
        with tqdm(desc=f"record {name}", unit="episode", disable=args.quiet) as bar:
            ds = record_group(name, args.episodes, args.seed, args.stride, args.episode_seconds,
                              progress=bar.update, source=source,
                              goal_seconds=args.goal_seconds)  # fmt: skip
        if args.split:  # the side evaluate --seed S --test-fraction F uses
            halves = split_by_track(ds.windows, args.test_fraction, args.seed)
            sides = dict(zip(("train", "test"), halves, strict=True))
            split = {"side": args.split, "test_fraction": args.test_fraction, "seed": args.seed}
            ds = Dataset(sides[args.split], {**ds.manifest, "split": split})
        save_dataset(ds, partial)
    path = Path(args.out)
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
    from neurotrajectory.compare.baselines.end2end import TrainSettings
    from neurotrajectory.compare.evaluation import EvalConfig, evaluate

    sources = {}
    for item in args.group:
        group, sep, path = item.partition("=")
        if not sep or not group or not path:
            raise RunError(f"--group takes NAME=FOLDER (or a glob), got {item!r}")
        if group in sources:
            raise RunError(f"--group {group} is given twice ({sources[group]} and {path}); "
                           "give each group its own name")  # fmt: skip
        sources[group] = path
    groups = args.groups if args.groups is not None else ([] if sources else list(GROUPS))
    twice = sorted({g for g in groups if groups.count(g) > 1})
    if twice:
        raise RunError(f"--groups names {', '.join(twice)} more than once")
    groups = [*groups, *(g for g in sources if g not in groups)]
    cfg = EvalConfig(
        groups=tuple(groups), episodes=args.episodes, episode_seconds=args.episode_seconds,
        sources=sources,
        test_fraction=args.test_fraction, seed=args.seed, pick=args.pick,
        end2end=TrainSettings(epochs=args.e2e_epochs, seed=args.seed),
        closed_loop_episodes=args.closed_loop_episodes,
        closed_loop_seconds=args.closed_loop_seconds, videos=args.videos,
        goal_seconds=args.goal_seconds,
    )  # fmt: skip
    log = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    group_runs = {}
    for item in args.group_run:
        group, sep, path = item.partition("=")
        if not sep or not path:
            raise RunError(f"--group-run takes GROUP=RUN_DIR, got {item!r}")
        if group in group_runs:
            raise RunError(f"--group-run {group} is given twice ({group_runs[group]} and {path})")
        group_runs[group] = path
    evaluate(args.run, args.out, cfg, data_dir=args.data, log=log, group_runs=group_runs,
             progress=not args.quiet)  # fmt: skip
    print((Path(args.out) / "table2.md").read_text())
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="neurotrajectory", description="NeuroTrajectory: neuroevolution of local trajectories."
    )
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="evolve a population in GridSim-v0")
    t.add_argument("--scenario", default=None, help="built-in name or YAML path (default seamless)")
    t.add_argument(
        "--preset", default=None, choices=sorted(PRESETS), help="network size (default: default)"
    )
    t.add_argument(
        "--population", type=at_least(2), default=None, help="networks per generation (default 16)"
    )
    t.add_argument(
        "--generations", type=at_least(1), default=None, help="generations to evolve (default 10)"
    )
    t.add_argument(
        "--episodes", type=at_least(1), default=None, help="evaluation episodes per individual"
    )
    t.add_argument(
        "--episode-seconds",
        dest="episode_seconds",
        type=float,
        default=None,
        help="length of each training episode [s] (default 15)",
    )
    t.add_argument("--sigma", type=float, default=None, help="mutation noise scale")
    t.add_argument(
        "--seed", type=at_least(0, MAX_SEED), default=None, help="seed of the whole run (default 0)"
    )
    t.add_argument(
        "--backend",
        default=None,
        choices=BACKENDS,
        help="where individuals are evaluated (default local)",
    )
    t.add_argument(
        "--workers",
        type=at_least(1),
        default=None,
        help="worker processes or Ray actors (default 2)",
    )
    t.add_argument(
        "--ray-address",
        dest="ray_address",
        default=None,
        help="an existing Ray cluster (default: start a local one)",
    )
    t.add_argument("--batch", type=at_least(1), default=None,
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
        type=at_least(0),
        default=None,
        metavar="N",
        help="first fit the network to N episodes of the scenario recorded now (30 s each, "
        "training seeds; generated scenarios only)",
    )
    t.add_argument(
        "--pretrain-epochs",
        dest="pretrain_epochs",
        type=at_least(1),
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
    t.add_argument(
        "--dagger-rounds",
        dest="dagger_rounds",
        type=at_least(0),
        default=None,
        metavar="N",
        help="after the warm start, N rounds of driving the fitted network on its episodes and "
        "refitting it to the states it visited, labelled as --dagger-labels says "
        "(default 0)",
    )
    t.add_argument(
        "--dagger-weight",
        dest="dagger_weight",
        type=float,
        default=None,
        metavar="SHARE",
        help="the DAgger windows' total weight in the refit as a share of the human windows' "
        "(default: every window weighs alike, however many were visited)",
    )
    t.add_argument(
        "--dagger-labels",
        dest="dagger_labels",
        choices=DAGGER_LABELS,
        default=None,
        help="how the DAgger windows are labelled: 'rejoin' (default), the human's path "
        "shifted by the ego's offset from the human, the shift fading out over the horizon; "
        "'human', the human's next set-points from there",
    )
    _goal_flag(t, "the network is given the destination")
    t.add_argument(
        "--selection",
        choices=list(SELECTIONS),
        default=None,
        help="how parents are selected: 'anchored' (the default with a warm start): the warm "
        "start stays in every generation and a member whose l1 is worse than its is ranked "
        "as a constraint violation; 'es': evolution strategies, a centre (first the warm "
        "start) and antithetic pairs around it, the centre moved by their rank-weighted noise "
        "(--es-step); 'pareto' (the default without): constrained NSGA-II on the three "
        "objectives",
    )
    t.add_argument(
        "--es-step",
        type=float,
        default=None,
        help="--selection es: how far the centre moves per generation, in mean noise steps "
        "of its pairs (default 3)",
    )
    t.add_argument(
        "--evolve",
        choices=list(EVOLVE_SCOPES),
        default=None,
        help="what mutation changes: 'all' weights (default), or with a warm start only the "
        "planning 'head' (LSTM branches and read-outs) or only the linear 'readout's",
    )
    t.add_argument("--out", default=None, help=f"run directory (created; default {DEFAULT_OUT})")
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
        "--activation",
        default=None,
        choices=sorted(ACTIVATIONS),
        help="the network's hidden activation (default: the preset's, sigmoid)",
    )
    t.add_argument(
        "--plan-smoothing",
        dest="plan_smoothing",
        type=float,
        default=None,
        metavar="KEEP",
        help="in closed loop, keep this share of the previous plan in each new one, in [0, 1) "
        "(default 0.7; 0: follow every plan as given)",
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
        type=at_least(0),
        default=None,
        metavar="N",
        help="choose the final front on N more training episodes (default 8; 0: the last "
        "generation's)",
    )
    t.add_argument(
        "--heldout",
        type=at_least(0),
        default=None,
        metavar="N",
        help="after training, drive the knee member on N held-out episodes "
        "(default 20, or what the resumed run was given; 0: skip) and write heldout.json",
    )
    t.add_argument("--quiet", action="store_true", help="no progress bars")
    t.set_defaults(func=_cmd_train)
    r = sub.add_parser("rollout", help="drive a Pareto-front member and export a video")
    r.add_argument("--run", required=True, help="a finished training run's folder")
    r.add_argument("--pick", default="knee", choices=PICKS,
                   help="the front member: the knee or the best on one objective")  # fmt: skip
    r.add_argument("--video", default="rollout.mp4", help="video to write (.mp4 or .gif)")
    overlay_flag(r)
    r.add_argument("--seed", type=at_least(0, MAX_SEED), default=0, help="episode seed")
    r.add_argument(
        "--steps",
        type=at_least(1),
        default=None,
        help="decisions to drive at most (default: the run's episode length)",
    )
    r.set_defaults(func=_cmd_rollout)
    h = sub.add_parser("heldout", help="drive a front member on episodes no generation saw")
    h.add_argument("--run", required=True, help="a finished training run's folder")
    h.add_argument("--pick", default="knee", choices=PICKS,
                   help="the front member: the knee or the best on one objective")  # fmt: skip
    h.add_argument("--episodes", type=at_least(1), default=20, help="held-out episodes")
    h.add_argument(
        "--seconds",
        type=float,
        default=None,
        help="length of each episode [s] (default: the run's episode length)",
    )
    h.add_argument(
        "--plan-smoothing",
        dest="plan_smoothing",
        type=float,
        default=None,
        metavar="KEEP",
        help="drive with this plan smoothing instead of the run's (see train --plan-smoothing)",
    )
    h.add_argument("--out", required=True, help="JSON report to write")
    h.set_defaults(func=_cmd_heldout)
    d = sub.add_parser("record", help="record labelled windows of human driving")
    d.add_argument("--scenario", required=True,
                   help=f"a scenario group ({', '.join(GROUPS)}), a built-in scenario, a YAML "
                        "or CommonRoad XML path, or a folder or glob of them; recorded scenes "
                        "drive every track once")  # fmt: skip
    d.add_argument("--group", default=None, metavar="NAME",
                   help="the group name the dataset records (default: --scenario)")  # fmt: skip
    d.add_argument(
        "--episodes", type=at_least(1), default=8, help="episodes per generated scenario"
    )
    d.add_argument(
        "--episode-seconds",
        dest="episode_seconds",
        type=float,
        default=None,
        help="length of each episode [s] (default: the scenario's)",
    )
    d.add_argument(
        "--stride",
        type=at_least(1),
        default=None,
        help="decisions between windows (default 1 on recorded scenes, else 5)",
    )
    d.add_argument(
        "--seed", type=at_least(0, MAX_SEED), default=0, help="seed of the episodes and split"
    )
    d.add_argument(
        "--split",
        choices=["train", "test"],
        default=None,
        help="keep only this side of the split by track that `evaluate` with the same --seed "
        "and --test-fraction makes (e.g. train data for a group's run)",
    )
    d.add_argument(
        "--test-fraction",
        dest="test_fraction",
        type=float,
        default=None,
        help="share of the tracks on the test side of --split (default 0.3)",
    )
    _goal_flag(d, "the windows see the destination")
    d.add_argument("--out", required=True, help="dataset folder (created)")
    d.add_argument("--quiet", action="store_true", help="no progress bar")
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
    _goal_flag(e, "every planner is given the destination")
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
    e.add_argument(
        "--episodes", type=at_least(1), default=8, help="episodes recorded per generated scenario"
    )
    e.add_argument(
        "--episode-seconds",
        dest="episode_seconds",
        type=float,
        default=30.0,
        help="length of each recorded episode [s]",
    )
    e.add_argument(
        "--test-fraction",
        dest="test_fraction",
        type=float,
        default=0.3,
        help="share of each group's tracks held out for testing",
    )
    e.add_argument(
        "--pick",
        default="knee",
        choices=PICKS,
        help="the front member compared (picked without test data)",
    )
    e.add_argument(
        "--e2e-epochs",
        dest="e2e_epochs",
        type=at_least(1),
        default=8,
        help="training epochs of the End2End baseline",
    )
    e.add_argument(
        "--closed-loop-episodes",
        dest="closed_loop_episodes",
        type=at_least(0),
        default=3,
        help="closed-loop episodes per scenario (0: skip)",
    )
    e.add_argument(
        "--closed-loop-seconds",
        dest="closed_loop_seconds",
        type=float,
        default=20.0,
        help="length of each closed-loop episode [s]",
    )
    e.add_argument(
        "--videos",
        action="store_true",
        help="export each method's first closed-loop episode to <out>/videos/",
    )
    e.add_argument(
        "--seed", type=at_least(0, MAX_SEED), default=0, help="seed of the split and episodes"
    )
    e.add_argument("--quiet", action="store_true", help="no progress messages")
    e.set_defaults(func=_cmd_evaluate)
    return p


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv, (GridSimError, RunError, BackendError, ValueError))


if __name__ == "__main__":
    sys.exit(main())
