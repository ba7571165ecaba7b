"""``neurotrajectory train``: evolve a population in GridSim-v0 (a run folder), then drive
its knee on held-out episodes.

Every flag that sets a :class:`~neurotrajectory.evolve.runs.TrainConfig` field is generated
from the field (:func:`~neurotrajectory.cli.flags.settings_flag`): its destination, help,
default, type, bounds and choices. A flag left out is None here, so that a resumed run can
tell a flag given from one not given."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from gridsim.cli.flags import at_least, quiet_flag, scenario_flag
from gridsim.interrupts import ended_by
from gridsim.outputs import DISK_FULL, as_given, counted
from gridsim.scenario.collection import absolute_ref
from neurotrajectory.cli.flags import check_video, goal_flag, settings_flag
from neurotrajectory.cli.heldout import report_heldout
from neurotrajectory.cli.rollout import rollout
from neurotrajectory.compare.front import heldout_problem
from neurotrajectory.evolve.runs import (
    AFTER_DEFAULTS,
    WARM_START_FILE,
    WARM_START_FIT_FILE,
    Run,
    RunError,
    SettingsClash,
    TrainConfig,
    run_folder,
)

DEFAULT_OUT = "runs/default"


#: The flag of each :class:`TrainConfig` field declared with :func:`config_flag`, and the
#: value it stores when it takes none (None: it takes a value).
_FLAGS: dict[str, tuple[str, Any]] = {}


def config_flag(parser: argparse.ArgumentParser, flag: str, **kwargs) -> None:
    """``flag`` for its :class:`TrainConfig` field (:func:`settings_flag`)."""
    _FLAGS[settings_flag(parser, TrainConfig, flag, **kwargs)] = (flag, kwargs.get("const"))


def flag_of(field: str) -> str:
    """The ``train`` flag that sets the :class:`TrainConfig` ``field``."""
    return _FLAGS.get(field, ("--" + field.replace("_", "-"), None))[0]


def clash_message(exc: SettingsClash) -> str:
    """Why ``train --resume`` refuses flags that would change the run's results, in the
    flags' own words."""
    parts = []
    for field, (has, asked) in exc.clash.items():
        flag, const = _FLAGS.get(field, (flag_of(field), None))
        if const is not None:  # a flag that takes no value
            parts.append(f"{flag} (the run began without it)")
        else:
            parts.append(f"{flag} {as_given(asked)} (the run has {as_given(has)})")
    may = ", ".join(flag_of(f) for f in TrainConfig.RESUMABLE)
    return (f"{exc.out}: cannot resume with {'; '.join(parts)}: "
            f"{'it' if len(parts) == 1 else 'they'} would change the run's results. Leave "
            f"{'it' if len(parts) == 1 else 'them'} out to resume (a resume may change "
            f"{may}), or start a new run with another --out")  # fmt: skip


