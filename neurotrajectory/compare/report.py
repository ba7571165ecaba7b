"""Tables and plots of an evaluation, written into its folder.

- ``table2.md``: the paper's Table II layout (metrics x scenario groups; each cell lists the
  methods in the order of its header), the full per-method table with ADE / FDE and
  per-set-point RMSE, the closed-loop table, and what each group's ground truth is;
- ``table2.csv`` (one row per group and method) and ``closed_loop.csv``;
- ``results.json``: every number;
- ``fig8_rmse_per_setpoint.png``: RMSE per set-point with a +-1 standard deviation band of the
  per-window error (the paper's Fig. 8);
- ``fig9_window_rmse.png``: box plots of the per-window RMSE (the paper's Fig. 9).
"""

from __future__ import annotations

import csv
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gridsim.outputs import atomic_text, counted, write_json, write_text  # noqa: E402
from neurotrajectory.compare.methods import NT_PICKED  # noqa: E402
from neurotrajectory.compare.metrics import SUMMARY_KEYS  # noqa: E402

GROUP_TITLES = {
    "seamless": "GridSim seamless",
    "inner_city": "GridSim inner-city",
    "highway": "real highway (US-101)",
    "urban": "real urban (Lankershim, Peachtree)",
}
TABLE_ROWS = (("mean e_x", "mean_ex"), ("max e_x", "max_ex"), ("mean e_y", "mean_ey"),
              ("max e_y", "max_ey"), ("RMSE", "rmse"))  # fmt: skip
LOOP_KEYS = ("completed", "progress", "collision", "off_road", "mean_speed",
             "mean_steer_rate", "l1", "l2", "l3", "episodes")  # fmt: skip


def _methods(results) -> list[str]:
    names: list[str] = []
    for r in results:
        names += [m for m in r.accuracy if m not in names]
    return names


def write_report(results, out: Path, run_info: dict) -> list[Path]:
    out = Path(out)
    methods = _methods(results)
    paths = [_write_markdown(results, methods, out, run_info), _write_csv(results, out)]
    paths += [_write_json(results, out, run_info), _fig8(results, methods, out),
              _fig9(results, methods, out)]  # fmt: skip
    return paths


def _write_markdown(results, methods, out: Path, run_info: dict) -> Path:
    lines = ["# Accuracy against human-driven trajectories (the paper's Table II)", ""]
    runs: dict[str, list[str]] = {}
    for group, info in run_info.items():
        text = (f"`{info['run']}` (trained on {info['scenario']}, preset {info['preset']}, "
                f"population {info['population']}, {info['generations']} generations, "
                f"{info['episodes']} x {info['episode_seconds']:g} s episodes; front of "
                f"{info['front_size']}, member {info['picked_member']} picked as "
                f"`{info['pick']}`)")  # fmt: skip
        runs.setdefault(text, []).append(group)
    for text, groups in runs.items():
        lines.append(f"NeuroTrajectory for {', '.join(groups)}: run {text}.")
    goals = {info.get("goal_seconds") for info in run_info.values()}
    goal = goals.pop() if len(goals) == 1 else None
    lines += ["", "Setting: every planner is given the destination "
              + ("at the last set-point (where the human will be at the end of the horizon)."
                 if goal is None else f"{goal:g} s ahead, beyond the last set-point (a goal "
                 "beyond the horizon: no planner is given a set-point).")]  # fmt: skip
    lines += ["", "Metres, held-out windows (tracks never shared with End2End's training "
              "windows); each cell: " + " / ".join(methods) + ".", ""]  # fmt: skip
    head = ["metric"] + [f"{GROUP_TITLES.get(r.group, r.group)} [{r.source}]" for r in results]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for label, key in TABLE_ROWS:
        cells = [" / ".join(f"{getattr(r.accuracy[m], key):.2f}" for m in methods
                            if m in r.accuracy) for r in results]  # fmt: skip
        lines.append("| " + " | ".join([label] + cells) + " |")
    lines += ["", "## Per method", ""]
    cols = ["group", "method", "windows", *SUMMARY_KEYS, "RMSE per set-point"]
    lines += ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in results:
        for m, a in r.accuracy.items():
            per = " ".join(f"{v:.2f}" for v in a.rmse_per_setpoint)
            vals = [f"{getattr(a, k):.2f}" for k in SUMMARY_KEYS]
            lines.append("| " + " | ".join([r.group, m, str(a.count), *vals, per]) + " |")
    lines += ["", "Ground truth: " + "; ".join(
        f"{r.group}: {r.source}, {r.test_windows} test windows from "
        f"{counted(r.test_tracks, 'track')}, {r.train_windows} train windows"
        for r in results) + "."]  # fmt: skip
    lines += ["Simulator groups use human speed and lane-change profiles replayed in GridSim; "
              "real groups are the recorded NGSIM drivers themselves.", ""]  # fmt: skip
    lines += [f"**Not held out:** {not_held_out(r.group, r.trained_test_tracks, r.test_tracks)}.\n"
              for r in results if r.trained_test_tracks]  # fmt: skip
    if any(r.closed_loop for r in results):
        lines += ["## Closed loop in GridSim-v0", "",
                  "Rates are shares of episodes; completed: ran to its end without a collision "
                  "or leaving the road (a car that stands still completes: read it beside "
                  "progress); progress: distance driven / the human's in the same time; speed "
                  "[m/s], steering rate [rad/s]; l1, l2, l3 are episode sums of the fitness "
                  "vector, over episodes of different lengths where some fail (compare methods "
                  "on the episodes both complete: `heldout`'s paired figures).", ""]  # fmt: skip
        cols = ["group", "method", *LOOP_KEYS]
        lines += ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        for r in results:
            for m, s in r.closed_loop.items():
                vals = [_loop_cell(k, s[k]) for k in LOOP_KEYS]
                lines.append("| " + " | ".join([r.group, m, *vals]) + " |")
    return write_text(out / "table2.md", "\n".join(lines) + "\n")


