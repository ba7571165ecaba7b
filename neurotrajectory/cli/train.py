"""``neurotrajectory train``: evolve a population in GridSim-v0 (a run folder), then drive
its knee on held-out episodes.

Every flag that sets a :class:`~neurotrajectory.evolve.runs.TrainConfig` field is declared by
:func:`config_flag`: its destination is the field, its default (in the help) the field's,
an integer field parses with the field's minimum. A flag left out is None here, so that a
resumed run can tell a flag given from one not given."""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import MISSING, fields
from pathlib import Path

import numpy as np

from gridsim.cli.flags import MAX_COUNT, MAX_SEED, at_least, quiet_flag, scenario_flag
from neurotrajectory.cli.flags import check_video, goal_flag, plan_smoothing_flag
from neurotrajectory.cli.heldout import report_heldout
from neurotrajectory.cli.rollout import rollout
from neurotrajectory.compare.front import heldout_problem
from neurotrajectory.data.windows import DAGGER_LABELS
from neurotrajectory.evolve.backends import BACKENDS
from neurotrajectory.evolve.evolution import SELECTIONS
from neurotrajectory.evolve.runs import AFTER_DEFAULTS, Run, RunError, TrainConfig, run_folder
from neurotrajectory.model import ACTIVATIONS, EVOLVE_SCOPES, PRESETS, PRIORS, NetConfig

DEFAULT_OUT = "runs/default"
_FIELDS = {f.name: f for f in fields(TrainConfig)}


def config_flag(parser: argparse.ArgumentParser, flag: str, what: str, **kwargs) -> None:
    """Declare ``flag`` for the :class:`TrainConfig` field of its name (``--a-b``: ``a_b``;
    or ``dest``). Its default is None (the field's is used); the help ends with the field's
    default unless it says ``{default}`` itself or the default is None or a bool; an ``int``
    field parses as an integer of at least :attr:`TrainConfig.MINIMUM`, a ``float`` as a
    number."""
    name = kwargs.pop("dest", flag.lstrip("-").replace("-", "_"))
    field = _FIELDS[name]  # a KeyError here is a flag without its field: a bug
    default = None if field.default is MISSING else field.default
    if "action" not in kwargs and "type" not in kwargs and "choices" not in kwargs:
        if field.type == "int":
            top = MAX_SEED if name == "seed" else MAX_COUNT
            kwargs["type"] = at_least(TrainConfig.MINIMUM[name], top)
        elif field.type in ("float", "float | None"):
            kwargs["type"] = float
    if "{default}" in what:
        what = what.format(default=default)
    elif default is not None and not isinstance(default, bool):
        what += f" (default {default:g})" if isinstance(default, float) else f" (default {default})"
    parser.add_argument(flag, dest=name, default=None, help=what, **kwargs)