def add_parser(sub) -> None:
    t = sub.add_parser("train", help="evolve a population in GridSim-v0")
    scenario_flag(t, default=None, help=TrainConfig.model_fields["scenario"].description
                  + f" (default {TrainConfig.defaults()['scenario']!r})")  # fmt: skip
    for flag in ("--preset", "--population", "--generations", "--episodes",
                 "--episode-seconds", "--sigma", "--seed", "--backend", "--workers",
                 "--ray-address", "--batch"):  # fmt: skip
        config_flag(t, flag)
    config_flag(t, "--pretrain", metavar="DATA")
    config_flag(t, "--pretrain-episodes", metavar="N")
    config_flag(t, "--pretrain-epochs")
    config_flag(t, "--pretrain-validation", metavar="SHARE")
    config_flag(t, "--dagger-rounds", metavar="N")
    config_flag(t, "--dagger-weight", metavar="SHARE")
    config_flag(t, "--dagger-labels")
    goal_flag(t, "the network is given the destination")
    config_flag(t, "--selection")
    config_flag(t, "--es-step")
    config_flag(t, "--evolve")
    t.add_argument("--out", default=None, help=f"run directory (created; default {DEFAULT_OUT})")
    t.add_argument("--resume", default=None, help="continue the run in this directory")
    t.add_argument("--video", default=None,
                   help="after training, drive the knee member into this video")  # fmt: skip
    config_flag(t, "--prior")
    config_flag(t, "--frame")
    config_flag(t, "--max-correction", nargs=2, type=float, metavar=("ALONG", "ACROSS"))
    config_flag(t, "--activation")
    config_flag(t, "--plan-smoothing", metavar="KEEP")
    config_flag(t, "--no-skip", help="without the linear read-out of the ego's kinematic "
                "features", dest="skip", action="store_const", const=False)  # fmt: skip
    config_flag(t, "--fixed-episodes", help="evaluate every generation on the same episodes "
                "(default: new ones)", dest="resample_episodes", action="store_const",
                const=False)  # fmt: skip
    config_flag(t, "--unconstrained", help="rank collisions and off-road by fitness alone",
                dest="constrained", action="store_const", const=False)  # fmt: skip
    config_flag(t, "--validation-episodes", metavar="N")
    config_flag(t, "--validation-tracks", metavar="SHARE")
    t.add_argument("--heldout", type=at_least(0), default=None, metavar="N",
                   help="after training, drive the knee member on N held-out episodes "
                   f"(default {AFTER_DEFAULTS['heldout']}, or what the resumed run was given; "
                   "0: skip) and write heldout.json")  # fmt: skip
    quiet_flag(t, "no progress bars")
    t.set_defaults(func=execute)


def _train_flags(args: argparse.Namespace) -> dict:
    """The ``train`` flags that set :class:`TrainConfig` fields (None where not given)."""
    flags = {name: getattr(args, name) for name in TrainConfig.model_fields if hasattr(args, name)}
    return {k: tuple(v) if isinstance(v, list) else v for k, v in flags.items()}  # nargs: tuples


