"""The run's plots show what a user needs to read: a padded score (an episode lost to a
collision or leaving the road) never sets the scale."""

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from neurotrajectory.evolve import plots  # noqa: E402


def _score(l1, lost=0.0):
    return {"index": 0, "l1": l1, "l2": 0.5 + l1 / 1000, "l3": 1700.0 + l1, "violation": lost}


@pytest.mark.parametrize("warm_lost", [False, True])
def test_the_learning_curve_is_scaled_to_what_completed(tmp_path, monkeypatch, warm_lost):
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    warm = _score(5e5, lost=0.2) if warm_lost else _score(110.0)
    history = [{"generation": g, "knee_validation": _score(100.0 - g)} for g in range(6)]
    history[3]["knee_validation"] = _score(4e5, lost=0.1)  # a knee that lost an episode
    history[0]["warm_start_validation"] = warm
    plots.learning_curve(tmp_path / "lc.png", history)
    (fig,) = figures
    l1 = fig.axes[0]
    low, high = l1.get_ylim()
    assert low < 95.0 and 100.0 < high < 150.0  # the completed knees, not 4e5 or 5e5
    labels = l1.get_legend_handles_labels()[1]
    if warm_lost:
        assert "warm start: lost an episode (not drawn to scale)" in labels
    else:
        assert "warm start" in labels and high > 110.0  # the warm start's line is on the axes
    assert "the knee lost an episode (not drawn to scale)" in labels
    title = fig._suptitle.get_text()
    assert "the last generation's members and the best of these points" in title
    # a run that keeps no best point (pareto selection) is not said to
    plots.learning_curve(tmp_path / "lc.png", history, best_kept=False)
    assert "best of these points" not in figures[-1]._suptitle.get_text()


def test_the_objectives_plot_is_scaled_to_the_members_that_completed(tmp_path, monkeypatch):
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    history = []
    for g in range(4):
        fitness = [[100.0 + i, 1.0 + 0.1 * i, 1700.0 - i] for i in range(5)]
        violation = [0.0] * 5
        if g == 2:  # one member lost an episode: its remaining steps at the worst values
            fitness[4], violation[4] = [5e6, 30.0, 800.0], 0.4
        history.append({"generation": g, "fitness": fitness, "violation": violation,
                        "rank": [0] * 5, "hypervolume": 1.0})  # fmt: skip
    monkeypatch.setattr(plots, "generation_hypervolume", lambda *args: 1.0)
    plots.plot_run(tmp_path, history)
    l2, l3 = figures[0].axes[1], figures[0].axes[2]
    assert l2.get_ylim()[1] < 2.0 and l3.get_ylim()[0] > 1600.0  # 30 and 800 left out
    # the member that lost one is a cross at the top edge, at its generation
    top = l2.get_ylim()[1]
    crosses = [c.get_offsets().tolist() for c in l2.collections
               if len(c.get_offsets()) and c.get_offsets()[0][1] == top]  # fmt: skip
    assert crosses == [[[2.0, top]]]
    # on l3 (maximised) it is at the bottom edge
    bottom = l3.get_ylim()[0]
    low = [c.get_offsets().tolist() for c in l3.collections
           if len(c.get_offsets()) and c.get_offsets()[0][1] == bottom]  # fmt: skip
    assert low == [[[2.0, bottom]]]


def test_the_front_plot_is_scaled_to_the_members_that_completed(tmp_path, monkeypatch):
    """Members that lost an episode (padded to l1 ~ 1e5) neither squash the front into a dot
    nor vanish: they are crosses at the axes' edges."""
    import numpy as np

    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    monkeypatch.setattr(plots, "generation_hypervolume", lambda *args: 1.0)
    fitness = np.array([[120.0 + 10 * i, 4.3 + 0.02 * i, 680.0 + i] for i in range(6)]
                       + [[6.7e4, 6.2, 665.0], [1.2e5, 7.7, 660.0]])  # fmt: skip
    rank, violation = np.array([0] * 6 + [1, 1]), np.array([0.0] * 6 + [0.2, 0.4])
    history = [{"generation": 0, "fitness": fitness.tolist(), "violation": violation.tolist(),
                "rank": rank.tolist(), "hypervolume": 1.0}]  # fmt: skip
    plots.plot_run(tmp_path, history, (fitness, rank, violation), "8 validation episodes")
    l1_l2 = figures[1].axes[0]
    assert l1_l2.get_xlim()[1] < 250.0 and l1_l2.get_ylim()[1] < 4.5  # the completed ones
    x1, y1 = l1_l2.get_xlim()[1], l1_l2.get_ylim()[1]
    edge = [c.get_offsets().tolist() for c in l1_l2.collections if c.get_offsets().shape[0] == 2]
    assert edge == [[[x1, y1], [x1, y1]]]  # both failed members, at the worse corner
    labels = figures[1].legends[0].get_texts()
    assert any("lost an episode" in t.get_text() and "not to scale" in t.get_text()
               for t in labels)  # fmt: skip


