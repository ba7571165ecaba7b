"""Every script in examples/ runs, in its quick mode, in a fresh interpreter from an empty
folder (as a user runs it after the install)."""

import subprocess
import sys

import pytest
from paths import ROOT

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow

EXAMPLES = sorted((ROOT / "examples").glob("*.py"))

#: What each example prints when it worked.
SAYS = {
    "01_first_env.py": "l1 0.00 m^2 (distance to the human)",
    "02_vector_envs.py": "rewards (4, 3) per environment",
    "03_sb3_ppo.py": "trained; a deterministic action per environment",
    "04_author_scenario.py": "busy_city: 35 participants at 2.77-8.33 m/s, 30 s",
    "05_commonroad_file.py": "the ego replays the human of track",
    "06_train_and_evaluate.py": "its warm start",
    "07_custom_policy.py": "decisions, ended by ",
}


def test_every_example_is_listed():
    assert {p.name for p in EXAMPLES} == set(SAYS)


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_example_runs_in_its_quick_mode(script, tmp_path):
    out = subprocess.run([sys.executable, str(script), "--quick"], cwd=tmp_path, text=True,
                         capture_output=True, timeout=600)  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    assert SAYS[script.name] in out.stdout, out.stdout