def execute(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    moved = args.resume and args.out and Path(args.out).resolve() != Path(args.resume).resolve()
    if moved:
        raise RunError(f"--out {args.out} with --resume {args.resume}: a resumed run stays in "
                       "its folder; leave out --out (or drop --resume for a new run)")  # fmt: skip
    if args.video:
        check_video(args.video)
    out = args.resume or args.out or DEFAULT_OUT
    had_warm_start = (Path(out) / WARM_START_FILE).exists()  # (a run there already)
    try:
        return _train(args, out, started)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM
        said, status = ended_by(exc)
        print(f"neurotrajectory: {said}; {kept_note(Path(out))}", file=sys.stderr)
        return status
    except Exception as exc:  # a full disk, or a new run that failed after its warm start
        # was saved: say what stays
        full = isinstance(exc, OSError) and exc.errno in DISK_FULL
        if (Path(out) / "config.json").exists() and (full or (
                not args.resume and not had_warm_start
                and (Path(out) / WARM_START_FILE).exists())):  # fmt: skip
            fixed = "space is freed" if full else "the cause below is fixed"
            print(f"neurotrajectory: note: {kept_note(Path(out))} once {fixed} (or remove it "
                  "to start again)", file=sys.stderr)  # fmt: skip
        raise


def kept_note(out: Path) -> str:
    """What an interrupted ``train`` left in the run folder ``out``, and how to go on."""
    resume = f"go on with: neurotrajectory train --resume {out}"
    if not (out / "config.json").exists():
        return "nothing was kept (no generation finished, no warm start saved)"
    try:
        done = Run.open(out).completed_generations()
    except RunError as exc:  # interrupted while it was being written
        return f"{out} may not resume: {exc}"
    if done:
        return f"{out} keeps its {counted(done, 'finished generation')}; {resume}"
    if (out / WARM_START_FILE).exists():
        return f"{out} keeps its warm start (not fitted again); {resume}"
    if (out / WARM_START_FIT_FILE).exists():
        return f"{out} keeps its warm start's fit as far as it got; {resume}"
    return f"{out} has no finished generation yet; {resume}"


def _train(args: argparse.Namespace, out: str, started: float) -> int:
    with run_folder(out, resume=bool(args.resume)):  # one writer; a failure early undoes
        given = _train_flags(args)
        if given.get("scenario"):  # files by absolute paths: resumed from any folder
            given["scenario"] = absolute_ref(given["scenario"])
        if given.get("pretrain"):
            given["pretrain"] = os.path.abspath(given["pretrain"])
        if args.resume:
            # flags that would change the run's results are refused unless they match it
            try:
                run = Run.open(out, **given, **_after_flags(args))
            except SettingsClash as exc:
                raise RunError(clash_message(exc)) from None
            run.check_inputs()  # the same data as when it began
            run.note_resumed(args.command)
        else:
            # the fields' own defaults: None where TrainConfig resolves one from the other
            # fields (the activation from the preset, the selection from the warm start)
            defaults = TrainConfig.defaults()
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
        front_before = _read_bytes(run.out / "front.json")
        summary = run.train(progress=not args.quiet)
        print(front_table(run.out, summary))
        stale = run.out / "heldout.json"
        if (
            not heldout
            and stale.exists()
            and front_before not in (None, _read_bytes(run.out / "front.json"))
        ):  # (an extended run's: another front)
            stale.unlink()
            print(f"neurotrajectory: removed {stale}: it was of the front before; "
                  f"`neurotrajectory heldout --run {run.out} --out {stale}` drives this one",
                  file=sys.stderr)  # fmt: skip
        if heldout:
            warm = ", its warm start" if run.warm_start_genome() is not None else ""
            run.say(f"driving the knee{warm} and the destination curve on {heldout} held-out "
                    "episodes")  # fmt: skip
            report_heldout(run, heldout, progress=not args.quiet)
        if video:  # an episode no generation trained on
            run.say(f"filming the knee on a held-out episode: {video}")
            rollout(str(run.out), "knee", video, seed=run.config.heldout_seeds(1)[0], steps=None)
    minutes, seconds = divmod(round(time.perf_counter() - started), 60)
    print(f"done in {minutes} min {seconds} s")
    return 0


def _read_bytes(path: Path) -> bytes | None:
    """The file's bytes, or None if it cannot be read."""
    try:
        return path.read_bytes()
    except OSError:
        return None


def _after_flags(args: argparse.Namespace) -> dict:
    """What ``train`` does after the generations (kept in the run, restored by --resume):
    the held-out episodes and the video (None where not given)."""
    return {"heldout": args.heldout, "video": args.video}


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
    scores = ("l1", "l2", "l3", "violation")
    warm = summary.get("warm_start")
    for k, m in enumerate(front):  # numbered as rollout --pick and front.npz number them
        name = f"member {k}" + (f" (best validated, generation "
                                f"{summary['best_knee']['generation']})"
                                if m["index"] == best else "")  # fmt: skip
        if warm is not None and all(m[s] == warm[s] for s in scores):
            name += " (= the warm start)"  # (the same scores on the same episodes)
        rows.append((("* " if k == knee else "  ") + name, m))
    if "warm_start" in summary:
        rows.append(("  warm start", summary["warm_start"]))
    head = (f"{out}: {counted(summary['generation'] + 1, 'generation')}; the front of {len(front)} "
            f"chosen on {summary['chosen_on']} (* the knee):")  # fmt: skip
    width = max(len(name) for name, _ in rows)
    lines = [head, f"  {'':<{width}}  {'l1 [m^2]':>10}  {'l2 [rad/s]':>10}  {'l3 [m/s]':>9}  "
                   f"{'time lost':>9}"]  # fmt: skip
    lines += [f"  {name:<{width}}  {m['l1']:10.1f}  {m['l2']:10.3f}  {m['l3']:9.1f}  "
              f"{m['violation']:9.1%}" for name, m in rows]  # fmt: skip
    if rows[knee][0].endswith("(= the warm start)"):
        lines.append("  the knee is the warm start itself: evolution found no better trade-off "
                     "on these episodes")  # fmt: skip
    lines.append("  (mean episode sums of the fitness vector, each summed over the ticks; l1 "
                 "and l2 lower and l3 higher better: front.json; plots in "
                 f"{Path(out) / 'plots'})")  # fmt: skip
    return "\n".join(lines)