@pytest.mark.parametrize(("centre", "says"), [(False, "warm start"), (True, "centre")])
def test_the_objectives_plot_draws_individual_0_beside_the_members(tmp_path, monkeypatch, centre,
                                                                   says):  # fmt: skip
    """Each generation's episodes are drawn anew, so the members' scores move with the
    draw; in an anchored or evolution-strategies run individual 0 (the warm start, or the
    centre) drives the same episodes: each member is drawn as its change from individual 0
    [%] (absolute scores swung with the draw and hid an l3 spread of 1 %); a generation
    whose individual 0 lost an episode has no reference and is left out, said so."""
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    monkeypatch.setattr(plots, "generation_hypervolume", lambda *args: 1.0)
    history = [{"generation": g, "fitness": [[50.0 * (g + 1) + i, 1.0, 1700.0 + 17 * i]
                                             for i in range(4)],
                "violation": [0.0] * 4, "rank": [0] * 4, "hypervolume": 1.0}
               for g in range(3)]  # fmt: skip
    history[1]["violation"][0] = 0.2
    plots.plot_run(tmp_path, history, anchored=True, centre=centre)
    l1, _, l3 = figures[0].axes
    (line,) = [ln for ln in l1.lines if ln.get_label().startswith("individual 0")]
    assert line.get_label().endswith(says) and list(line.get_ydata()) == [0.0, 0.0]
    members = np.concatenate([c.get_offsets() for c in l1.collections if len(c.get_offsets())])
    assert sorted(map(tuple, members.round(6).tolist())) == sorted(
        (g, round(100 * i / (50 * (g + 1)), 6)) for g in (0, 2) for i in range(4)
    )
    members = np.concatenate([c.get_offsets() for c in l3.collections if len(c.get_offsets())])
    assert members[:, 1].max() == pytest.approx(3.0)  # l3 1 % apart per member: visible
    assert "change from individual 0 [%] (higher better)" in l3.get_title()
    assert "1 generation(s) where individual 0 lost an episode left out" in \
        figures[0]._suptitle.get_text()  # fmt: skip
    # an individual 0 that barely steers (l2 ~ 0): the members' median is the scale, not it
    for h in history:
        h["fitness"] = [[100.0, 0.001 if i == 0 else 0.5 + 0.1 * i, 1700.0] for i in range(4)]
    figures.clear()
    plots.plt.close("all")  # (the figures are not saved, so not closed)
    plots.plot_run(tmp_path, history, anchored=True, centre=centre)
    l2 = figures[0].axes[1]
    members = np.concatenate([c.get_offsets() for c in l2.collections if len(c.get_offsets())])
    assert members[:, 1].max() == pytest.approx(100 * (0.8 - 0.001) / 0.65)
    # individual 0 lost an episode in every generation: the scores themselves, not changes
    for h in history:
        h["violation"][0] = 0.2
    figures.clear()
    plots.plt.close("all")  # (the figures are not saved, so not closed)
    plots.plot_run(tmp_path, history, anchored=True, centre=centre)
    assert "change from" not in figures[0].axes[0].get_title()
    figures.clear()
    plots.plot_run(tmp_path, history)  # no warm start: no such line
    assert not [ln for ln in figures[0].axes[0].lines if ln.get_label().startswith("individual")]


def _labelled(ax, label: str) -> list[list[float]]:
    """The points of ``ax``'s scatters labelled ``label`` (sorted)."""
    points = [p for c in ax.collections if c.get_label() == label
              for p in c.get_offsets().tolist()]  # fmt: skip
    return sorted(points)