#: Closed-loop columns written with fixed decimals, so that a column reads in one style
#: (shares 1.00 beside 0.33, not 1 beside 0.333); the fitness sums take :func:`_number`.
_LOOP_DECIMALS = {"completed": 2, "progress": 2, "collision": 2, "off_road": 2,
                  "mean_speed": 2, "mean_steer_rate": 4}  # fmt: skip


def _loop_cell(key: str, v: float) -> str:
    """A closed-loop figure of column ``key`` for the Markdown table."""
    if key == "episodes":
        return str(int(v))
    if key in _LOOP_DECIMALS:
        return f"{v:.{_LOOP_DECIMALS[key]}f}".replace("-0.00", "0.00")
    return _number(v)


def _number(v: float) -> str:
    """A closed-loop figure for the Markdown table, in one style: three significant digits,
    thousands written out with separators (225,894, not 2.26e+05), below a thousandth as
    0.000 (a human reference's l1 of 1e-11 is rounding)."""
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    if abs(v) < 1e-3:
        return f"{v:.3f}".replace("-0.000", "0.000")
    return f"{v:.3g}"


def _write_csv(results, out: Path) -> Path:
    path = out / "table2.csv"
    horizon = len(next(iter(results[0].accuracy.values())).rmse_per_setpoint)
    with atomic_text(path) as fh:
        w = csv.writer(fh)
        w.writerow(["group", "source", "method", "windows", *SUMMARY_KEYS,
                    *[f"rmse_{k + 1}" for k in range(horizon)]])  # fmt: skip
        for r in results:
            for m, a in r.accuracy.items():
                w.writerow([r.group, r.source, m, a.count,
                            *[f"{getattr(a, k):.4f}" for k in SUMMARY_KEYS],
                            *[f"{v:.4f}" for v in a.rmse_per_setpoint]])  # fmt: skip
    if any(r.closed_loop for r in results):
        with atomic_text(out / "closed_loop.csv") as fh:
            w = csv.writer(fh)
            w.writerow(["group", "method", *LOOP_KEYS])
            for r in results:
                for m, s in r.closed_loop.items():
                    w.writerow([r.group, m, *[f"{s[k]:.4f}" if k != "episodes"
                                              else str(int(s[k])) for k in LOOP_KEYS]])  # fmt: skip
    return path


def not_held_out(group: str, seen, tracks: int) -> str:
    """What it means that ``seen`` of a group's ``tracks`` test tracks were the run's
    training tracks, in one sentence."""
    more = ", ..." if len(seen) > 3 else ""
    was = "was a training track" if len(seen) == 1 else "were training tracks"
    return (f"{group}: {len(seen)} of its {tracks} test tracks {was} of the NeuroTrajectory "
            f"run ({', '.join(seen[:3])}{more}): its figures on this group are not held-out "
            "ones")  # fmt: skip


def _write_json(results, out: Path, run_info: dict) -> Path:
    doc = {"neurotrajectory": run_info, "groups": []}
    for r in results:
        doc["groups"].append({
            "group": r.group, "source": r.source, "train_windows": r.train_windows,
            "test_windows": r.test_windows, "test_tracks": r.test_tracks,
            "trained_test_tracks": list(r.trained_test_tracks),
            "best_member": r.best_member,
            "accuracy": {m: {**a.summary(), "rmse_per_setpoint": a.rmse_per_setpoint,
                             "std_per_setpoint": a.std_per_setpoint}
                         for m, a in r.accuracy.items()},
            "closed_loop": r.closed_loop,
        })  # fmt: skip
    return write_json(out / "results.json", doc)


#: Fig. 8's line per method: marker and line style, so that lines that coincide (the picked
#: member and the best on test often do) stay told apart.
_STYLES = (("o", "-"), ("s", "--"), ("^", "-."), ("v", ":"), ("D", "-"), ("x", "--"))


