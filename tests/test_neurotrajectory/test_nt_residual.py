"""The network's residual in the ego frame, its kinematic skip read-out and their fit."""

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from neurotrajectory.data.windows import record_group, split_by_track
from neurotrajectory.evolve.genome import initial_genome, set_genome
from neurotrajectory.evolve.runs import Run, TrainConfig
from neurotrajectory.evolve.warm_start import fit_skip
from neurotrajectory.model import (
    PRESETS,
    NetConfig,
    TrajectoryNet,
    from_ego_frame,
    kinematic_features,
    prior_setpoints,
    to_ego_frame,
    window_inputs,
)


def _ego(heading, speed=8.0):
    return torch.tensor([[speed, 0.05, 0.7, -0.01, np.cos(heading), np.sin(heading)]],
                        dtype=torch.float64)  # fmt: skip


def test_frames_round_trip_and_features_do_not_depend_on_the_heading():
    rng = np.random.default_rng(0)
    pts = torch.from_numpy(rng.normal(size=(1, 5, 2)))
    ego = _ego(0.7)
    np.testing.assert_allclose(from_ego_frame(to_ego_frame(pts, ego), ego), pts, atol=1e-12)
    # straight ahead is +x in the ego frame, to the left +y
    ahead = torch.tensor([[[np.cos(0.7), np.sin(0.7)], [-np.sin(0.7), np.cos(0.7)]]])
    np.testing.assert_allclose(to_ego_frame(ahead, ego)[0], [[1, 0], [0, 1]], atol=1e-12)
    cfg = PRESETS["tiny"]
    dest_local = torch.tensor([[18.0, 2.0]], dtype=torch.float64)
    feats = []
    for heading in (0.0, 1.0, -2.5):
        ego = _ego(heading)
        dest = from_ego_frame(dest_local[:, None, :], ego)[:, 0]
        prior = prior_setpoints(cfg, ego, dest, 0.5 * torch.arange(1, 6, dtype=torch.float64))
        feats.append(kinematic_features(cfg, ego, dest, prior))
    for f in feats[1:]:
        np.testing.assert_allclose(f, feats[0], atol=1e-6)  # the prior is float32
    assert feats[0].shape == (1, cfg.features)
    # speed / v_max, steering, acceleration / a_max, destination / 20 (not the steering rate)
    a_max, _, v_max, _ = cfg.limits
    np.testing.assert_allclose(feats[0][0, :5], [8.0 / v_max, 0.05, 0.7 / a_max, 0.9, 0.1])


def test_a_fresh_network_outputs_its_prior_whatever_the_frame():
    for cfg in (PRESETS["tiny"], replace(PRESETS["tiny"], frame="grid", skip=False)):
        net = TrajectoryNet(cfg)
        set_genome(net, initial_genome(net, 1))
        grids = torch.zeros(3, 5, 128, 128, dtype=torch.uint8)
        ego = torch.tensor([[9.0, 0.0, 0.0, 0.0, 0.6, 0.8]] * 3)
        dest = torch.tensor([[13.0, 17.0], [12.0, 18.0], [-1.0, -3.0]])
        prior = prior_setpoints(cfg, ego, dest, net.times)
        assert torch.equal(net(grids, ego, dest), prior)


@pytest.fixture(scope="module")
def windows():
    return record_group("seamless", 3, seed=4, duration=8.0).windows


def test_the_skip_fit_recovers_a_linear_residual(windows):
    """Targets made as the prior plus a known linear function of the kinematic features (in the
    ego frame): the ridge fit finds it, choosing its penalty on held-out tracks."""
    net = TrajectoryNet(replace(PRESETS["tiny"], grid_size=128))
    set_genome(net, initial_genome(net, 0))
    grids, ego, dest = window_inputs(windows, np.arange(len(windows)))
    prior = prior_setpoints(net.cfg, ego, dest, net.times)
    feats = kinematic_features(net.cfg, ego, dest, prior)
    rng = np.random.default_rng(1)
    w_true = rng.normal(scale=0.5, size=(5, 2, net.cfg.features)).astype(np.float32)
    w_true = torch.from_numpy(w_true)
    made = prior + from_ego_frame(torch.einsum("bf,tcf->btc", feats, w_true) + 0.3, ego)
    w = replace(windows, target=made.numpy().astype(windows.target.dtype))
    fit, held_out = split_by_track(w, 0.34, 0)
    stats = fit_skip(net, fit, held_out)
    assert stats["ridge_validation_mse"] < 1e-3 and stats["ridge_penalty"] <= 1e-2
    with torch.no_grad():
        err = (net(*window_inputs(held_out, np.arange(len(held_out))))
               - torch.from_numpy(held_out.target)).abs().max()  # fmt: skip
    assert float(err) < 0.1  # m, on tracks the fit did not see


def test_runs_saved_before_the_ego_frame_keep_their_network(tmp_path):
    run = Run.create(tmp_path / "old", TrainConfig(preset="tiny"))
    doc = json.loads((run.out / "config.json").read_text())
    for key in TrainConfig.LEGACY:
        del doc["train"][key]
    (run.out / "config.json").write_text(json.dumps({**doc, "format": 1}))
    old = Run.open(run.out).config
    assert (old.frame, old.skip, old.pretrain_validation) == ("grid", False, 0.0)
    assert old.dagger_labels == "human"  # DAgger's labels before rejoin_labels
    assert old.plan_smoothing == old.net.smoothing == 0.0  # plans followed as given
    assert (old.net.frame, old.net.skip) == ("grid", False)
    assert NetConfig.from_dict({"history": 5}).skip is False
    new = Run.open(Run.create(tmp_path / "new", TrainConfig(preset="tiny")).out).config
    assert (new.net.frame, new.net.skip) == ("ego", True)
    # a format-2 configuration from before dagger_labels: only that field is filled in
    doc = json.loads((tmp_path / "new" / "config.json").read_text())
    del doc["train"]["dagger_labels"]
    (tmp_path / "new" / "config.json").write_text(json.dumps(doc))
    before = Run.open(tmp_path / "new").config
    assert before.dagger_labels == "human" and (before.frame, before.skip) == ("ego", True)
