"""Plots of a run: objectives per generation (the paper's Fig. 6), the Pareto front, the
hypervolume per generation and the learning curve (each generation's knee on the validation
episodes, beside the warm start). Written headless (Agg) into ``<run>/plots/``."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import FuncFormatter, MaxNLocator, SymmetricalLogLocator  # noqa: E402

from neurotrajectory.evolve.evolution import ANCHOR  # noqa: E402
from neurotrajectory.evolve.pareto import (  # noqa: E402
    HV_MARGIN,
    dominates_matrix,
    generation_hypervolume,
    minimised,
    pick_member,
)

#: The objectives as plotted: a member's fitness is the mean over its episodes of each
#: episode's sum of the per-step terms (l2 and l3 add one value per simulation tick).
NAMES = (
    "l1: episode sum of squared set-point errors [m^2] (min)",
    "l2: episode sum of |steering rate| per tick [rad/s] (min)",
    "l3: episode sum of speed per tick [m/s] (max)",
)


def plot_run(
    out: str | Path,
    history: list[dict],
    final: tuple | None = None,
    chosen_on: str = "",
    anchored: bool = False,
    centre: bool = False,
    warm_start: dict | None = None,
) -> list[Path]:
    """The run's plots. ``final``: ``(fitness, rank, violation)`` of the members the final
    front was chosen from (on ``chosen_on``, as ``front.json`` gives them); the front plot
    shows those, else the last generation's training scores. ``anchored``: individual 0 of
    every generation is the warm start (or the evolution-strategies centre); ``centre``: the
    member validated each generation is the evolution-strategies centre, not the knee;
    ``warm_start``: the warm start's scores on ``chosen_on`` (``front.json``'s), drawn on the
    final front."""
    folder = Path(out) / "plots"
    folder.mkdir(parents=True, exist_ok=True)
    gens = np.array([h["generation"] for h in history])
    fit = [np.array(h["fitness"]) for h in history]
    paths = []

    lost = [np.array(h.get("violation", np.zeros(len(h["fitness"])))) > 0 for h in history]
    paths.append(
        _objectives(
            folder / "objectives.png",
            gens,
            fit,
            lost,
            ("centre" if centre else "warm start") if anchored else None,
        )
    )

    if final is None:
        last, rank = fit[-1], np.array(history[-1]["rank"])
        lost = np.array(history[-1].get("violation", np.zeros(len(last)))) > 0
        title = f"generation {gens[-1]}, on its training episodes"
    else:
        last, rank, lost = np.asarray(final[0]), np.asarray(final[1]), np.asarray(final[2]) > 0
        title = f"the final front, chosen on {chosen_on} (front.json)"
    warm = warm_start if final is not None else None  # (on the front's episodes only)
    front = np.flatnonzero(rank == 0)
    at = pick_member(last[front], "knee")
    knee = front[at]
    k1, k2, k3 = last[knee]
    # numbered as train prints the final front (and rollout --pick takes it), else as the
    # generation's individuals
    who = f"member {at} of the front" if final is not None else f"member {knee}"
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    kept = ~lost
    # anchored: below the front by the constraint alone (l1 above individual 0's), not dominated
    excluded = _excluded(last, rank, kept) if anchored else np.zeros(len(last), bool)
    anchor = "centre" if centre else "warm start"
    for ax, (i, j) in zip(axes, [(0, 1), (0, 2), (1, 2)], strict=True):
        shown = kept & (rank > 0) & ~excluded
        ax.scatter(last[shown, i], last[shown, j], s=10, color="0.6", label="dominated")
        if excluded.any():
            ax.scatter(last[excluded, i], last[excluded, j], s=18, facecolors="none",
                       edgecolors="tab:purple", label=f"l1 above the {anchor}'s: excluded, not "
                       "dominated")  # fmt: skip
        shown = kept & (rank == 0)
        # (above the warm start's star: a front that is the warm start itself shows)
        ax.scatter(last[shown, i], last[shown, j], s=18, color="tab:red", label="Pareto front",
                   zorder=4)  # fmt: skip
        # the axes span the members that completed every episode: a padded score (the
        # episode's remaining steps at the worst values) would squash them into a dot
        if kept.any():  # (and the warm start, if it completed every episode)
            shown = last[kept] if warm is None or warm["violation"] > 0 else np.vstack(
                [last[kept], [[warm["l1"], warm["l2"], warm["l3"]]]])  # fmt: skip
            _span(ax, shown[:, i], "x")
            _span(ax, shown[:, j], "y")
        if excluded.any() and i == 0:  # the constraint's bound, where l1 is the x axis
            ax.axvline(last[ANCHOR, 0], color="tab:purple", ls=":", lw=1,
                       label=f"the {anchor}'s l1 (individual 0): the bound")  # fmt: skip
        if lost.any():
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            ax.scatter(np.clip(last[lost, i], x0, x1), np.clip(last[lost, j], y0, y1), s=40,
                       marker="x", color="black", clip_on=False,
                       label="lost an episode (a collision or off-road; at the edge, not to "
                             "scale)" if kept.any() else "lost an episode")  # fmt: skip
        ax.scatter(last[knee, i], last[knee, j], s=120, facecolors="none", edgecolors="tab:green",
                   linewidths=2, label=f"knee ({who}): l1 {k1:.4g}, l2 {k2:.3g}, "
                                       f"l3 {k3:.4g}")  # fmt: skip
        if warm is not None:  # what evolution started from, on the same episodes (if it
            w = [warm["l1"], warm["l2"], warm["l3"]]  # lost one: at the edge, as members)
            lost_too = warm["violation"] > 0
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            at = (np.clip(w[i], x0, x1), np.clip(w[j], y0, y1)) if lost_too else (w[i], w[j])
            ax.scatter(*at, s=140, marker="*", color="tab:orange", zorder=3, clip_on=False,
                       label=f"warm start: l1 {w[0]:.4g}, l2 {w[1]:.3g}, l3 {w[2]:.4g}"
                             + (" (lost an episode; at the edge, not to scale)" if lost_too
                                else ""))  # fmt: skip

        ax.set_xlabel(NAMES[i], fontsize=8)
        ax.set_ylabel(NAMES[j], fontsize=8)
    fig.suptitle(title, fontsize=10)
    _legend_below(fig, axes[0], 4, 0.08)
    paths.append(_save(fig, folder / "front.png"))

    paths.append(_hypervolume(folder / "hypervolume.png", history, anchored))
    validated = "the centre of the generation" if centre else "knee of the generation"
    curve = learning_curve(folder / "learning_curve.png", history, validated, anchored)
    return paths + ([curve] if curve else [])


def _excluded(fitness: np.ndarray, rank: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """The members of an anchored run's ``fitness`` ``(K, 3)`` below the front (``rank`` > 0)
    by the anchored constraint alone: they completed every episode (``kept``), their l1 is
    above individual 0's (:func:`~neurotrajectory.evolve.evolution.anchored_violation`) and
    no member that completed every episode dominates them."""
    dominated = dominates_matrix(minimised(fitness))[kept].any(axis=0)
    return kept & (rank > 0) & (fitness[:, 0] > fitness[ANCHOR, 0]) & ~dominated


def _objectives(path: Path, gens: np.ndarray, fit: list[np.ndarray], lost: list[np.ndarray],
                reference: str | None) -> Path:  # fmt: skip
    """Every member of every generation (``fit``: each generation's fitness ``(K, 3)``,
    ``lost``: which members lost an episode), each objective a panel (the paper's Fig. 6).
    With a ``reference`` (individual 0 is the warm start or the centre, on the same episodes
    as the others), each member as its change from individual 0 [%]: the episodes, drawn
    anew each generation, move every member's scores together far more than members differ
    (an l3 spread of 1 % hid under a line that swung 40 % from one draw to the next);
    without one, the scores themselves. The median line is of the members that completed
    every episode (a padded score is no member's real one; none where none did)."""
    left_out = 0  # generations whose individual 0 lost an episode: no reference to draw
    whole = np.array([not gone[0] for gone in lost])
    if reference is not None and not whole.any():  # (no generation to draw against it)
        return _objectives(path, gens, fit, lost, None)
    if reference is not None:
        left_out = int((~whole).sum())
        fit = [100.0 * (f - f[0]) / _scale(f, gone)
               for f, gone, ok in zip(fit, lost, whole, strict=True) if ok]  # fmt: skip
        gens, lost = gens[whole], [gone for gone, ok in zip(lost, whole, strict=True) if ok]
    l1 = np.concatenate([f[:, 0] for f in fit])
    # l1 may span decades (a member that lost an episode): a log scale, where it does
    logged = reference is None and not (l1.min() > 0 and l1.max() < 10 * l1.min())
    any_lost = any(gone.any() for gone in lost)
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for k, ax in enumerate(axes):
        for g, f, gone in zip(gens, fit, lost, strict=True):
            ax.scatter(np.full((~gone).sum(), g), f[~gone, k], s=8, alpha=0.4, color="tab:blue",
                       label="a member" if g == gens[0] else None)  # fmt: skip
        # of the members drawn to scale: a padded score is no member's real one
        medians = [np.median(f[~gone, k]) if (~gone).any() else np.nan
                   for f, gone in zip(fit, lost, strict=True)]  # fmt: skip
        ax.plot(gens, medians, color="tab:red",
                label="median of the members that completed every episode")  # fmt: skip
        if reference is not None:  # the members' reference, on the same episodes
            ax.axhline(
                0.0,
                color="tab:orange",
                lw=1.5,
                label=f"individual 0, on the same episodes: the {reference}",
            )
        if k == 0 and logged:  # l1 spans decades; ticks at 1, 2 and 5 of each, written out
            ax.set_yscale("symlog")
            ax.yaxis.set_major_locator(SymmetricalLogLocator(base=10, linthresh=2, subs=(1, 2, 5)))
            ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        # the axes span the members that completed every episode: a padded score (the
        # episode's remaining steps at the worst values) would flatten the rest
        padded_to_edge = k > 0 or reference is not None
        if padded_to_edge:
            _span(
                ax,
                np.concatenate(
                    [f[~gone, k] for f, gone in zip(fit, lost, strict=True)]
                    + ([np.zeros(1)] if reference is not None else [])
                ),
            )
        # a padded score is drawn at the worse edge: the top for l1 and l2, the bottom for l3
        top = ax.get_ylim()[0 if k == 2 else 1] if padded_to_edge else None
        for g, f, gone in zip(gens, fit, lost, strict=True):
            y = f[gone, k] if top is None else np.full(gone.sum(), top)
            ax.scatter(np.full(gone.sum(), g), y, s=14, marker="x", color="black", clip_on=False,
                       label="a member that lost an episode" + ("" if top is None else
                             " (not drawn to scale)") if g == gens[0] and any_lost
                             else None)  # fmt: skip
        ax.set_xlabel("generation")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        name = NAMES[k]  # (relative: the quantity, then the change on a line of its own)
        if reference is not None:
            better = "higher" if k == 2 else "lower"
            name = (f"{name[: name.index(' [')]}\nchange from individual 0 [%] ({better} "
                    "better)")  # fmt: skip
        ax.set_title(name + ("\n(log scale)" if logged and k == 0 else ""), fontsize=9,
                     pad=10)  # fmt: skip
    if reference is None:
        said = (
            "every member of every generation, on that generation's training episodes "
            "(drawn anew each generation: compare members within a generation)"
        )
    else:
        said = (f"every member of every generation against individual 0 (the {reference}) on "
                "the same training episodes, drawn anew each generation"
                + (f"\n({left_out} generation(s) where individual 0 lost an episode left out)"
                   if left_out else ""))  # fmt: skip
    fig.suptitle(said, fontsize=10)
    _legend_below(fig, axes[0], 4 if reference is not None else 3, 0.07)
    return _save(fig, path)


def _scale(f: np.ndarray, lost: np.ndarray) -> np.ndarray:
    """What a generation's fitness ``f`` ``(K, 3)`` is a share of, per objective: individual
    0's magnitude, or the median one of the members that completed every episode (not
    ``lost``; a padded score is no member's real one) where individual 0's is under a tenth
    of it (an individual 0 that barely steers, l2 near 0, would make every other member's
    change thousands of %); 1 where both are 0."""
    own, median = np.abs(f[0]), np.median(np.abs(f[~lost]), axis=0)
    scale = np.where(own >= 0.1 * median, own, median)
    return np.where(scale > 0, scale, 1.0)


def _hypervolume(path: Path, history: list[dict], anchored: bool) -> Path:
    """Each generation's hypervolume against a reference on the same episodes
    (:func:`~neurotrajectory.evolve.pareto.hypervolume_ratio`): individual 0 (the warm start or
    the centre) of an anchored run, else the median member of generation 0."""
    values = [generation_hypervolume(h, history[0], anchored) for h in history]
    who = ("individual 0 (the warm start or the centre)" if anchored
           else "generation 0's median member")  # fmt: skip
    fig, ax = plt.subplots(figsize=(6.5, 4))
    ax.plot([h["generation"] for h in history], values, marker="o")
    ax.axhline(1.0, color="tab:orange", linestyle="--", label=f"{who} alone")
    ax.set_xlabel("generation")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylim(bottom=0)
    ax.set_ylabel(f"hypervolume / {'individual 0' if anchored else 'that member'}'s alone")
    where = ("on the same episodes" if anchored else "on generation 0's episodes (later "
             "generations may draw others:\nthen the curve moves with the draw as much as "
             "with progress)")  # fmt: skip
    ax.set_title(f"the objective space the generation's members dominate, relative to\n{who}"
                 f" alone {where} (objectives as ratios to it, up to {HV_MARGIN:g}x)"
                 "\n1: no member does better on any objective; it moves with each draw",
                 fontsize=8)  # fmt: skip
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def learning_curve(
    path: Path,
    history: list[dict],
    validated: str = "knee of the generation",
    best_kept: bool = True,
) -> Path | None:
    """Each generation's knee (or what ``validated`` says it is) on the validation episodes
    (``knee_validation``), one panel per objective, with the warm start on the same episodes
    as a line. The axes span the knees
    that completed every episode (and the warm start); a knee that lost episode time (a
    collision or leaving the road, its remaining steps counted at the worst values) is a
    cross at the worse edge (the top, the bottom for l3), a warm start that lost some a dotted
    line there, neither drawn to scale. None without validation scores. ``best_kept``: the
    run keeps its best point for the final front (anchored selection); the title says so."""
    points = [(h["generation"], h["knee_validation"]) for h in history if "knee_validation" in h]
    if not points:
        return None
    gens = np.array([g for g, _ in points])
    warm = history[0].get("warm_start_validation")
    warm_lost = warm is not None and warm["violation"] > 0
    lost = np.array([v["violation"] > 0 for _, v in points])
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, key, name in zip(axes, ("l1", "l2", "l3"), NAMES, strict=True):
        y = np.array([v[key] for _, v in points], dtype=float)
        kept = np.where(lost, np.nan, y)
        ax.plot(gens, kept, marker="o", ms=4, color="tab:blue", label=validated)
        # the axes span what completed every episode: a padded score would flatten the rest
        _span(ax, np.append(kept[~lost], [] if warm is None or warm_lost else [warm[key]]))
        top = ax.get_ylim()[0 if key == "l3" else 1]  # the worse edge (l3 is maximised)
        if warm is not None and not warm_lost:
            ax.axhline(warm[key], color="tab:orange", ls="--", label="warm start")
        elif warm_lost:
            ax.axhline(top, color="tab:orange", ls=":", lw=2, clip_on=False,
                       label="warm start: lost an episode (not drawn to scale)")  # fmt: skip
        if lost.any():
            ax.scatter(gens[lost], np.full(lost.sum(), top), s=60, marker="x", color="black",
                       zorder=3, clip_on=False,
                       label="the knee lost an episode (not drawn to scale)")  # fmt: skip
        ax.set_xlabel("generation")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_title(name, fontsize=9, pad=10)
    best = " and the best of these points" if best_kept else ""
    fig.suptitle("learning curve: on the validation episodes (none trained on); the final "
                 f"front is sorted again on them, of the last generation's members{best} "
                 "(train's table, front.json)", fontsize=9)  # fmt: skip
    _legend_below(fig, axes[0], 3, 0.08)
    return _save(fig, path)


def _legend_below(fig, ax, columns: int, height: float) -> None:
    """One legend (of ``ax``'s labels) under the panels, clear of the points, in the bottom
    ``height`` of the figure (a share of it)."""
    fig.legend(*ax.get_legend_handles_labels(), loc="lower center", ncol=columns, fontsize=8)
    fig.tight_layout(rect=(0, height, 1, 1))


#: The least span of an axis, as a share of its values' size (see :func:`_span`).
MIN_SPAN = 0.05


def _span(ax, values: np.ndarray, axis: str = "y") -> None:
    """The ``axis`` ("x" or "y") spans ``values`` (with a margin, more above), if there are
    any: the scores of what completed every episode, so that a padded score never sets the
    scale. It spans at least :data:`MIN_SPAN` of their size, so that differences of a few
    per mille do not fill the panel as if they were large."""
    if len(values):
        lo, hi = float(values.min()), float(values.max())
        widen = max(MIN_SPAN * max(abs(lo), abs(hi)) - (hi - lo), 0.0) / 2
        lo, hi = lo - widen, hi + widen
        pad = 0.08 * (hi - lo) or 0.05 * max(abs(hi), 1e-9)
        (ax.set_xlim if axis == "x" else ax.set_ylim)(lo - pad, hi + 2 * pad)


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
