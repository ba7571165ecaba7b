"""The ``neurotrajectory`` command (and ``python -m neurotrajectory``): checks that the
trainer's extra is installed before loading the trainer."""

import sys
from importlib.util import find_spec

#: What the trainer needs beyond the simulator: ``pip install "gridsim[train]"``.
TRAIN_EXTRA = ("torch", "matplotlib", "moocore")


def missing_extra() -> list[str]:
    """The modules of :data:`TRAIN_EXTRA` that cannot be imported here."""
    missing = []
    for name in TRAIN_EXTRA:
        try:
            found = find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            missing.append(name)
    return missing


def main(argv: list[str] | None = None) -> int:
    missing = missing_extra()
    if missing:
        print(f"neurotrajectory: error: the trainer needs {', '.join(missing)}, which the "
              "simulator alone does not install: pip install \"gridsim[train]\" (from a "
              "checkout: pip install \".[train]\")", file=sys.stderr)  # fmt: skip
        return 2
    try:  # (torch and the trainer load for a second or two: Ctrl-C meanwhile is no crash)
        from neurotrajectory.cli import main as run
    except KeyboardInterrupt:
        print("neurotrajectory: interrupted", file=sys.stderr)
        return 130
    return run(argv)


if __name__ == "__main__":
    sys.exit(main())