def _fig8(results, methods, out: Path) -> Path:
    """RMSE per set-point against its time after the decision [s], one panel per group; the
    band is one standard deviation over the windows (for NeuroTrajectory only: the bands of
    every method hide each other)."""
    fig, axes = plt.subplots(1, len(results), figsize=(4.2 * len(results), 4.2), squeeze=False)
    shown: dict[str, object] = {}  # one legend entry per method, below the panels
    for ax, r in zip(axes[0], results, strict=True):
        for m, (marker, line) in zip(methods, _STYLES * 2, strict=False):
            if m not in r.accuracy:
                continue
            a = r.accuracy[m]
            mean, std = np.array(a.rmse_per_setpoint), np.array(a.std_per_setpoint)
            t = np.array(r.setpoint_times) if r.setpoint_times else np.arange(1, len(mean) + 1)
            hollow = "best member" in m
            (drawn,) = ax.plot(t, mean, marker=marker, ls=line, label=m, ms=7 if hollow else 5,
                               mfc="none" if hollow else None,
                               zorder=3 if m == NT_PICKED else 2)  # fmt: skip
            shown.setdefault(m, drawn)
            if m == NT_PICKED:
                ax.fill_between(t, np.maximum(mean - std, 0), mean + std, alpha=0.15,
                                color=drawn.get_color())  # fmt: skip
        ax.set_title(GROUP_TITLES.get(r.group, r.group), fontsize=10)
        ax.set_xlabel("time after the decision [s]" if r.setpoint_times else "set-point")
        ax.set_xticks(t)
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("RMSE [m] (band: NeuroTrajectory \u00b1 1 std)")
    fig.suptitle("error at each set-point on the held-out windows (Fig. 8)", fontsize=10)
    columns = max(1, min(len(shown), 2 if len(results) == 1 else 3 * len(results)))
    if shown:
        fig.legend(list(shown.values()), list(shown), loc="lower center", ncol=columns,
                   fontsize=9, frameon=False)  # fmt: skip
    rows = -(-len(shown) // columns)
    fig.tight_layout(rect=(0, 0.035 * rows + 0.03, 1, 1))
    path = out / "fig8_rmse_per_setpoint.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")  # (with the legend: a panel may be narrow)
    plt.close(fig)
    return path


def _worst_windows(ax, errors: list[np.ndarray], boxes: dict) -> None:
    """Each method's worst window on a box plot ``boxes`` of ``errors``: a red x, or, above
    the whiskers' range (the panel stays scaled to the boxes), a red triangle at the top
    with the value [m]."""
    ends = [float(np.max(w.get_ydata())) for w in boxes["whiskers"]] or [1.0]
    top = 1.25 * max(ends)
    ax.set_ylim(0.0, top)
    for k, e in enumerate(errors, 1):
        if not len(e):
            continue
        worst = float(e.max())
        if worst <= top:
            ax.plot(k, worst, "x", color="tab:red", ms=5)
        else:
            ax.plot(k, 0.97 * top, "^", color="tab:red", ms=5)
            ax.annotate(f"{worst:.2g}", (k, 0.97 * top), xytext=(0, -11),
                        textcoords="offset points", ha="center", fontsize=6,
                        color="tab:red")  # fmt: skip


def _fig9(results, methods, out: Path) -> Path:
    fig, axes = plt.subplots(1, len(results), figsize=(4.2 * len(results), 3.8), squeeze=False)
    for ax, r in zip(axes[0], results, strict=True):
        names = [m for m in methods if m in r.accuracy]
        errors = [np.asarray(r.accuracy[m].window_rmse, float) for m in names]
        boxes = ax.boxplot(errors, showfliers=False)
        _worst_windows(ax, errors, boxes)
        ax.set_xticks(np.arange(1, len(names) + 1),
                      [n.replace("NeuroTrajectory", "NT") for n in names], rotation=35,
                      ha="right", fontsize=7)  # fmt: skip
        ax.set_title(GROUP_TITLES.get(r.group, r.group), fontsize=9)
    axes[0, 0].set_ylabel("per-window RMSE [m]")
    said = textwrap.wrap(
        "box: the middle half of the held-out windows; orange: the median; whiskers: 1.5 box "
        "lengths; red x: the worst window (a red triangle with its value where it lies above "
        "the panel); NT: NeuroTrajectory",
        70 * len(results),
        break_long_words=False,
    )  # (a narrow figure: lines)
    fig.suptitle("error of each held-out window (Fig. 9)", fontsize=10)
    fig.text(0.5, 0.005, "\n".join(said), ha="center", va="bottom", fontsize=7)
    fig.tight_layout(rect=(0, 0.04 * len(said), 1, 1))
    path = out / "fig9_window_rmse.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
