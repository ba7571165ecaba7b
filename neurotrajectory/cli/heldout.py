"""``neurotrajectory heldout``: drive a member of a run's front on episodes no generation
saw."""

from __future__ import annotations

import argparse
import shlex
from contextlib import nullcontext
from pathlib import Path

from gridsim.cli.flags import at_least
from gridsim.outputs import named, output_problem, write_json
from neurotrajectory.cli.flags import episode_seconds, pick_flag, plan_smoothing_flag, run_flag
from neurotrajectory.evolve.runs import Run, RunError, run_folder


def add_parser(sub) -> None:
    p = sub.add_parser("heldout", help="drive a front member on episodes no generation saw")
    run_flag(p)
    pick_flag(p)
    p.add_argument("--episodes", type=at_least(1), default=20, help="held-out episodes")
    p.add_argument(
        "--seconds",
        type=episode_seconds,
        default=None,
        help="length of each episode [s] (default: the run's episode length)",
    )
    plan_smoothing_flag(
        p, "drive with this plan smoothing instead of the run's (see train --plan-smoothing)"
    )
    p.add_argument("--out", required=True, help="JSON report to write")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    problem = output_problem(Path(args.out), directory=False)
    if problem:
        raise RunError(f"--out {args.out}: {problem}")
    if Path(args.out).exists() and not args.overwrite:
        whose = (" (the run's own report, which train writes)"
                 if Path(args.out).resolve() == (Path(args.run) / "heldout.json").resolve()
                 else "")  # fmt: skip
        raise RunError(f"--out {args.out} exists{whose}: give another file, or --overwrite "
                       "to replace it")  # fmt: skip
    inside = Path(args.out).resolve().is_relative_to(Path(args.run).resolve())
    # a report written into the run folder holds it, as train does (one writer at a time)
    with run_folder(args.run, resume=True, flag="--run") if inside else nullcontext():
        report_heldout(Run.open(args.run), args.episodes, args.seconds, args.pick, args.out,
                       args.plan_smoothing, progress=not args.quiet)  # fmt: skip
    return 0


def report_heldout(
    run: Run,
    episodes: int,
    seconds: float | None = None,
    pick: str = "knee",
    out=None,
    smoothing: float | None = None,
    progress: bool = False,
) -> None:
    """Drive a front member on held-out episodes (``smoothing``: instead of the run's plan
    smoothing; ``progress``: with a bar); write ``out`` (default the run's
    ``heldout.json``), print a summary."""
    from neurotrajectory.compare.front import heldout

    report = heldout(run.out, episodes, pick, seconds, smoothing, progress)
    path = Path(out) if out else run.out / "heldout.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, report)
    count = len(report["episodes"])
    which = "held-out tracks" if "ego_tracks" in report else "held-out episodes"
    length = f"{report['episode_seconds']:g} s each"
    if "ego_tracks" in report:  # a recorded track's episode ends with its recording
        # (an episode's length: as long as the member or its warm start drove it)
        warm = report.get("warm_start_episodes", report["episodes"])
        rows = zip(report["episodes"], warm, strict=True)
        driven = sum(max(a["seconds"], b["seconds"]) for a, b in rows) / count
        length = f"up to {report['episode_seconds']:g} s each, about {driven:.1f} s on average"
    fewer = f"; {episodes} asked, the run holds out {count}" if count < episodes else ""
    print(f"{pick} member on {count} {which} ({length}{fewer}):")
    rows = [(f"{pick} member", report["network"]), ("its warm start", report.get("warm_start")),
            ("destination curve", report["destination curve"])]  # fmt: skip
    for name, r in rows:
        if r is not None:
            print(
                f"  {name:<18} completed {r['completed']:4.0%}  progress {r['progress']:4.0%}"
                f"  mean l1 {r['l1']:7.0f} m^2  steering {r['mean_steer_rate']:.2g} rad/s"
            )
    print("  (progress: of the human's path; steering: the mean |steering rate| a tick)")
    _print_failures(run, pick, report)
    _print_paired(report, pick, which)
    print(f"  (every episode's figures: {path})")


def _print_paired(report: dict, pick: str, which: str) -> None:
    """What the summary says of the episodes both the member and its warm start complete."""
    paired = report.get("paired")
    if paired is None:
        return
    if not paired["episodes"]:
        print(f"  no {which[:-1]} is completed by both the {pick} member and its warm start: "
              "their l1 is not compared")  # fmt: skip
    elif paired["l1_change"] is not None:
        print(f"  on the {paired['episodes']} {which} both the {pick} member and its warm start "
              f"complete:\n    mean l1 {paired['l1']:.1f} against {paired['other_l1']:.1f} m^2 "
              f"({paired['l1_change']:+.1%}), lower on {paired['better']} of them")  # fmt: skip


def _print_failures(run: Run, pick: str, report: dict, shown: int = 3) -> None:
    """The member's episodes that ended early (a few), and how to watch one."""
    failed = [e for e in report["episodes"] if not e["completed"]]
    if not failed:
        return

    def name(e: dict) -> str:
        how = "collision" if e["collision"] else "off the road" if e["off_road"] else "ended"
        on = f", track {e['track']}" if "track" in e else ""
        return f"seed {e['seed']}{on} ({how} at {e['seconds']:.1f} s)"

    first = failed[0]
    argv = ["neurotrajectory", "rollout", "--run", str(run.out), "--pick", pick, "--seed",
            str(first["seed"]), "--seconds", repr(report["episode_seconds"])]  # fmt: skip
    argv += ["--track", first["track"]] if "track" in first else []
    if report["plan_smoothing"] != run.net_config.smoothing:  # heldout --plan-smoothing
        argv += ["--plan-smoothing", repr(report["plan_smoothing"])]
    argv += ["--video", "episode.mp4"]
    print(f"  not completed by the {pick} member: {named([name(e) for e in failed], shown)}; "
          f"watch one: {shlex.join(argv)}")  # fmt: skip