def add_parser(sub) -> None:
    t = sub.add_parser("train", help="evolve a population in GridSim-v0")
    scenario_flag(t, default=None, help="built-in name, YAML path, or a comma-separated list, "
                  f"folder or glob of them (default {_FIELDS['scenario'].default})")  # fmt: skip
    config_flag(t, "--preset", "network size", choices=sorted(PRESETS))
    config_flag(t, "--population", "networks per generation")
    config_flag(t, "--generations", "generations to evolve")
    config_flag(t, "--episodes", "evaluation episodes per individual")
    config_flag(t, "--episode-seconds", "length of each training episode [s]")
    config_flag(t, "--sigma", "mutation noise scale")
    config_flag(t, "--seed", "seed of the whole run")
    config_flag(t, "--backend", "where individuals are evaluated", choices=BACKENDS)
    config_flag(t, "--workers", "worker processes or Ray actors")
    config_flag(t, "--ray-address", "an existing Ray cluster (default: start a local one)")
    config_flag(t, "--batch", "individuals each worker evaluates together")
    config_flag(t, "--pretrain", "first fit the network to the windows of this recorded dataset",
                metavar="DATA")  # fmt: skip
    config_flag(t, "--pretrain-episodes",
                "first fit the network to N episodes of the scenario recorded now (30 s each, "
                "training seeds; generated scenarios only)", metavar="N")  # fmt: skip
    config_flag(t, "--pretrain-epochs", "epochs of the warm start's fit")
    config_flag(t, "--pretrain-validation",
                "share of the warm start's tracks held out to pick its epoch (default {default}; "
                "0: keep the last epoch)", metavar="SHARE")  # fmt: skip
    config_flag(t, "--dagger-rounds",
                "after the warm start, N rounds of driving the fitted network on its episodes "
                "and refitting it to the states it visited, labelled as --dagger-labels says",
                metavar="N")  # fmt: skip
    config_flag(t, "--dagger-weight",
                "the DAgger windows' total weight in the refit as a share of the human "
                "windows' (default: every window weighs alike, however many were visited)",
                metavar="SHARE")  # fmt: skip
    config_flag(t, "--dagger-labels",
                "how the DAgger windows are labelled: 'rejoin', the human's path shifted by "
                "the ego's offset from the human, the shift fading out over the horizon; "
                "'human', the human's next set-points from there",
                choices=DAGGER_LABELS)  # fmt: skip
    goal_flag(t, "the network is given the destination")
    config_flag(
        t,
        "--selection",
        "how parents are selected: 'anchored' (the default with a warm start): the "
        "warm start stays in every generation and a member whose l1 is worse than its "
        "is ranked as a constraint violation; 'es': evolution strategies, a centre "
        "(first the warm start) and antithetic pairs around it, the centre moved by "
        "their rank-weighted noise (--es-step); 'pareto' (the default without): "
        "constrained NSGA-II on the three objectives",
        choices=list(SELECTIONS),
    )
    config_flag(t, "--es-step", "--selection es: how far the centre moves per generation, in "
                "mean noise steps of its pairs")  # fmt: skip
    config_flag(t, "--evolve",
                "what mutation changes: 'all' weights, or with a warm start only the planning "
                "'head' (LSTM branches and read-outs) or only the linear 'readout's",
                choices=list(EVOLVE_SCOPES))  # fmt: skip
    t.add_argument("--out", default=None, help=f"run directory (created; default {DEFAULT_OUT})")
    t.add_argument("--resume", default=None, help="continue the run in this directory")
    t.add_argument("--video", default=None,
                   help="after training, drive the knee member into this video")  # fmt: skip
    config_flag(t, "--prior", "the kinematic prior the network refines (default: the "
                f"preset's, {NetConfig.prior})", choices=list(PRIORS))  # fmt: skip
    config_flag(t, "--frame", "frame of the network's residual on its prior: 'ego', along "
                "and across the heading, or 'grid'", choices=["ego", "grid"])  # fmt: skip
    config_flag(t, "--max-correction", "bound the network's correction to its prior to these "
                "many metres along and across the heading (tanh-squashed; default: unbounded)",
                nargs=2, type=float, metavar=("ALONG", "ACROSS"))  # fmt: skip
    config_flag(t, "--activation", "the network's hidden activation (default: the preset's, "
                f"{NetConfig.activation})", choices=sorted(ACTIVATIONS))  # fmt: skip
    plan_smoothing_flag(t, "in closed loop, keep this share of the previous plan in each new "
                        f"one, in [0, 1) (default {_FIELDS['plan_smoothing'].default:g}; 0: "
                        "follow every plan as given)")  # fmt: skip
    config_flag(t, "--no-skip", "without the linear read-out of the ego's kinematic features",
                dest="skip", action="store_const", const=False)  # fmt: skip
    config_flag(t, "--fixed-episodes", "evaluate every generation on the same episodes "
                "(default: new ones)", dest="resample_episodes", action="store_const",
                const=False)  # fmt: skip
    config_flag(t, "--unconstrained", "rank collisions and off-road by fitness alone",
                dest="constrained", action="store_const", const=False)  # fmt: skip
    config_flag(t, "--validation-episodes", "choose the final front on N more training "
                "episodes (default {default}; 0: the last generation's)", metavar="N")  # fmt: skip
    config_flag(t, "--validation-tracks", "recorded scenes: keep this share of the training "
                "tracks out of evolution and draw the validation episodes from them (0: the "
                "validation episodes drive the training tracks)", metavar="SHARE")  # fmt: skip
    t.add_argument("--heldout", type=at_least(0), default=None, metavar="N",
                   help="after training, drive the knee member on N held-out episodes "
                   f"(default {AFTER_DEFAULTS['heldout']}, or what the resumed run was given; "
                   "0: skip) and write heldout.json")  # fmt: skip
    quiet_flag(t, "no progress bars")
    t.set_defaults(func=execute)


def _train_flags(args: argparse.Namespace) -> dict:
    """The ``train`` flags that set :class:`TrainConfig` fields (None where not given)."""
    flags = {f.name: getattr(args, f.name) for f in fields(TrainConfig) if hasattr(args, f.name)}
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
            report_heldout(run, heldout)
        if video:  # an episode no generation trained on
            rollout(str(run.out), "knee", video, seed=run.config.heldout_seeds(1)[0], steps=None)
    minutes, seconds = divmod(round(time.perf_counter() - started), 60)
    print(f"done in {minutes} min {seconds} s")
    return 0


def _after_flags(args: argparse.Namespace) -> dict:
    """What ``train`` does after the generations (kept in the run, restored by --resume):
    the held-out episodes and the video (None where not given)."""
    return {"heldout": args.heldout, "video": args.video}


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
