"""Bounded corrections (``NetConfig.max_correction``, ``train --max-correction``): the
network's residual on its prior is squashed into a box in the ego frame, checked on input,
saved with the run, and left out of runs that do not use it."""

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from neurotrajectory.evolve.runs import Run, RunError, TrainConfig
from neurotrajectory.model import PRESETS, NetConfig, finish_setpoints, to_ego_frame


def _ego(heading, speed=8.0):
    return torch.tensor([[speed, 0.05, 0.7, -0.01, np.cos(heading), np.sin(heading)]],
                        dtype=torch.float32)  # fmt: skip


def test_the_correction_stays_in_its_box_along_and_across_the_heading():
    cfg = replace(PRESETS["tiny"], max_correction=(6.0, 2.0))
    ego = _ego(1.1)
    prior = torch.tensor([[[5.0 * k, 1.0] for k in range(1, 6)]])
    residual = torch.tensor([[[40.0, -17.0], [0.01, 0.02], [-9.0, 3.0], [0.3, -0.1], [0, 0]]])
    out = finish_setpoints(cfg, residual, prior, ego)
    got = to_ego_frame(out - prior, ego)[0].numpy()  # the correction, in the ego frame
    assert (np.abs(got[:, 0]) <= 6.0).all() and (np.abs(got[:, 1]) <= 2.0).all()
    squashed = [[6.0, -2.0], [-6.0 * np.tanh(1.5), 2.0 * np.tanh(1.5)]]
    np.testing.assert_allclose(got[[0, 2]], squashed, rtol=1e-5)
    # small corrections pass nearly as they are (tanh(x) ~ x), their signs kept
    np.testing.assert_allclose(got[1], [0.01, 0.02], rtol=1e-3)
    np.testing.assert_allclose(got[3], [6 * np.tanh(0.05), 2 * np.tanh(-0.05)], rtol=1e-5)
    unbounded = finish_setpoints(PRESETS["tiny"], residual, prior, ego)
    np.testing.assert_allclose(to_ego_frame(unbounded - prior, ego)[0], residual[0], atol=1e-4)


@pytest.mark.parametrize(
    ("bound", "frame", "message"),
    [
        ((0.0, 2.0), "ego", "two finite numbers > 0"),
        ((3.0,), "ego", "two finite numbers > 0"),
        ((3.0, float("inf")), "ego", "two finite numbers > 0"),
        ((3.0, 2.0), "grid", "needs frame 'ego'"),
    ],
)
def test_a_bad_bound_is_refused_saying_why(bound, frame, message):
    with pytest.raises(ValueError, match=message):
        NetConfig(max_correction=bound, frame=frame)


def test_train_config_checks_saves_and_resumes_the_bound(tmp_path):
    for bad in ((4.0, -1.0), (None, 3.0), 5.0, (1.0, 2.0, 3.0)):
        with pytest.raises(RunError, match="max_correction must be two finite numbers > 0"):
            TrainConfig(preset="tiny", max_correction=bad)
    # ints from Python and floats from the command line are the same run
    assert TrainConfig(max_correction=(8, 3)) == TrainConfig(max_correction=(8.0, 3.0))
    with pytest.raises(RunError, match="needs frame 'ego'"):
        TrainConfig(preset="tiny", max_correction=(4.0, 1.0), frame="grid")
    run = Run.create(tmp_path / "b", TrainConfig(preset="tiny", max_correction=(4.0, 1.5)))
    saved = json.loads((run.out / "config.json").read_text())["train"]
    assert saved["max_correction"] == [4.0, 1.5]
    reopened = Run.open(run.out, max_correction=(4.0, 1.5))  # the same flag: no clash
    assert reopened.config.max_correction == (4.0, 1.5)
    assert reopened.config.net.max_correction == (4.0, 1.5)
    assert reopened.fingerprint == run.fingerprint
    with pytest.raises(RunError, match="cannot resume with a different configuration"):
        Run.open(run.out, max_correction=(5.0, 1.5))


def test_a_network_without_a_bound_saves_as_before():
    cfg = PRESETS["tiny"]
    assert cfg.max_correction is None and "max_correction" not in cfg.to_dict()
    assert NetConfig.from_dict(cfg.to_dict()) == cfg