@pytest.mark.parametrize(("centre", "anchor"), [(True, "centre"), (False, "warm start")])
def test_the_front_plot_tells_the_anchored_constraint_from_domination(tmp_path, monkeypatch,
                                                                      centre, anchor):  # fmt: skip
    """In an anchored or evolution-strategies run a member whose l1 is above individual 0's
    (the warm start, or the centre) is ranked below the front by a constraint: one no other
    member dominates is drawn as excluded, not as dominated; a dominated one stays
    dominated, whatever its l1."""
    from neurotrajectory.evolve.evolution import anchored_violation
    from neurotrajectory.evolve.pareto import minimised, non_dominated_sort

    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    monkeypatch.setattr(plots, "generation_hypervolume", lambda *args: 1.0)
    fitness = np.array([
        [100.0, 1.0, 500.0],  # individual 0: the centre or the warm start
        [90.0, 1.1, 505.0],  # on the front
        [110.0, 0.5, 500.0],  # l1 above individual 0's, the lowest l2: dominated by none
        [120.0, 1.2, 400.0],  # l1 above individual 0's, and dominated by it
        [95.0, 1.2, 490.0],  # dominated by member 1
    ])  # fmt: skip
    lost = np.zeros(len(fitness))
    rank = non_dominated_sort(minimised(fitness), anchored_violation(fitness, lost))
    assert np.flatnonzero(rank == 0).tolist() == [0, 1]  # (2: below it by the constraint)
    history = [{"generation": 0, "fitness": fitness.tolist(), "violation": lost.tolist(),
                "rank": rank.tolist(), "hypervolume": 1.0}]  # fmt: skip
    plots.plot_run(tmp_path, history, (fitness, rank, lost), "2 validation episodes",
                   anchored=True, centre=centre)  # fmt: skip
    front = figures[1]
    excluded = f"l1 above the {anchor}'s: excluded, not dominated"
    labels = [t.get_text() for t in front.legends[0].get_texts()]
    assert "dominated" in labels and excluded in labels
    l1_l2 = front.axes[0]
    assert _labelled(l1_l2, "dominated") == [[95.0, 1.2], [120.0, 1.2]]
    assert _labelled(l1_l2, excluded) == [[110.0, 0.5]]
    assert _labelled(l1_l2, "Pareto front") == [[90.0, 1.1], [100.0, 1.0]]
    # the bound itself: individual 0's l1, on the panels whose x is l1
    (bound,) = [ln for ln in l1_l2.lines if ln.get_label().endswith("l1 (individual 0): the bound")]
    assert list(bound.get_xdata()) == [100.0, 100.0] and anchor in bound.get_label()
    # the plot of the last generation (no final front) says it alike
    figures.clear()
    plots.plt.close("all")  # (the figures are not saved, so not closed)
    plots.plot_run(tmp_path, history, anchored=True, centre=centre)
    assert _labelled(figures[1].axes[0], excluded) == [[110.0, 0.5]]
    # a run without the constraint (pareto selection) has no such member
    figures.clear()
    plots.plt.close("all")
    plain = non_dominated_sort(minimised(fitness))
    plots.plot_run(tmp_path, history, (fitness, plain, lost), "2 validation episodes")
    labels = [t.get_text() for t in figures[1].legends[0].get_texts()]
    assert not [t for t in labels if "excluded" in t or t.endswith("the bound")]
    assert _labelled(figures[1].axes[0], "dominated") == [[95.0, 1.2], [120.0, 1.2]]
    plots.plt.close("all")


@pytest.mark.parametrize("anchored", [False, True])
def test_the_objectives_medians_are_of_the_members_that_completed(tmp_path, monkeypatch,
                                                                  anchored):  # fmt: skip
    """A member that lost an episode has a padded score (the episode's remaining steps at
    the worst values, l1 ~ 1e6): the median drawn per generation is of the members that
    completed every episode (the points drawn to scale), and says so; so is the scale of an
    anchored run's changes from individual 0."""
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    monkeypatch.setattr(plots, "generation_hypervolume", lambda *args: 1.0)
    history = []
    for g in range(3):
        fitness = [[100.0 + i, 1.0 + 0.1 * i, 1700.0 - i] for i in range(5)]
        violation = [0.0] * 5
        if g == 1:  # three of five lost an episode: padded, the median of all would be theirs
            for i in (2, 3, 4):
                fitness[i], violation[i] = [5e6, 30.0, 800.0], 0.4
        history.append({"generation": g, "fitness": fitness, "violation": violation,
                        "rank": [0] * 5, "hypervolume": 1.0})  # fmt: skip
    plots.plot_run(tmp_path, history, anchored=anchored)
    if anchored:  # changes from individual 0 [%]: of the members 0..4, and of 0 and 1
        want = [[2.0, 0.5, 2.0], [20.0, 5.0, 20.0], [-200 / 1700, -50 / 1700, -200 / 1700]]
    else:
        want = [[102.0, 100.5, 102.0], [1.2, 1.05, 1.2], [1698.0, 1699.5, 1698.0]]
    for ax, values in zip(figures[0].axes, want, strict=True):
        (line,) = [ln for ln in ax.lines if ln.get_label().startswith("median")]
        assert line.get_label() == "median of the members that completed every episode"
        np.testing.assert_allclose(line.get_ydata(), values)
        low, high = ax.get_ylim()
        assert low < min(values) and max(values) < high  # on the axes, with the members
    if not anchored:  # a generation none of whose members completed: no median there
        history[1]["violation"] = [0.4] * 5
        figures.clear()
        plots.plt.close("all")  # (the figures are not saved, so not closed)
        plots.plot_run(tmp_path, history)
        (line,) = [ln for ln in figures[0].axes[1].lines if ln.get_label().startswith("median")]
        assert np.isnan(line.get_ydata()[1]) and not np.isnan(line.get_ydata()[[0, 2]]).any()
    plots.plt.close("all")
