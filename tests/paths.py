"""Where the tests find the checkout and their data, wherever a test module lies below
``tests/`` (its folders mirror the packages)."""

from pathlib import Path

#: The tests' own folder.
TESTS = Path(__file__).parent
#: The checkout (pyproject.toml, the packages, examples/, docs/).
ROOT = TESTS.parent
#: The tests' data files (golden digests, small CommonRoad files).
DATA = TESTS / "data"
#: Small CommonRoad files written for the tests.
COMMONROAD = DATA / "commonroad"
