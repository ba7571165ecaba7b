"""Build the API reference from the docstrings, offline: one HTML page per module of
``gridsim`` and ``neurotrajectory``, with a search index (pdoc; ``pip install ".[docs]"``).

    python docs/build_api.py [--out docs/api]

then open ``docs/api/index.html``. The test suite builds it too and fails on a docstring
pdoc cannot read (``tests/test_docs.py``).
"""

from __future__ import annotations

import argparse
import pkgutil
import warnings
from pathlib import Path

#: pdoc's complaints that are not about the docs: a package's submodules named again,
#: NamedTuple fields annotated with a module alias (``np.ndarray``) pdoc cannot resolve, and,
#: run from the checkout with the package installed, the two copies it could mean (it
#: documents the installed one).
HARMLESS = (
    "has already been added",
    "Error parsing type annotation ForwardRef('np.",
    "may refer to either the installed Python module or the local file/directory",
)


def modules() -> list[str]:
    """Every module of both packages (not the ``__main__`` entry points)."""
    import gridsim
    import neurotrajectory

    names = ["gridsim", "neurotrajectory"]
    for package in (gridsim, neurotrajectory):
        names += [m.name for m in pkgutil.walk_packages(package.__path__, package.__name__ + ".")]
    return [n for n in names if not n.endswith("__main__")]


def build(out: Path) -> list[str]:
    """Write the reference into ``out``; pdoc's warnings about the docs themselves."""
    import pdoc

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*modules(), output_directory=out)
    messages = {str(w.message) for w in caught}
    return sorted(m for m in messages if not any(h in m for h in HARMLESS))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).parent / "api"))
    args = ap.parse_args()
    problems = build(Path(args.out))
    for p in problems:
        print(f"warning: {p}")
    print(f"{len(modules())} modules documented in {args.out}/index.html")


if __name__ == "__main__":
    main()
