"""One field of ``/proc/cpuinfo`` (no NumPy: ``conftest.py`` reads it before NumPy loads)."""

from pathlib import Path


def cpuinfo_field(name: str) -> str:
    """The value of the first ``name`` line of ``/proc/cpuinfo`` (``""`` where there is none)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.split(":", 1)[0].strip() == name:
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""
