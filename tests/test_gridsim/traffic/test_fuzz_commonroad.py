"""Property-based fuzzing of CommonRoad XML content: whatever a value, element or id of a
scene becomes, ``gym.make`` and stepping either work with finite observations and rewards,
or refuse the file with a :class:`GridSimError` naming it; nothing else escapes."""

import re
import tempfile
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from paths import COMMONROAD

from gridsim.errors import DataWarning, GridSimError

SCENE = (COMMONROAD / "straight_2020a.xml").read_text()
TAGS = ["x", "y", "exact", "length", "width", "radius"]
VALUES = st.one_of(
    st.sampled_from(
        [
            "nan",
            "inf",
            "-inf",
            "1e308",
            "-1e308",
            "-5",
            "0",
            "",
            "abc",
            "1e-300",
            "3000000",
            " 7 ",
            "0x10",
            "1_000",
        ]
    ),  # fmt: skip
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**12), 10**12).map(str),
)


def _replace(text: str, tag: str, occurrence: int, value: str) -> str:
    """``text`` with the value of the ``occurrence``-th ``<tag>...</tag>`` (modulo their
    count) replaced."""
    spans = [m.span(1) for m in re.finditer(rf"<{tag}>([^<]*)</{tag}>", text)]
    if not spans:
        return text
    a, b = spans[occurrence % len(spans)]
    return text[:a] + value + text[b:]


def _edit(text: str, kind: str, occurrence: int) -> str:
    """A structural edit: drop an element, repeat an obstacle (its id too), or empty one."""
    blocks = list(re.finditer(r"<dynamicObstacle .*?</dynamicObstacle>", text, re.S))
    states = list(re.finditer(r"<state>.*?</state>", text, re.S))
    if kind == "drop_state" and states:
        m = states[occurrence % len(states)]
        return text[: m.start()] + text[m.end() :]
    if kind == "repeat_obstacle" and blocks:
        m = blocks[occurrence % len(blocks)]
        return text[: m.end()] + m.group(0) + text[m.end() :]
    if kind == "drop_shape":
        return re.sub(r"<shape>.*?</shape>", "", text, count=1, flags=re.S)
    if kind == "truncate":
        return text[: occurrence % max(len(text), 1)]
    return text


MUTATION = st.one_of(
    st.tuples(st.just("value"), st.sampled_from(TAGS), st.integers(0, 500), VALUES),
    st.tuples(
        st.just("edit"),
        st.sampled_from(["drop_state", "repeat_obstacle", "drop_shape", "truncate"]),
        st.integers(0, 10_000),
        st.just(""),
    ),  # fmt: skip
)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(MUTATION, min_size=1, max_size=3))
def test_mutated_commonroad_files_work_or_are_refused_clearly(mutations):
    text = SCENE
    for kind, what, occurrence, value in mutations:
        text = _replace(text, what, occurrence, value) if kind == "value" else _edit(
            text, what, occurrence)  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.xml"
        path.write_text(text)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DataWarning)
                env = gym.make("GridSim-v0", scenario=str(path))
                obs, _ = env.reset(seed=0)
                for _ in range(3):
                    assert all(np.all(np.isfinite(v)) for v in obs.values())
                    obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
                    assert np.all(np.isfinite(reward))
                    if terminated or truncated:
                        break
        except GridSimError as exc:
            assert str(path) in str(exc) or "fuzz.xml" in str(exc), str(exc)
